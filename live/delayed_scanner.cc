#include "live/delayed_scanner.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "live/sim_scene.h"

namespace echoservo::live {

DelayedScanner::DelayedScanner(SimScene& scene, const PipelineClock& clock,
                               DelayedScannerOptions options)
    : scene_(scene), clock_(clock), o_(options) {
  thread_ = std::thread([this] { Run(); });
}

DelayedScanner::~DelayedScanner() { Stop(); }

void DelayedScanner::Stop() {
  stop_ = true;
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::uint64_t DelayedScanner::dropped() const {
  std::lock_guard lock(m_);
  return dropped_ + queue_.size();
}

void DelayedScanner::Run() {
  tbb::task_arena one(1);
  std::mt19937_64 rng(o_.seed + 3);
  std::uniform_real_distribution<double> delay(o_.delay_min_s, o_.delay_max_s);
  double last_deliver = 0.0;
  // Slots 0 … last_slot lie within the run (t ≤ duration).
  const auto last_slot = static_cast<std::int64_t>(std::floor(o_.duration_s * o_.rate_hz + 1e-9));
  for (std::int64_t k = 0; !stop_; ++k) {
    double t_acq = static_cast<double>(k) / o_.rate_hz;
    // A scanner acquires on its own schedule: slots missed while rendering are lost (those
    // past the end of the run were never slots).
    if (clock_.Now() > t_acq + 1.0 / o_.rate_hz) {
      const auto behind = std::max<std::int64_t>(
          0, static_cast<std::int64_t>(std::floor(clock_.Now() * o_.rate_hz)) - k);
      missed_ += static_cast<std::uint64_t>(
          std::min(behind, std::max<std::int64_t>(0, last_slot + 1 - k)));
      k += behind;
      t_acq = static_cast<double>(k) / o_.rate_hz;
    }
    if (t_acq > o_.duration_s) break;
    std::this_thread::sleep_until(clock_.At(t_acq));
    std::optional<imaging::SourceFrame> frame;
    one.execute([&] { frame = scene_.Render(t_acq); });
    ++acquired_;
    last_deliver = std::max(last_deliver, t_acq + delay(rng));
    {
      std::lock_guard lock(m_);
      queue_.push_back({std::move(frame->volume), t_acq, last_deliver});
    }
    cv_.notify_one();
  }
  finished_ = true;
  cv_.notify_all();
}

std::optional<Delivery> DelayedScanner::Next(double timeout_s) {
  std::optional<Delivery> next;
  {
    std::unique_lock lock(m_);
    cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                 [&] { return !queue_.empty() || stop_ || finished_; });
    if (queue_.empty()) return std::nullopt;
    // Only the newest delivered volume matters: older ones still queued are dropped.
    while (queue_.size() > 1 && queue_[1].deliver_s <= clock_.Now()) {
      queue_.pop_front();
      ++dropped_;
    }
    next.emplace(std::move(queue_.front()));
    queue_.pop_front();
  }
  std::this_thread::sleep_until(clock_.At(next->deliver_s));
  return next;
}

}  // namespace echoservo::live
