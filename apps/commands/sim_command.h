// Registration of the `sim` subcommands, one file each.
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddSimTrack(CLI::App* sim);
void AddSimSweeps(CLI::App* sim);
void AddSimRecord(CLI::App* sim);
void AddSimEffects(CLI::App* sim);

}  // namespace echoservo::apps
