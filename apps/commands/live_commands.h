// Registration of the live-pipeline commands: `demo` (apps/commands/demo_command.cc, the
// closed-loop simulated scanner → tracker → servo run, live/demo_run.h), and the
// separate processes `track` (track_command.cc), `servo` (servo_command.cc) and
// `command` (command_command.cc, operator commands over DDS), `security`
// (security_command.cc: DDS-Security credentials for them) and `faults` (faults_command.cc,
// the servo's fault-injection scenarios).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddLiveCommands(CLI::App& app);  // all five
void AddTrackCommand(CLI::App& app);
void AddServoCommand(CLI::App& app);
void AddOperatorCommand(CLI::App& app);
void AddFaultsCommand(CLI::App& app);
void AddSecurityCommand(CLI::App& app);

}  // namespace echoservo::apps
