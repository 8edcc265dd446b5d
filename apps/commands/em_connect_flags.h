// `--em-connect HOST:PORT [--em-tool NAME]` of `track` and `demo`: the flags of the run's live
// EM stream, a library component (live/em_stream_recorder.h: live::EmStreamRecorder, whose
// options the flags fill). Details: docs/report.md#live-em-tracking-from-plus
#pragma once

#include "live/em_stream_recorder.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

using EmConnectFlags = live::EmStreamOptions;
void AddEmConnectFlags(CLI::App& cmd, EmConnectFlags& flags);

}  // namespace echoservo::apps
