#include "apps/commands/sim_command.h"

#include <CLI/CLI.hpp>

#include "apps/cli.h"
#include "apps/commands/motion_commands.h"

namespace echoservo::apps {

void AddSimCommands(CLI::App& app) {
  auto* sim = app.add_subcommand("sim", "Simulated catheter experiments (the seed's bench tests)");
  sim->require_subcommand(1);
  AddSimTrack(sim);
  AddSimSweeps(sim);
  AddSimRecord(sim);
  AddSimEffects(sim);
  AddSimMotion(sim);
}

}  // namespace echoservo::apps
