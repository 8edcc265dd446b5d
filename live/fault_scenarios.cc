#include "live/fault_scenarios.h"

#include <cmath>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <utility>

#include "hw/fault_injection.h"
#include "live/servo_node.h"
#include "live/servo_runtime.h"
#include "live/sim_catheter.h"

namespace echoservo::live {
namespace {

constexpr double kRateHz = 25.0;
constexpr double kDelayS = 0.06;
constexpr double kOffsetMm = 12.0;  // image axis coordinate of the catheter's tip at x = 0
constexpr double kDurationS = 8.0;
constexpr double kFaultStartS = 4.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// The target's axis coordinate (image mm): a 60 bpm heartbeat with two harmonics.
estimation::FourierMotion TargetMotion() {
  estimation::FourierMotion m;
  m.frequency_hz = 1.0;
  m.offset_mm = 20.0;
  m.cos_mm = {0.0, 1.5};
  m.sin_mm = {5.0, 0.0};
  return m;
}

// The estimate of a volume acquired kDelayS before `t`: the target's motion, and the tip as
// the image saw it then (the true tip kOffsetMm along the axis).
link::TargetEstimateSample ScenarioEstimate(const estimation::FourierMotion& target,
                                            std::uint64_t seq, double t,
                                            const std::deque<std::pair<double, double>>& tips) {
  const double t_acq = t - kDelayS;
  double tip_at_acq = tips.front().second;
  for (const auto& [ts, x] : tips)
    if (ts <= t_acq) tip_at_acq = x;
  link::TargetEstimateSample s;
  s.sequence_number = seq;
  s.acquisition_time_s = t_acq;
  s.publication_time_s = t;
  s.axis = Eigen::Vector3d::UnitZ();
  s.target_mm = Eigen::Vector3d(0, 0, target.Position(t_acq));
  s.tip_mm = Eigen::Vector3d(0, 0, tip_at_acq + kOffsetMm);
  s.motion = target;
  s.motion.t0_s = 0.0;
  s.motion.valid_until_s = t_acq + 0.5;
  s.confidence = 0.9;
  return s;
}

// One scenario's knobs: hardware faults, and hooks on each estimate (drop it, delay it,
// corrupt it) and on each cycle (commands).
struct Scenario {
  Scenario(std::string n, std::string f) : name(std::move(n)), fault(std::move(f)) {}
  std::string name, fault;
  std::vector<hw::InjectedFault> hardware;
  bool safe_state_required = false;
  double fault_end_s = kDurationS;
  // Returns false to drop the estimate; may corrupt it or add delay (s). Counts injections.
  std::function<bool(link::TargetEstimateSample&, double& delay_s, std::uint64_t& injected)>
      on_estimate;
  // Called every cycle before the node's; commands go through node.HandleCommand.
  std::function<void(ServoNode&, double t, std::uint64_t& injected)> on_cycle;
};

FaultScenarioResult Run(const Scenario& sc) {
  SimCatheter catheter = MakeSimCatheter(1.59, 1.50, 1);
  hw::FaultInjectingHardware hardware(*catheter.plant, sc.hardware);
  ServoNodeOptions o;
  o.follower.standoff_mm = 8.0;
  o.auto_enable = true;
  ServoNode node(hardware, catheter.servo, std::move(catheter.compensator), o, nullptr);
  const estimation::FourierMotion target = TargetMotion();
  const std::size_t tip_index = catheter.plant->StateIndex(hw::iface::kTipPosition);

  FaultScenarioResult r;
  r.name = sc.name;
  r.fault = sc.fault;
  r.safe_state_required = sc.safe_state_required;
  std::deque<std::pair<double, double>> tip_history;  // the true tip, to see it "in the image"
  std::uint64_t seq = 0, injected = 0;
  double err_sq = 0.0;
  std::uint64_t err_n = 0;
  const double period = catheter.servo.period_s;
  const auto every = static_cast<std::uint64_t>(std::llround(1.0 / (kRateHz * period)));
  // The servo runtime on simulated time; the scanner's estimates fed in process.
  DelayedEstimates estimates;
  ServoRuntimeOptions ro;
  ro.clock = ServoClock::kSimulated;
  ro.duration_s = kDurationS;
  ro.estimates = &estimates;
  ServoRuntime(node, ro).Run(
      [&](std::uint64_t k, double t) {
        const double tip_true = catheter.plant->state(tip_index);
        tip_history.emplace_back(t, tip_true);
        while (tip_history.size() > 200) tip_history.pop_front();
        // A volume acquired every 1/25 s is delivered kDelayS later as an estimate.
        if (k % every == 0 && t >= kDelayS) {
          link::TargetEstimateSample s = ScenarioEstimate(target, ++seq, t, tip_history);
          double extra_delay = 0.0;
          if (!sc.on_estimate || sc.on_estimate(s, extra_delay, injected))
            estimates.Push(s, t + extra_delay);
        }
        if (sc.on_cycle) sc.on_cycle(node, t, injected);
      },
      [&](std::uint64_t, double t, const ServoCycle& c) {
        const bool safe = c.mode == link::ServoMode::kHolding ||
                          c.mode == link::ServoMode::kRetracting ||
                          c.mode == link::ServoMode::kStopped;
        if (t >= kFaultStartS && safe && !r.safe_state_reached) {
          r.safe_state_reached = true;
          r.safe_state_after_s = t - kFaultStartS;
        }
        const bool in_fault = t >= kFaultStartS && t < sc.fault_end_s + 0.5;
        if (c.mode == link::ServoMode::kTracking && t >= 2.0 && !in_fault &&
            std::isfinite(c.record.tip_mm)) {
          err_sq +=
              (c.record.tip_mm - c.record.reference_mm) * (c.record.tip_mm - c.record.reference_mm);
          ++err_n;
        }
        r.final_mode = std::string(link::ToString(c.mode));
      });
  const ServoNodeStats& st = node.stats();
  r.injected = injected + hardware.injected();
  r.detected = st.estimates_rejected + st.commands_rejected + st.sensor_faults +
               node.follower().counters().stale_events;
  r.limit_violations = st.limit_violations;
  r.cycles = st.cycles;
  r.tracking_rms_mm = err_n ? std::sqrt(err_sq / static_cast<double>(err_n)) : 0.0;
  return r;
}

bool InWindow(double t, double end_s) { return t >= kFaultStartS && t < end_s; }

// The scenarios, each fault on the servo node from 4 s on (seed: the loss-and-delay draws).
std::vector<Scenario> FaultScenarioList(std::uint64_t seed) {
  std::vector<Scenario> all;
  {
    Scenario s{"tracker_killed", "no estimate after 4 s (the tracker process killed)"};
    s.safe_state_required = true;
    s.on_estimate = [](link::TargetEstimateSample& e, double&, std::uint64_t& n) {
      if (e.publication_time_s < kFaultStartS) return true;
      ++n;
      return false;
    };
    all.push_back(s);
  }
  {
    Scenario s{"estimates_corrupt",
               "4–6 s: every estimate corrupt in turn (NaN, ±inf, out of range, future, stale)"};
    s.safe_state_required = true;
    s.fault_end_s = 6.0;
    s.on_estimate = [](link::TargetEstimateSample& e, double&, std::uint64_t& n) {
      if (!InWindow(e.publication_time_s, 6.0)) return true;
      switch (n++ % 8) {
        case 0:
          e.motion.offset_mm = kNaN;
          break;
        case 1:
          e.motion.cos_mm[0] = kInf;
          break;
        case 2:
          e.tip_mm.z() = kNaN;
          break;
        case 3:
          e.acquisition_time_s = -kInf;
          break;
        case 4:
          e.motion.frequency_hz = 0.0;
          break;
        case 5:
          e.acquisition_time_s += 1.0, e.publication_time_s += 1.0;
          break;  // the future
        case 6:
          e.acquisition_time_s -= 5.0;
          break;  // stale
        case 7:
          e.target_mm.x() = 1e9;
          break;  // out of range
      }
      return true;
    };
    all.push_back(s);
  }
  {
    Scenario s{"loss_and_delay", "4–8 s: 30 % of estimates lost, the rest delayed 0–150 ms more"};
    auto rng = std::make_shared<std::mt19937_64>(seed);
    s.on_estimate = [rng](link::TargetEstimateSample& e, double& delay, std::uint64_t& n) {
      if (e.publication_time_s < kFaultStartS) return true;
      ++n;
      std::uniform_real_distribution<double> u(0.0, 1.0);
      if (u(*rng) < 0.3) return false;
      delay = 0.15 * u(*rng);
      return true;
    };
    all.push_back(s);
  }
  auto sensor = [&](const std::string& name, const std::string& what, const std::string& iface,
                    hw::FaultKind kind, double length_s, double value, bool safe) {
    Scenario s{name, what};
    s.hardware.push_back({iface, false, kind, kFaultStartS, kFaultStartS + length_s, value});
    s.safe_state_required = safe;
    s.fault_end_s = kFaultStartS + length_s;
    all.push_back(s);
  };
  sensor("tip_sensor_nan", "tip sensor NaN for 50 ms", std::string(hw::iface::kTipPosition),
         hw::FaultKind::kNaN, 0.05, 0, true);
  sensor("base_sensor_inf", "base position +inf for one cycle",
         std::string(hw::iface::kBasePosition), hw::FaultKind::kPosInf, 0.001, 0, true);
  sensor("force_sensor_nan", "force sensor NaN for 100 ms", std::string(hw::iface::kSensorForce),
         hw::FaultKind::kNaN, 0.1, 0, true);
  sensor("tip_sensor_dropout", "tip sensor frozen for 200 ms", std::string(hw::iface::kTipPosition),
         hw::FaultKind::kDropout, 0.2, 0, false);
  sensor("tip_sensor_spike", "tip sensor +5 mm for 20 ms", std::string(hw::iface::kTipPosition),
         hw::FaultKind::kOffset, 0.02, 5.0, false);
  {
    Scenario s{"commands_bad_then_stop", "4 s: standoff NaN, 45 mm, a stale ENABLE; 5 s: STOP"};
    s.safe_state_required = true;
    s.on_cycle = [](ServoNode& node, double t, std::uint64_t& n) {
      auto cmd = [&](link::ServoAction a, double stamp, double standoff) {
        link::ServoCommandSample c;
        c.sequence_number = static_cast<std::uint64_t>(t * 1e3) + static_cast<std::uint64_t>(a);
        c.stamp_s = stamp;
        c.action = a;
        c.standoff_mm = standoff;
        node.HandleCommand(c, t);
      };
      if (std::abs(t - kFaultStartS) < 1e-9) {
        cmd(link::ServoAction::kSetStandoff, t, kNaN);
        cmd(link::ServoAction::kSetStandoff, t, 45.0);
        cmd(link::ServoAction::kEnable, t - 10.0, 8.0);
        n += 3;
      }
      if (std::abs(t - 5.0) < 1e-9) cmd(link::ServoAction::kStop, t, 0.0);
    };
    all.push_back(s);
  }
  return all;
}

}  // namespace

std::vector<FaultScenarioResult> RunFaultScenarios(std::uint64_t seed) {
  std::vector<FaultScenarioResult> out;
  for (const Scenario& s : FaultScenarioList(seed)) out.push_back(Run(s));
  return out;
}

}  // namespace echoservo::live
