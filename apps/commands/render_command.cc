// Registers no command until the imaging work that owns this file lands.
#include "apps/commands/imaging_commands.h"

namespace echoservo::apps {

void AddRenderCommand(CLI::App&) {}

}  // namespace echoservo::apps
