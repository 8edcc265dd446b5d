#include "live/servo_runtime.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "live/servo_cycle_clock.h"
#include "live/servo_node.h"

namespace echoservo::live {

void DelayedEstimates::Push(const link::TargetEstimateSample& sample, double deliver_s) {
  // Kept sorted by delivery time (stable: equal times keep their order of arrival).
  auto it = queue_.end();
  while (it != queue_.begin() && std::prev(it)->deliver_s > deliver_s) --it;
  queue_.insert(it, Due{sample, deliver_s});
}

std::size_t DelayedEstimates::Deliver(ServoNode& node, double t_s) {
  std::size_t n = 0;
  while (!queue_.empty() && queue_.front().deliver_s <= t_s + 1e-12) {
    node.HandleTarget(queue_.front().sample, t_s);
    queue_.pop_front();
    ++n;
  }
  return n;
}

void ServoRuntimeOptions::Validate() const {
  auto bad = [](const std::string& field, const std::string& why) {
    throw std::invalid_argument("ServoRuntimeOptions::" + field + " " + why);
  };
  if (clock == ServoClock::kRealtime && pipeline_clock == nullptr)
    bad("pipeline_clock", "is required for the real-time clock");
  if (!std::isfinite(t0_s)) bad("t0_s", "must be finite");
  if (clock == ServoClock::kRealtime && t0_s != 0.0)
    bad("t0_s",
        "must be 0 on the real-time clock (cycle k is due at k·period on the pipeline clock)");
  if (!(std::isfinite(duration_s) && duration_s >= 0.0)) bad("duration_s", "must be ≥ 0 s");
  if (clock == ServoClock::kSimulated && duration_s == 0.0 && !stop)
    bad("duration_s", "must be > 0 s on simulated time without a stop condition");
  realtime.Validate();
}

ServoRuntime::ServoRuntime(ServoNode& node, ServoRuntimeOptions options)
    : node_(node), o_(std::move(options)) {
  o_.Validate();
}

ServoRunResult ServoRuntime::Run(
    const Before& before, const After& after,
    const std::function<void(const control::RealtimeStatus&)>& on_started) {
  const double period = node_.loop().config().period_s;
  const double end_s = o_.t0_s + o_.duration_s;
  std::optional<ServoCycleClock> cycle_clock;
  if (o_.clock == ServoClock::kRealtime) {
    cycle_clock.emplace(*o_.pipeline_clock, period, &node_, o_.realtime);
    if (on_started) on_started(cycle_clock->realtime());
  }
  ServoRunResult result;
  node_.Start(o_.t0_s);
  for (std::uint64_t k = 0;; ++k) {
    const double t = o_.t0_s + static_cast<double>(k) * period;
    if ((o_.duration_s > 0.0 && t > end_s + 1e-12) || (o_.stop && o_.stop())) break;
    if (cycle_clock) cycle_clock->Wait(k);
    if (before) before(k, t);
    if (o_.estimates) o_.estimates->Deliver(node_, t);
    const ServoCycle c = node_.Cycle(t, k);
    if (after) after(k, t, c);
    if (cycle_clock) cycle_clock->Done();
    ++result.cycles;
    result.end_s = t;
  }
  if (cycle_clock) {
    result.realtime = cycle_clock->realtime();
    result.timing = cycle_clock->Report();
  }
  return result;
}

}  // namespace echoservo::live
