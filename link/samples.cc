#include "link/samples.h"

namespace echoservo::link {

std::string_view ToString(ServoMode m) {
  switch (m) {
    case ServoMode::kIdle:
      return "idle";
    case ServoMode::kTracking:
      return "tracking";
    case ServoMode::kHolding:
      return "holding";
    case ServoMode::kRetracting:
      return "retracting";
    case ServoMode::kStopped:
      return "stopped";
    case ServoMode::kFault:
      return "fault";
  }
  return "unknown";
}

std::string_view ToString(ServoAction a) {
  switch (a) {
    case ServoAction::kEnable:
      return "enable";
    case ServoAction::kDisable:
      return "disable";
    case ServoAction::kStop:
      return "stop";
    case ServoAction::kSetStandoff:
      return "set_standoff";
  }
  return "unknown";
}

}  // namespace echoservo::link
