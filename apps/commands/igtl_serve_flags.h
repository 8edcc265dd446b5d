// `--igtl-serve PORT [--igtl-volumes] [--igtl-bind ADDR]` of `track` and `demo`: the flags of
// the run's detection server, a library component (live/detection_serve.h:
// live::DetectionServe, whose options the flags fill). Details: docs/slicer.md, docs/live.md.
#pragma once

#include "live/detection_serve.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

using IgtlServeFlags = live::DetectionServeOptions;
using IgtlServe = live::DetectionServe;
void AddIgtlServeFlags(CLI::App& cmd, IgtlServeFlags& flags);

}  // namespace echoservo::apps
