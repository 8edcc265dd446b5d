// Registers no command until the imaging work that owns this file lands.
#include "apps/commands/imaging_commands.h"

namespace echoservo::apps {

void AddInfoCommand(CLI::App&) {}

}  // namespace echoservo::apps
