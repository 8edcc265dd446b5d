// Registration of `echoservo calibrate`: temporal calibration of a tracked probe against its
// image stream (tracking/temporal_calibration.h) and the simulated water-tank sweep to try
// it on (imaging/sim/water_tank_sweep.h). Details: docs/calibration.md
#pragma once

#include <string>

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddCalibrateCommand(CLI::App& app);

}  // namespace echoservo::apps
