// `echoservo reconstruct` on the real PLUS N-wire sweep (data/plus/NwirePhantomFreehand:
// 97 frames of 820×616, no ImageToProbe in the file) with PLUS's nominal fCal calibration
// (docs/reconstruction.md), at 1 mm to keep the test cheap (one full run, ~2 s CPU); and on
// bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "imaging/io/volume_io.h"
#include "tests/test_util/cli_runner.h"
#include "tests/test_util/sanitizers.h"
#include "tests/test_util/temp_dir.h"

namespace echoservo {
namespace {

using testing::RunCli;
using testing::ShellQuote;

const std::string kNwire = std::string(ECHOSERVO_DATA_DIR) + "/plus/NwirePhantomFreehand.igs.mha";
// PLUS's Image→Probe for the fCal N-wire replay (PlusDeviceSet_Server_Sim_NwirePhantom.xml).
const char* kCalibration = "0 0.08 0 11 -0.08 0 0 50 0 0 0.08 0 0 0 0 1";

TEST(ReconstructCli, RealNwireSweepWritesVolumeAndReportsFrames) {
  ECHOSERVO_RELEASE_SUITE_ONLY(
      "the reconstruction runs under the sanitizers in FreehandReconstruction, the real file's "
      "reader in PlusSequence and ReconstructCli.BadInputIsAClearError");
  testing::TempDir dir("reconstruct_cli", true);
  const std::string out = (dir.path() / "nwire.mha").string();
  // In the Reference tool's frame (the phantom is fixed to it), 1 mm voxels.
  const auto r = RunCli("reconstruct " + ShellQuote(kNwire) + " --out " + ShellQuote(out) +
                        " --spacing 1 --reference Reference --image-to-probe " +
                        ShellQuote(kCalibration) + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["frames_total"], 97);
  EXPECT_EQ(j["frames_used"], 97);  // every ProbeToTracker and ReferenceToTracker is OK
  EXPECT_EQ(j["frames_skipped"], 0);
  EXPECT_EQ(j["skipped"]["invalid_status"], 0);
  EXPECT_EQ(j["calibration_source"], "option");
  EXPECT_EQ(j["output_frame"], "Reference");
  const imaging::Volume v = imaging::ReadVolume(out);
  EXPECT_EQ(v.dims().x(), j["dims"][0].get<int>());
  EXPECT_EQ(v.dims().y(), j["dims"][1].get<int>());
  EXPECT_EQ(v.dims().z(), j["dims"][2].get<int>());
  EXPECT_NEAR(v.spacing_mm().x(), 1.0, 1e-12);
  // One frame spans 819·0.08 × 615·0.08 = 65.5 × 49.2 mm (diagonal 81.9 mm): the box's
  // diagonal is at least that.
  const double diagonal_mm = (v.dims().cast<double>() - Eigen::Vector3d::Ones()).norm() * 1.0;
  EXPECT_GE(diagonal_mm, std::hypot(65.5, 49.2) - 2.0);
  EXPECT_GT(j["voxels_known"].get<long long>(), 0);
  // Voxels hold the echoes: some bright, most of the known ones dark (the frames are black
  // except for the wires).
  int bright = 0;
  for (const std::uint8_t b : v.voxels()) bright += b >= 40;
  EXPECT_GT(bright, 100);
  EXPECT_LT(bright, j["voxels_known"].get<long long>() / 10);
}

TEST(ReconstructCli, BadInputIsAClearError) {
  testing::TempDir dir("reconstruct_cli_bad", true);
  const std::string out = (dir.path() / "v.mha").string();
  const std::string base = "reconstruct " + ShellQuote(kNwire) + " --out " + ShellQuote(out);
  // No calibration in the file and none given.
  auto r = RunCli(base);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("image-to-probe"), std::string::npos) << r.err;
  const std::string cal = " --image-to-probe " + ShellQuote(kCalibration);
  // Too many voxels: the numbers are in the message.
  r = RunCli(base + cal + " --max-voxels 1000");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("limit of 1000"), std::string::npos) << r.err;
  // Bad arguments (each option's checks are also covered by the library tests).
  for (const std::string& args :
       {cal + " --spacing 0", cal + " --roi 0,0,0,1,-1,1",
        std::string(" --image-to-probe '1 0 0 0 0 1 0 0 0 0 0 0 0 0 0 1'"),
        cal + " --reference NoSuchTool"}) {
    r = RunCli(base + args);
    EXPECT_NE(r.rc, 0) << args;
    EXPECT_NE(r.err.find("error"), std::string::npos) << args << ": " << r.err;
  }
  r = RunCli("reconstruct /no/such.igs.mha --out " + ShellQuote(out) + cal);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("no such file"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "v.mha"));  // nothing written on error
}

}  // namespace
}  // namespace echoservo
