// Registration of the `bench` subcommands (in-process benchmarks that print throughput and
// accuracy): `bench detect` (apps/commands/bench_command.cc).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddBenchCommands(CLI::App& app);

}  // namespace echoservo::apps
