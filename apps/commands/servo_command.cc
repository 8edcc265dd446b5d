// `echoservo servo`: the servo process — subscribes to the tracker's target estimates and
// the operator's commands, drives the catheter at 1 kHz (live::ServoNode on the simulated
// catheter; a rig's driver would take its place behind hw::HardwareInterface), and
// publishes the catheter state. Runs for --duration s (0: until SIGINT/SIGTERM).
// JSON summary: cycles, overruns, estimates accepted/rejected (by reason at the link),
// commands, states published, fault events, limit_violations (must be 0), the mode
// timeline, time to the safe state after the tracker went away, and the tip's RMS error
// to its setpoint while following; limit_interventions (cycles a limit intervened), the time
// at a travel clamp, and the image response check: when it faulted after following began,
// how soon the servo held and retracted, and the time at a clamp after it; the real-time
// settings granted, the cycle timing (wake-up latency and cycle duration percentiles,
// overruns: cycles whose work ended after the next deadline) and the deadline watchdog's
// holds and retractions (live/servo_cycle_clock.h ServoTimingJson; docs/control.md).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "apps/commands/link_flags.h"
#include "apps/commands/live_commands.h"
#include "apps/commands/realtime_flags.h"
#include "apps/commands/set_flags.h"
#include "hw/fault_injection.h"
#include "live/pipeline_clock.h"
#include "live/pipeline_parameters.h"
#include "live/servo_cycle_clock.h"
#include "live/servo_node.h"
#include "live/servo_runtime.h"
#include "live/sim_catheter.h"

namespace echoservo::apps {
namespace {

struct ServoArgs {
  LinkFlags link;
  RealtimeFlags rt;
  SetFlags set;  // --set NAME=VALUE: the follower's and the servo's parameters
  double duration_s = 0.0;
  double standoff_mm = live::LiveFollowerConfig().standoff_mm;
  bool auto_enable = false;
  double sheath_id_mm = 1.59, guidewire_od_mm = 1.50;
  std::uint64_t seed = 1;
  double state_rate_hz = 100.0;
  double stale_after_s = live::LiveFollowerConfig().stale_after_s,
         retract_after_s = live::LiveFollowerConfig().retract_after_s;
  bool json = false;
};

nlohmann::json RejectionsJson(const link::RejectionCounters& c) {
  nlohmann::json j = nlohmann::json::object();
  for (int r = 0; r < static_cast<int>(link::Rejection::kCount); ++r)
    if (c.rejected[r])
      j[std::string(link::ToString(static_cast<link::Rejection>(r)))] = c.rejected[r];
  return j;
}

// What `servo` watches each cycle: the mode timeline, the image response check, the time to
// the safe state after the tracker went away, the tip's error to its setpoint while following,
// and where the servo looks while no tracker is there.
struct ServoWatch {
  ServoWatch(const ServoArgs& args, const live::ServoNode& n, double period)
      : a(args), node(n), period_s(period) {}
  const ServoArgs& a;
  const live::ServoNode& node;
  double period_s;
  link::ServoMode mode = link::ServoMode::kIdle;
  nlohmann::json timeline = nlohmann::json::array();
  std::optional<double> tracker_lost_s, safe_s;
  double err_sq = 0.0;
  std::uint64_t err_n = 0;
  double following_since = -1.0;  // < 0: not following
  // The image response check (docs/control.md): from the first following to its fault, after.
  double following_started_s = -1.0;
  std::optional<double> image_fault_s, image_fault_after_following_s, image_hold_s, image_retract_s;
  double clamp_after_image_fault_s = 0.0;
  // No tracker matched on the target topic: said after 2 s, then every 5 s until one is.
  double next_no_peer_report_s = 2.0;
  bool peer_reported_missing = false, peer_seen = false;

