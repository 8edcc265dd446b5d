// The echoservo command line: one binary, one subcommand per job. Each subcommand
// registers itself from its own file in apps/commands/ through these hooks.
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace echoservo::apps {

int RunCli(int argc, char** argv);

// One command line (without the program name) run in this process, as `echoservo ARGS…`
// would run it: what it writes to std::cout and std::cerr is returned in `out` and `err`
// instead; the exit status is returned. For the Python API (python/): the same commands, the
// same checks and messages. Not reentrant (std::cout is redirected for the call).
int RunCommand(const std::vector<std::string>& args, std::string& out, std::string& err);

// The echoservo program that commands starting processes of their own (`tune`'s trials) run:
// this process's own (/proc/self/exe) unless set. The Python module sets the program built
// beside it (its process is the interpreter). Throws std::runtime_error when unknown.
void SetProgramPath(const std::string& path);
std::string ProgramPath();

// Registration hooks, one per command file.
void AddSimCommands(CLI::App& app);

}  // namespace echoservo::apps
