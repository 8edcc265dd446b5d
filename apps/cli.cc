#include "apps/cli.h"

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "apps/commands/bench_commands.h"
#include "apps/commands/imaging_commands.h"
#include "apps/commands/lab_command.h"
#include "apps/commands/live_commands.h"
#include "apps/commands/motion_commands.h"
#include "apps/commands/report_command.h"

namespace echoservo::apps {

int RunCli(int argc, char** argv) {
  CLI::App app{
      "echoservo: ultrasound-guided motion-compensation catheter servo, simulator and model lab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "echoservo 0.1.0");
  AddSimCommands(app);
  AddLabCommands(app);
  AddPredictCommand(app);
  AddInfoCommand(app);
  AddDetectCommand(app);
  AddRenderCommand(app);
  AddScannerCommand(app);
  AddIngestCommand(app);
  AddReplayCommand(app);
  AddBenchCommands(app);
  AddLiveCommands(app);
  AddReportCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "echoservo: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace echoservo::apps