  void Cycle(std::uint64_t k, double t, const live::ServoCycle& c) {
    constexpr double kNoPeerReportS = 5.0;
    if (!peer_seen && k % 100 == 0) {  // 10 Hz: where the servo looks, while nothing is there
      if (node.target_link_stats().matched_publishers > 0) {
        peer_seen = true;
        if (peer_reported_missing)
          std::fprintf(stderr, "servo: tracker found on %s after %.1f s\n",
                       DescribeLink(a.link).c_str(), t);
      } else if (t >= next_no_peer_report_s) {
        peer_reported_missing = true;
        std::fprintf(stderr, "servo: no tracker on %s, topic %s, after %.0f s; still waiting\n",
                     DescribeLink(a.link).c_str(), std::string(link::kTargetTopic).c_str(), t);
        next_no_peer_report_s += kNoPeerReportS;
      }
    }
    if (c.mode != mode || k == 0) {
      mode = c.mode;
      timeline.push_back({{"t_s", t}, {"mode", std::string(link::ToString(mode))}});
      if (!a.json)
        std::fprintf(stderr, "servo: t %.3f s: %s\n", t, std::string(link::ToString(mode)).c_str());
    }
    if (c.mode == link::ServoMode::kTracking && following_started_s < 0) following_started_s = t;
    if ((c.faults & link::fault::kImageNotResponding) && !image_fault_s) {
      image_fault_s = t;
      if (following_started_s >= 0) image_fault_after_following_s = t - following_started_s;
    }
    if (image_fault_s) {
      if (!image_hold_s && c.mode != link::ServoMode::kTracking) image_hold_s = t;
      if (!image_retract_s &&
          (c.mode == link::ServoMode::kRetracting || c.mode == link::ServoMode::kStopped))
        image_retract_s = t;
      if (c.clamped) clamp_after_image_fault_s += period_s;
    }
    if (node.tracker_gone() && !tracker_lost_s) tracker_lost_s = t;
    if (tracker_lost_s && !safe_s &&
        (mode == link::ServoMode::kRetracting || mode == link::ServoMode::kStopped))
      safe_s = t;
    if (mode == link::ServoMode::kTracking) {
      if (following_since < 0) following_since = t;
      if (t - following_since >= 1.0) {  // after the first second of following
        const double e = c.record.tip_mm - c.record.reference_mm;
        err_sq += e * e;
        ++err_n;
      }
    } else {
      following_since = -1.0;
    }
  }
};

nlohmann::json OrNull(const std::optional<double>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

nlohmann::json ServoJson(const ServoWatch& w, const live::ServoNodeStats& s,
                         const link::SubscriberStats& ls, const nlohmann::json& timing_json,
                         std::uint64_t overruns) {
  auto since_fault = [&](const std::optional<double>& t) {
    return t ? nlohmann::json(*t - *w.image_fault_s) : nlohmann::json(nullptr);
  };
  return {{"cycles", s.cycles},
          {"overruns", overruns},
          {"estimates_accepted", s.estimates_accepted},
          {"estimates_rejected", s.estimates_rejected},
          {"link_rejections", RejectionsJson(ls.validation)},
          {"commands_applied", s.commands_applied},
          {"commands_rejected", s.commands_rejected},
          {"states_published", s.states_published},
          {"fault_events", s.fault_events},
          {"limit_violations", s.limit_violations},
          {"limit_interventions", s.limit_interventions},
          {"time_at_clamp_s", s.time_at_clamp_s},
          {"image_not_responding", s.image_not_responding},
          {"image_fault_s", OrNull(w.image_fault_s)},
          {"image_fault_after_following_s", OrNull(w.image_fault_after_following_s)},
          {"image_fault_hold_after_s", since_fault(w.image_hold_s)},
          {"image_fault_retract_after_s", since_fault(w.image_retract_s)},
          {"time_at_clamp_after_image_fault_s",
           w.image_fault_s ? nlohmann::json(w.clamp_after_image_fault_s) : nlohmann::json(nullptr)},
          {"resumes", s.resumes},
          {"final_mode", std::string(link::ToString(w.mode))},
          {"timeline", w.timeline},
          {"tracker_lost_s", OrNull(w.tracker_lost_s)},
          {"safe_state_after_s", w.tracker_lost_s && w.safe_s
                                     ? nlohmann::json(*w.safe_s - *w.tracker_lost_s)
                                     : nlohmann::json(nullptr)},
          {"tip_to_setpoint_rms_mm",
           w.err_n ? nlohmann::json(std::sqrt(w.err_sq / static_cast<double>(w.err_n)))
                   : nlohmann::json(nullptr)},
          {"realtime", timing_json["realtime"]},
          {"timing", timing_json["timing"]},
          {"deadline", timing_json["deadline"]}};
}

void PrintServoSummary(const live::ServoNodeStats& s, const ServoWatch& w,
                       const live::ServoRunResult& r, const control::DeadlineWatchdogConfig&) {
  const control::CycleTimingReport& timing = r.timing;
  std::printf(
      "servo: %llu cycles (%llu overruns), estimates %llu accepted / %llu rejected, commands "
      "%llu, limit violations %llu, final mode %s\n",
      static_cast<unsigned long long>(s.cycles), static_cast<unsigned long long>(timing.overruns),
      static_cast<unsigned long long>(s.estimates_accepted),
      static_cast<unsigned long long>(s.estimates_rejected),
      static_cast<unsigned long long>(s.commands_applied),
      static_cast<unsigned long long>(s.limit_violations),
      std::string(link::ToString(w.mode)).c_str());
  std::printf(
      "servo timing: wake-up latency p50 %.0f / p99 %.0f / p99.9 %.0f / max %.0f us, cycle "
      "p99 %.0f us, overruns %.3f %%; deadline holds %llu, retractions %llu; %s\n",
      timing.wakeup_latency.p50_us, timing.wakeup_latency.p99_us, timing.wakeup_latency.p999_us,
      timing.wakeup_latency.max_us, timing.cycle_duration.p99_us, 100.0 * timing.overrun_fraction,
      static_cast<unsigned long long>(s.deadline_holds),
      static_cast<unsigned long long>(s.deadline_retracts), r.realtime.Summary().c_str());
}

void RunServo(const ServoArgs& a) {
  // The follower and the servo: the pipeline's settings (live/pipeline_parameters.h), the
  // flags, then --set for the stages `servo` runs.
  live::PipelineSettings settings = live::DefaultSettings();
  settings.follower.standoff_mm = a.standoff_mm;
  settings.follower.stale_after_s = a.stale_after_s;
  settings.follower.retract_after_s = a.retract_after_s;
  live::SimCatheter catheter = live::MakeSimCatheter(a.sheath_id_mm, a.guidewire_od_mm, a.seed);
  settings.servo = catheter.servo;
  live::ApplyFor("servo", live::kServoStages, a.set.Parsed(), settings);
  live::ServoNodeOptions so;
  so.follower = settings.follower;
  so.auto_enable = a.auto_enable;
  so.state_rate_hz = a.state_rate_hz;
  so.watchdog = ToWatchdogConfig(a.rt, settings.servo.period_s);
  so.Validate();
  const std::vector<hw::InjectedFault> slow_reads = ToSlowReads(a.rt);
  link::Participant participant(ToParticipantOptions(a.link, "echoservo_servo", "servo"));
  const live::PipelineClock clock(0.05);
  so.link_offset_s = clock.link_offset_s();
  // A slow driver on purpose (--inject-slow-read): the servo reads through it.
  std::optional<hw::FaultInjectingHardware> slow_hw;
  if (!slow_reads.empty()) slow_hw.emplace(*catheter.plant, slow_reads);
  hw::HardwareInterface& hardware =
      slow_hw ? static_cast<hw::HardwareInterface&>(*slow_hw) : *catheter.plant;
  live::ServoNode node(hardware, settings.servo, std::move(catheter.compensator), so, &participant);
  InstallStopSignals();
  if (!a.json)
    std::fprintf(stderr, "servo: 1 kHz on the simulated catheter, DDS domain %d; %s\n",
                 a.link.domain,
                 a.auto_enable ? "following the first estimate" : "waiting for an ENABLE command");
  // The servo runtime on this thread (raised to real time: the DDS threads and the node's
  // state publisher exist already and keep their normal priority).
  live::ServoRuntimeOptions ro;
  ro.clock = live::ServoClock::kRealtime;
  ro.pipeline_clock = &clock;
  ro.realtime = ToRealtimeOptions(a.rt);
  ro.duration_s = a.duration_s;
  ro.stop = [] { return StopRequested(); };
  ServoWatch watch(a, node, settings.servo.period_s);
  const live::ServoRunResult r = live::ServoRuntime(node, ro).Run(
      nullptr,
      [&watch](std::uint64_t k, double t, const live::ServoCycle& c) { watch.Cycle(k, t, c); },
      [&a](const control::RealtimeStatus& rt) {
        for (const std::string& line : rt.refusals)
          std::fprintf(stderr, "servo: %s\n", line.c_str());
        if (!a.json) std::fprintf(stderr, "servo: real time: %s\n", rt.Summary().c_str());
      });
  node.WaitStatesPublished(1.0);  // the publisher thread's last state, counted
  const live::ServoNodeStats& s = node.stats();
  const nlohmann::json timing_json = nlohmann::json::parse(live::ServoTimingJson(
      r.realtime, r.timing, so.watchdog, s.deadline_holds, s.deadline_retracts));
  if (a.json)
    std::cout
        << ServoJson(watch, s, node.target_link_stats(), timing_json, r.timing.overruns).dump(2)
        << "\n";
  else
    PrintServoSummary(s, watch, r, so.watchdog);
}

}  // namespace

void AddServoCommand(CLI::App& app) {
  auto a = std::make_shared<ServoArgs>();
  CLI::App* cmd = app.add_subcommand("servo",
                                     "servo process: target estimates and commands over DDS → 1 "
                                     "kHz control of the simulated catheter → state");
  AddLinkFlags(*cmd, a->link);
  AddRealtimeFlags(*cmd, a->rt);
  cmd->add_option("--duration", a->duration_s, "run length, s (0: until SIGINT/SIGTERM)")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_option("--standoff", a->standoff_mm,
                  "tip-to-target standoff along the axis until a command sets it, mm")
      ->check(CLI::Range(0.0, 30.0));
  cmd->add_flag(
      "--auto-enable", a->auto_enable,
      "follow the first valid estimate and resume after a retraction (default: wait for ENABLE)");
  cmd->add_option("--sheath-id", a->sheath_id_mm, "simulated catheter's sheath inner diameter, mm");
  cmd->add_option("--guidewire-od", a->guidewire_od_mm,
                  "simulated catheter's guidewire outer diameter, mm");
  cmd->add_option("--seed", a->seed, "simulated catheter's calibration seed");
  cmd->add_option("--state-rate", a->state_rate_hz, "catheter state publication rate, Hz")
      ->check(CLI::Range(1.0, 1000.0));
  cmd->add_option("--stale-after", a->stale_after_s, "hold when the newest estimate is older, s")
      ->check(CLI::Range(0.01, 5.0));
  cmd->add_option("--retract-after", a->retract_after_s, "retract after holding this long, s")
      ->check(CLI::Range(0.0, 30.0));
  AddSetFlags(*cmd, a->set);
  cmd->add_flag("--json", a->json, "print the summary as JSON");
  cmd->callback([a] { RunServo(*a); });
}

}  // namespace echoservo::apps
