#include "live/run_row_queue.h"

#include <chrono>
#include <exception>
#include <string>

namespace echoservo::live {

RunRowQueue::RunRowQueue(formats::RunWriter* writer, double drain_period_s)
    : writer_(writer), drain_period_s_(drain_period_s) {
  if (!writer_) return;
  thread_ = std::thread([this] {
    const auto period = std::chrono::duration<double>(drain_period_s_);
    while (!stop_.load()) {
      std::this_thread::sleep_for(period);
      Drain();
    }
    Drain();  // what came before the stop
  });
}

RunRowQueue::~RunRowQueue() {
  try {
    Stop();
  } catch (const std::exception&) {  // Flush's error: the run is being left anyway
  }
}

void RunRowQueue::AddServo(double t_s, control::FollowerMode mode, double setpoint_mm,
                           double base_mm, double tip_estimate_mm, double faults,
                           const Eigen::Vector3d& target_mm, const Eigen::Vector3d& tip_mm) {
  if (!writer_) return;
  ServoRow r{t_s, setpoint_mm, base_mm, tip_estimate_mm, faults, {}, {}, mode};
  for (int i = 0; i < 3; ++i) {
    r.target_mm[i] = target_mm[i];
    r.tip_mm[i] = tip_mm[i];
  }
  servo_.Push(r);
}

void RunRowQueue::AddEm(const formats::EmSample& s) {
  if (!writer_) return;
  em_.Push({s.t_s, {s.position_mm.x(), s.position_mm.y(), s.position_mm.z()}, s.valid});
}

void RunRowQueue::AddLatency(const formats::LatencyRecord& r) {
  if (writer_) latency_.Push(r);
}

void RunRowQueue::Drain() {
  if (failed_.load()) {  // the writer failed: drop, so that the rings do not count it as lost
    servo_.Drain([](const ServoRow&) {});
    em_.Drain([](const EmRow&) {});
    latency_.Drain([](const formats::LatencyRecord&) {});
    return;
  }
  try {
    servo_.Drain([&](const ServoRow& r) {
      writer_->AddServo({r.t_s, control::ToString(r.mode), r.setpoint_mm, r.base_mm,
                         r.tip_estimate_mm, r.faults});
      writer_->AddTruth({r.t_s, Eigen::Vector3d(r.target_mm[0], r.target_mm[1], r.target_mm[2]),
                         Eigen::Vector3d(r.tip_mm[0], r.tip_mm[1], r.tip_mm[2])});
    });
    em_.Drain([&](const EmRow& r) {
      writer_->AddEm(
          {r.t_s, Eigen::Vector3d(r.position_mm[0], r.position_mm[1], r.position_mm[2]), r.valid});
    });
    latency_.Drain([&](const formats::LatencyRecord& r) { writer_->AddLatency(r); });
  } catch (const std::exception& e) {
    error_ = e.what();
    failed_.store(true);
  }
  lost_.store(servo_.lost() + em_.lost() + latency_.lost());
}

void RunRowQueue::Stop() {
  if (!thread_.joinable()) return;
  stop_.store(true);
  thread_.join();
  if (!failed_.load()) writer_->Flush();
}

std::string RunRowQueue::error() const { return failed_.load() ? error_ : std::string(); }

}  // namespace echoservo::live
