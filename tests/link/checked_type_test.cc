// msg/checked_pubsub_type.h: malformed payloads from the wire are rejected (deserialize
// returns false) instead of throwing on Fast DDS's receive thread. Regression test for the
// crash fuzz_dds_samples found (tests/fuzz/corpus/dds_samples/regression-bad-encapsulation).
#include <fastcdr/exceptions/Exception.h>
#include <fastdds/rtps/common/SerializedPayload.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "echoservo_msgs/msg/ServoCommand.h"
#include "echoservo_msgs/msg/ServoCommandPubSubTypes.h"
#include "echoservo_msgs/msg/TargetEstimate.h"
#include "echoservo_msgs/msg/TargetEstimatePubSubTypes.h"
#include "msg/checked_pubsub_type.h"

namespace {

using eprosima::fastrtps::rtps::SerializedPayload_t;
namespace msgs = echoservo_msgs::msg;

SerializedPayload_t Payload(const std::vector<std::uint8_t>& bytes) {
  SerializedPayload_t p(static_cast<std::uint32_t>(bytes.size()));
  std::memcpy(p.data, bytes.data(), bytes.size());
  p.length = static_cast<std::uint32_t>(bytes.size());
  return p;
}

TEST(CheckedPubSubType, UnknownEncapsulationIsRejectedNotThrown) {
  // Encapsulation kind 0x00FF (not CDR/PL_CDR) followed by a ServoCommand-sized body.
  std::vector<std::uint8_t> bytes = {0x00, 0xff, 0x00, 0x00};
  bytes.resize(4 + 32, 0xff);
  SerializedPayload_t payload = Payload(bytes);
  msgs::ServoCommand message;
  msgs::ServoCommandPubSubType generated;
  EXPECT_THROW(generated.deserialize(&payload, &message), eprosima::fastcdr::exception::Exception)
      << "the generated code throws: the reason for the wrapper";
  echoservo::msg::CheckedPubSubType<msgs::ServoCommandPubSubType> checked;
  EXPECT_FALSE(checked.deserialize(&payload, &message));
}

TEST(CheckedPubSubType, TruncatedPayloadIsRejected) {
  SerializedPayload_t payload = Payload({0x00, 0x01, 0x00, 0x00, 0x01, 0x02});
  msgs::TargetEstimate message;
  echoservo::msg::CheckedPubSubType<msgs::TargetEstimatePubSubType> checked;
  EXPECT_FALSE(checked.deserialize(&payload, &message));
}

TEST(CheckedPubSubType, ValidPayloadRoundTrips) {
  echoservo::msg::CheckedPubSubType<msgs::ServoCommandPubSubType> checked;
  msgs::ServoCommand sent;
  sent.sequence_number(7);
  sent.stamp_s(12.5);
  sent.action(1);
  sent.standoff_mm(4.0);
  SerializedPayload_t payload(1024);
  ASSERT_TRUE(checked.serialize(&sent, &payload));
  msgs::ServoCommand received;
  ASSERT_TRUE(checked.deserialize(&payload, &received));
  EXPECT_EQ(received.sequence_number(), 7u);
  EXPECT_EQ(received.stamp_s(), 12.5);
  EXPECT_EQ(received.action(), 1);
  EXPECT_EQ(received.standoff_mm(), 4.0);
}

}  // namespace
