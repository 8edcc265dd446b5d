// Registration of the target-motion commands: `predict` (heartbeat EKF against
// baselines) and `sim motion` (synthetic motion traces).
#pragma once

#include <cstdint>
#include <string>

#include "estimation/motion_trace.h"
#include "estimation/prediction_eval.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

// `echoservo predict`'s settings, one per flag (defaults as the flags').
struct PredictFlags {
  std::string trace;
  std::string column;
  std::string truth;
  double latency_s = 0.1;
  double rate_hz = 0.0;
  std::string harmonics = "auto";
  bool respiration = false;     // force the respiration state on
  bool no_respiration = false;  // force it off (default: automatic)
  double noise_mm = 0.0;
  double init_window_s = 4.0;
  double min_hz = 0.6;
  double max_hz = 3.0;
  bool json = false;
  std::string realistic;  // a realistic trace class instead of TRACE
  std::uint64_t seed = 1;
  double duration_s = 30.0;
  std::string combination = "best";
};

void AddPredictCommand(CLI::App& app);
// `predict --json`'s object (as text) for a trace in memory, scored against `truth` when not
// null, and the run behind it with its series (the Python API: python/). Throws
// std::invalid_argument like the command.
struct PredictResult {
  std::string json;
  estimation::PredictionRun run;
};
PredictResult PredictInMemory(const PredictFlags& f, const estimation::MotionTrace& trace,
                              const estimation::MotionTrace* truth);
void AddSimMotion(CLI::App* sim);

}  // namespace echoservo::apps
