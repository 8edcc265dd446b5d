// `echoservo command ACTION [--standoff MM]`: an operator's command to the servo over DDS
// (enable, disable, stop, standoff), published reliably, then the servo's catheter state
// is awaited until it shows the command applied (enable: tracking or holding; disable and
// stop: stopped; standoff: the new standoff) or --wait s pass (exit status 1). With
// --secure DIR it is the "operator" identity there (a servo started with --secure only
// matches participants whose credentials its CA issued and whose permissions allow it).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "apps/commands/link_flags.h"
#include "apps/commands/live_commands.h"
#include "link/clock.h"
#include "link/dds_link.h"

namespace echoservo::apps {
namespace {

struct CommandArgs {
  LinkFlags link;
  std::string action;
  double standoff_mm = std::nan("");
  double wait_s = 5.0;
  bool json = false;
};

bool Applied(const link::ServoCommandSample& c, const link::CatheterStateSample& s) {
  switch (c.action) {
    case link::ServoAction::kEnable:
      return (s.mode == link::ServoMode::kTracking || s.mode == link::ServoMode::kHolding) &&
             std::abs(s.standoff_mm - c.standoff_mm) < 1e-9;
    case link::ServoAction::kDisable:
    case link::ServoAction::kStop:
      return s.mode == link::ServoMode::kStopped;
    case link::ServoAction::kSetStandoff:
      return std::abs(s.standoff_mm - c.standoff_mm) < 1e-9;
  }
  return false;
}

void RunCommand(const CommandArgs& a) {
  link::ServoCommandSample c;
  if (a.action == "enable")
    c.action = link::ServoAction::kEnable;
  else if (a.action == "disable")
    c.action = link::ServoAction::kDisable;
  else if (a.action == "stop")
    c.action = link::ServoAction::kStop;
  else
    c.action = link::ServoAction::kSetStandoff;
  const bool needs_standoff =
      c.action == link::ServoAction::kEnable || c.action == link::ServoAction::kSetStandoff;
  if (needs_standoff && std::isnan(a.standoff_mm))
    throw std::invalid_argument("command " + a.action + ": --standoff MM is required");
  c.standoff_mm = needs_standoff ? a.standoff_mm : 0.0;

  link::Participant participant(ToParticipantOptions(a.link, "echoservo_operator", "operator"));
  const bool secure = !a.link.secure_dir.empty();
  const std::string identity = a.link.secure_identity.empty() ? "operator" : a.link.secure_identity;
  std::unique_ptr<link::CommandPublisher> pub_owner;
  try {
    pub_owner = std::make_unique<link::CommandPublisher>(participant);
  } catch (const std::runtime_error& e) {
    if (!secure) throw;
    throw std::runtime_error(
        "command: DDS refused a servo_command writer: the permissions of identity '" + identity +
        "' in " + a.link.secure_dir + " do not grant publishing it (" + e.what() + ")");
  }
  link::CommandPublisher& pub = *pub_owner;
  link::StateSubscriber state(participant);
  // Waits for a servo, saying where it looks every second while none is there.
  const std::string where = DescribeLink(a.link) + ", topic " + std::string(link::kCommandTopic);
  bool found = false;
  for (double waited_s = 0; !found && waited_s < a.wait_s;) {
    const double slice_s = std::min(1.0, a.wait_s - waited_s);
    found = pub.WaitForSubscribers(1, slice_s);
    waited_s += slice_s;
    if (!found && waited_s < a.wait_s)
      std::fprintf(stderr, "command: no servo on %s, after %.0f s; still waiting (--wait %g s)\n",
                   where.c_str(), waited_s, a.wait_s);
  }
  if (!found) {
    char wait[32];
    std::snprintf(wait, sizeof wait, "%g", a.wait_s);
    throw std::runtime_error("command " + a.action + ": no servo on " + where +
                             (secure ? " that accepts these credentials" : "") + " within --wait " +
                             wait + " s");
  }
  c.stamp_s = link::NowS();
  c.sequence_number = static_cast<std::uint64_t>(c.stamp_s * 1e6);
  if (!pub.Publish(c)) throw std::runtime_error("command: DDS refused the write");
  link::CatheterStateSample s;
  bool ok = false;
  const double deadline = link::NowS() + a.wait_s;
  while (!ok && link::NowS() < deadline) {
    if (state.WaitTakeLatest(s, 0.1)) ok = Applied(c, s);
  }
  if (a.json) {
    std::cout << nlohmann::json{{"action", a.action},
                                {"applied", ok},
                                {"mode", std::string(link::ToString(s.mode))},
                                {"faults", s.faults},
                                {"standoff_mm", s.standoff_mm}}
                     .dump(2)
              << "\n";
  } else {
    std::printf("%s: %s (servo mode %s, standoff %.2f mm, faults 0x%x)\n", a.action.c_str(),
                ok ? "applied" : "not confirmed", std::string(link::ToString(s.mode)).c_str(),
                s.standoff_mm, s.faults);
  }
  if (!ok)
    throw std::runtime_error("command " + a.action +
                             ": the servo's state did not confirm it within --wait");
}

}  // namespace

void AddOperatorCommand(CLI::App& app) {
  auto a = std::make_shared<CommandArgs>();
  CLI::App* cmd = app.add_subcommand(
      "command", "send an operator command to the servo over DDS and await its state");
  cmd->add_option("action", a->action, "enable | disable | stop | standoff")
      ->required()
      ->check(CLI::IsMember({"enable", "disable", "stop", "standoff"}));
  cmd->add_option("--standoff", a->standoff_mm, "tip-to-target standoff, mm (enable, standoff)")
      ->check(CLI::Range(0.0, 30.0));
  cmd->add_option("--wait", a->wait_s, "seconds to wait for the servo and its confirmation")
      ->check(CLI::Range(0.1, 60.0));
  AddLinkFlags(*cmd, a->link);
  cmd->add_flag("--json", a->json, "print the outcome as JSON");
  cmd->callback([a] { RunCommand(*a); });
}

}  // namespace echoservo::apps
