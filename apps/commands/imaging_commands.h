// Registration of the imaging subcommands, one file each: info (files), render,
// scanner/ingest/replay (OpenIGTLink streaming), reconstruct (freehand 3D).
#pragma once

#include <vector>

#include "live/pipeline_parameters.h"
#include "tracking/radon_detector.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddInfoCommand(CLI::App& app);
void AddDetectCommand(CLI::App& app);
// `detect --set`: the detector's and the target profile's parameters (stages detector and
// target) over `options`, validated together; throws std::invalid_argument naming the
// parameter (and `detect --set`). Also the Python API's Detector(set=…).
tracking::RadonDetectorOptions WithDetectSet(const tracking::RadonDetectorOptions& options,
                                             const std::vector<live::Assignment>& assignments);
void AddRenderCommand(CLI::App& app);
void AddScannerCommand(CLI::App& app);
void AddIngestCommand(CLI::App& app);
void AddReplayCommand(CLI::App& app);
void AddReconstructCommand(CLI::App& app);

}  // namespace echoservo::apps
