// Registration of the imaging subcommands, one file each: info (files), render,
// scanner/ingest/replay (OpenIGTLink streaming), reconstruct (freehand 3D).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddInfoCommand(CLI::App& app);
void AddDetectCommand(CLI::App& app);
void AddRenderCommand(CLI::App& app);
void AddScannerCommand(CLI::App& app);
void AddIngestCommand(CLI::App& app);
void AddReplayCommand(CLI::App& app);
void AddReconstructCommand(CLI::App& app);

}  // namespace echoservo::apps
