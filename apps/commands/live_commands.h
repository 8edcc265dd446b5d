// Registration of the live-pipeline commands: `demo` (apps/commands/demo_command.cc), the
// closed-loop simulated scanner → tracker → servo run (apps/live/demo_run.h).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddLiveCommands(CLI::App& app);

}  // namespace echoservo::apps
