// The echoservo command line: one binary, one subcommand per job. Each subcommand
// registers itself from its own file in apps/commands/ through these hooks.
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

int RunCli(int argc, char** argv);

// Registration hooks, one per command file.
void AddSimCommands(CLI::App& app);

}  // namespace echoservo::apps
