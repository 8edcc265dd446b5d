// Fuzz target: DDS samples from the wire to the servo (link/message_conversion.h,
// link/sample_validation.h), the path of every subscriber in link/dds_link.cc.
//
// Input: byte 0 picks the topic's type (TargetEstimate, CatheterState, ServoCommand); the
// rest is the serialized payload (CDR encapsulation + body) that Fast DDS hands to the
// generated type's deserialize(). A payload that deserializes goes through FromMessage and
// SampleValidator::Accept at a receiver clock taken from byte 1. Checked: deserialize
// returns false or succeeds (it must not throw, Fast DDS calls it on its own threads: the
// link registers msg/checked_pubsub_type.h's wrapper, used here too); an
// accepted sample has only finite numbers, a motion model the IDL can carry (ToMessage does
// not throw) that evaluates to finite values over its validity horizon.
#include <fastdds/rtps/common/SerializedPayload.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "echoservo_msgs/msg/CatheterState.h"
#include "echoservo_msgs/msg/CatheterStatePubSubTypes.h"
#include "echoservo_msgs/msg/ServoCommand.h"
#include "echoservo_msgs/msg/ServoCommandPubSubTypes.h"
#include "echoservo_msgs/msg/TargetEstimate.h"
#include "echoservo_msgs/msg/TargetEstimatePubSubTypes.h"
#include "link/message_conversion.h"
#include "link/sample_validation.h"
#include "msg/checked_pubsub_type.h"

namespace lnk = echoservo::link;
namespace msgs = echoservo_msgs::msg;

namespace {

bool Finite(const lnk::TargetEstimateSample& s) {
  bool ok = std::isfinite(s.acquisition_time_s) && std::isfinite(s.publication_time_s) &&
            s.target_mm.allFinite() && s.axis.allFinite() && s.tip_mm.allFinite() &&
            std::isfinite(s.confidence) && std::isfinite(s.motion.t0_s) &&
            std::isfinite(s.motion.phase0_rad) && std::isfinite(s.motion.frequency_hz) &&
            std::isfinite(s.motion.offset_mm) && std::isfinite(s.motion.drift_mm_s) &&
            std::isfinite(s.motion.valid_until_s);
  for (double c : s.motion.cos_mm) ok = ok && std::isfinite(c);
  for (double c : s.motion.sin_mm) ok = ok && std::isfinite(c);
  return ok;
}

template <class PubSubType, class Message, class Sample, class OnAccepted>
void Run(const std::uint8_t* data, std::size_t size, double now_s, OnAccepted on_accepted) {
  eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<std::uint32_t>(size));
  if (size > 0) std::memcpy(payload.data, data, size);
  payload.length = static_cast<std::uint32_t>(size);
  echoservo::msg::CheckedPubSubType<PubSubType> type;  // as link/dds_link.cc registers it
  Message message;
  if (!type.deserialize(&payload, &message)) return;
  Sample sample;
  lnk::FromMessage(message, sample);
  lnk::SampleValidator validator;
  if (validator.Accept(sample, now_s)) on_accepted(sample);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  // Receiver clock: near the seeds' stamps (100 s) so that the age checks pass sometimes.
  const double now_s = 100.0 + (static_cast<double>(data[1]) - 128.0) * 0.01;
  const std::uint8_t* body = data + 2;
  const std::size_t n = size - 2;
  switch (data[0] % 3) {
    case 0:
      Run<msgs::TargetEstimatePubSubType, msgs::TargetEstimate, lnk::TargetEstimateSample>(
          body, n, now_s, [&](const lnk::TargetEstimateSample& s) {
            if (!Finite(s)) __builtin_trap();
            msgs::TargetEstimate back;
            lnk::ToMessage(s, back);  // throws (a finding) if the IDL cannot carry it
            const double until = std::min(s.motion.valid_until_s, s.acquisition_time_s + 10.0);
            for (int k = 0; k <= 20; ++k) {
              const double t = s.acquisition_time_s + (until - s.acquisition_time_s) * k / 20.0;
              const auto m = s.motion.Evaluate(t);
              if (!std::isfinite(m.position_mm)) __builtin_trap();
            }
          });
      break;
    case 1:
      Run<msgs::CatheterStatePubSubType, msgs::CatheterState, lnk::CatheterStateSample>(
          body, n, now_s, [](const lnk::CatheterStateSample& s) {
            if (!std::isfinite(s.stamp_s) || !std::isfinite(s.base_mm) ||
                !std::isfinite(s.base_velocity_mm_s) || !std::isfinite(s.tip_estimate_mm) ||
                !std::isfinite(s.setpoint_mm) || !std::isfinite(s.force_n) ||
                !std::isfinite(s.standoff_mm) || !std::isfinite(s.estimate_age_s) ||
                static_cast<int>(s.mode) > lnk::kMaxServoMode)
              __builtin_trap();
          });
      break;
    default:
      Run<msgs::ServoCommandPubSubType, msgs::ServoCommand, lnk::ServoCommandSample>(
          body, n, now_s, [](const lnk::ServoCommandSample& s) {
            const int a = static_cast<int>(s.action);
            if (!std::isfinite(s.stamp_s) || !std::isfinite(s.standoff_mm) ||
                a < lnk::kMinServoAction || a > lnk::kMaxServoAction)
              __builtin_trap();
          });
      break;
  }
  return 0;
}
