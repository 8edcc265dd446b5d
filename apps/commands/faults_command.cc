// `echoservo faults [--seed N] [--json]`: the servo's fault-injection scenarios in
// simulated time (live/fault_scenarios.h) — for each, the faults injected, those
// detected, the limit violations (must be 0) and the time to the safe state. Exit status
// 1 when any scenario violates a limit or misses a required safe state.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apps/commands/live_commands.h"
#include "live/fault_scenarios.h"

namespace echoservo::apps {

void AddFaultsCommand(CLI::App& app) {
  struct Args {
    std::uint64_t seed = 1;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("faults",
                                     "fault injection on the servo (simulated time): faults "
                                     "injected, detected, limit violations, safe state");
  cmd->add_option("--seed", a->seed, "seed of the random packet loss and delay");
  cmd->add_flag("--json", a->json, "print the results as JSON");
  cmd->callback([a] {
    const std::vector<live::FaultScenarioResult> results = live::RunFaultScenarios(a->seed);
    bool ok = true;
    nlohmann::json j = nlohmann::json::array();
    if (!a->json)
      std::printf("%-24s %9s %9s %11s %12s %-11s  %s\n", "scenario", "injected", "detected",
                  "violations", "safe after s", "final mode", "fault");
    for (const auto& r : results) {
      const bool pass = r.limit_violations == 0 && (!r.safe_state_required || r.safe_state_reached);
      ok &= pass;
      j.push_back({{"name", r.name},
                   {"fault", r.fault},
                   {"injected", r.injected},
                   {"detected", r.detected},
                   {"limit_violations", r.limit_violations},
                   {"cycles", r.cycles},
                   {"safe_state_required", r.safe_state_required},
                   {"safe_state_reached", r.safe_state_reached},
                   {"safe_state_after_s", r.safe_state_after_s},
                   {"final_mode", r.final_mode},
                   {"tracking_rms_mm", r.tracking_rms_mm},
                   {"pass", pass}});
      if (!a->json)
        std::printf(
            "%-24s %9llu %9llu %11llu %12s %-11s  %s\n", r.name.c_str(),
            static_cast<unsigned long long>(r.injected),
            static_cast<unsigned long long>(r.detected),
            static_cast<unsigned long long>(r.limit_violations),
            r.safe_state_reached ? std::to_string(r.safe_state_after_s).substr(0, 6).c_str() : "-",
            r.final_mode.c_str(), r.fault.c_str());
    }
    if (a->json) std::cout << j.dump(2) << "\n";
    if (!ok)
      throw std::runtime_error("faults: a scenario violated a limit or missed its safe state");
  });
}

}  // namespace echoservo::apps
