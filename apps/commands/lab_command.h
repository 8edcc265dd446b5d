// Registration of the `lab` subcommands.
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddLabCommands(CLI::App& app);

}  // namespace echoservo::apps
