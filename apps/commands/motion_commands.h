// Registration of the target-motion commands: `predict` (heartbeat EKF against
// baselines) and `sim motion` (synthetic motion traces).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddPredictCommand(CLI::App& app);
void AddSimMotion(CLI::App* sim);

}  // namespace echoservo::apps
