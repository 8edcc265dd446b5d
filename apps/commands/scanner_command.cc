// `echoservo scanner --port N [--rate HZ] [--duration S] [--source sim|phantom]`, or
// `--record FILE`: the simulated scanner served over OpenIGTLink or recorded with ground
// truth (docs/openigtlink.md).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <csignal>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "apps/commands/imaging_commands.h"
#include "apps/commands/openigtlink_output.h"
#include "control/trajectory.h"
#include "imaging/igtl/image_message.h"
#include "imaging/igtl/image_server.h"
#include "imaging/igtl/ingest.h"
#include "imaging/igtl/phantom_source.h"
#include "imaging/io/plus_sequence.h"
#include "imaging/io/recording.h"
#include "imaging/io/truth_fields.h"
#include "imaging/sim/simulated_scanner.h"

namespace echoservo::apps {

namespace igtl = imaging::openigtlink;

namespace {

// Pulls `frames` frames from `source` and writes them, with their ground truth as
// per-frame fields (imaging/io/truth_fields.h), as one compressed PLUS sequence. With
// `stamp_delay_s` > 0 each volume is stamped that late (a scanner that stamps at sending) and
// its truth keeps the real acquisition time (AcquisitionTime).
void RecordFrames(imaging::VolumeSource& source, const std::string& path, std::int64_t frames,
                  bool json, double stamp_delay_s) {
  std::vector<imaging::Volume> volumes;
  std::vector<std::optional<imaging::FrameGroundTruth>> truths;
  while (static_cast<std::int64_t>(volumes.size()) < frames) {
    std::optional<imaging::SourceFrame> f = source.Next();
    if (!f) break;
    if (stamp_delay_s > 0) {
      if (f->truth) f->truth->acquisition_s = f->volume.timestamp_s();
      f->volume.set_timestamp_s(f->volume.timestamp_s() + stamp_delay_s);
    }
    volumes.push_back(std::move(f->volume));
    truths.push_back(f->truth);
  }
  imaging::PlusSequence seq = imaging::VolumesToSequence(volumes);
  for (std::size_t i = 0; i < truths.size(); ++i) {
    if (truths[i]) imaging::SetTruthFields(*truths[i], seq.frames[i].fields);
  }
  imaging::WritePlusSequence(seq, path, true);
  if (json) {
    std::cout << nlohmann::json{{"recorded", path}, {"frames", volumes.size()}}.dump(2) << "\n";
  } else {
    std::cout << "recorded " << volumes.size() << " frames with ground truth to " << path << "\n";
  }
}

// --fov AZ,EL,RANGE: the probe's angles (deg) and depth (mm), its beams, samples and voxels
// scaled from the defaults so that their density stays the default's.
void ScannerApplyFov(const std::string& text, imaging::sim::ProbeGeometry& p) {
  double az = 0, el = 0, range = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &az, &el, &range, &tail) != 3 ||
      !(az > 0 && az <= 60 && el > 0 && el <= 30 && range > 0 && range <= 120))
    throw std::invalid_argument("scanner --fov " + text +
                                ": give AZIMUTH_DEG,ELEVATION_DEG,RANGE_MM within 60,30,120");
  const imaging::sim::ProbeGeometry d;
  const double deg = 3.14159265358979323846 / 180.0;
  const double fa = std::sin(0.5 * az * deg) / std::sin(0.5 * d.azimuth_rad);
  const double fe = std::sin(0.5 * el * deg) / std::sin(0.5 * d.elevation_rad);
  const double fr = range / d.range_mm;
  auto scaled = [](int n, double f) { return std::max(8, static_cast<int>(std::lround(n * f))); };
  p.azimuth_rad = az * deg;
  p.elevation_rad = el * deg;
  p.range_mm = range;
  p.n_azimuth = scaled(d.n_azimuth, az * deg / d.azimuth_rad);
  p.n_elevation = scaled(d.n_elevation, el * deg / d.elevation_rad);
  p.n_samples = scaled(d.n_samples, fr);
  p.volume_dims =
      Eigen::Vector3i(scaled(d.volume_dims.x(), fa * fr), scaled(d.volume_dims.y(), fe * fr),
                      scaled(d.volume_dims.z(), fr));
}

}  // namespace

void AddScannerCommand(CLI::App& app) {
  auto* cmd =
      app.add_subcommand("scanner", "Serve simulated volumes as OpenIGTLink IMAGE messages");
  struct Args {
    int port = 18944;
    std::string bind = "127.0.0.1";
    double rate = -1;
    double duration = 0;
    std::int64_t frames = -1;
    std::string source = "sim";
    std::string stamps = "wall";
    int min_clients = 1;
    std::string record;
    bool json = false;
    // --source sim only: the catheter as built (a known mis-setting for the detector's
    // defaults, docs/tuning.md), the annulus's motion, a smaller field of view, the seed.
    double sheath_diameter_mm = -1, wire_diameter_mm = -1, dynamic_range_db = -1;
    double stamp_delay_s = 0;  // --record: volumes stamped this late (truth keeps the real time)
    std::string target_motion, fov;
    std::int64_t seed = -1;
  };
  auto args = std::make_shared<Args>();
  cmd->add_option("--port", args->port, "TCP port (0: ephemeral)")->check(CLI::Range(0, 65535));
  cmd->add_option("--record", args->record,
                  "instead of serving, write --frames volumes (default 25) with their ground truth "
                  "as a PLUS sequence (.igs.mha, compressed)");
  cmd->add_option("--bind", args->bind, "IPv4 address to listen on (0.0.0.0: all)");
  cmd->add_option("--rate", args->rate,
                  "volumes/s (default: the source's rate; 0: as fast as possible)");
  cmd->add_option("--duration", args->duration, "stop after S seconds of streaming (0: endless)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--frames", args->frames, "stop after N frames (-1: endless)");
  cmd->add_option("--source", args->source, "sim (Embree simulated scanner) or phantom (synthetic)")
      ->check(CLI::IsMember({"sim", "phantom"}));
  cmd->add_option("--timestamps", args->stamps,
                  "wall (send time, Unix epoch) or source (acquisition time)")
      ->check(CLI::IsMember({"wall", "source"}));
  cmd->add_option("--min-clients", args->min_clients, "clients to wait for before streaming")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--json", args->json, "print the summary as JSON");
  cmd->add_option("--sheath-diameter", args->sheath_diameter_mm,
                  "sim: the catheter sheath's outer diameter, mm (default 2.5)");
  cmd->add_option("--wire-diameter", args->wire_diameter_mm,
                  "sim: the guidewire's diameter, mm (default 0.9)");
  cmd->add_option("--target-motion", args->target_motion,
                  "sim: the annulus's motion along its normal, a trajectory spec "
                  "(mitral:BPM:P2P_MM, sine:AMP_MM:FREQ_HZ; default: still)");
  cmd->add_option("--fov", args->fov,
                  "sim: AZIMUTH_DEG,ELEVATION_DEG,RANGE_MM: a smaller field of view (default "
                  "60,30,120) at the default beam and voxel density: faster volumes");
  cmd->add_option("--seed", args->seed, "sim: the speckle's seed (default 1)");
  cmd->add_option("--stamp-delay", args->stamp_delay_s,
                  "--record: stamp each volume S s after its acquisition, as a scanner that "
                  "stamps at sending does; the ground truth keeps the real acquisition time "
                  "(AcquisitionTime; the tracker's setting scanner.stamp_delay_s undoes it)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--dynamic-range", args->dynamic_range_db,
                  "sim: the display's log-compression window, dB (default 50)");
  cmd->callback([args] {
    std::unique_ptr<imaging::VolumeSource> source;
    const bool sim_flags = args->sheath_diameter_mm >= 0 || args->wire_diameter_mm >= 0 ||
                           args->dynamic_range_db >= 0 || !args->target_motion.empty() ||
                           !args->fov.empty() || args->seed >= 0;
    if (sim_flags && args->source != "sim")
      throw std::invalid_argument(
          "scanner: --sheath-diameter, --wire-diameter, --dynamic-range, --target-motion, --fov "
          "and --seed are "
          "for --source sim");
    if (args->source == "sim") {
      imaging::sim::SimulatedScannerOptions o;
      if (args->rate > 0) o.rate_hz = args->rate;
      if (args->sheath_diameter_mm >= 0)
        o.catheter_geometry.sheath_diameter_mm = args->sheath_diameter_mm;
      if (args->wire_diameter_mm >= 0)
        o.catheter_geometry.wire_diameter_mm = args->wire_diameter_mm;
      if (args->dynamic_range_db >= 0) o.dynamic_range_db = args->dynamic_range_db;
      if (args->seed >= 0) o.seed = static_cast<std::uint64_t>(args->seed);
      if (!args->target_motion.empty()) {
        std::shared_ptr<control::Trajectory> motion = control::MakeTrajectory(args->target_motion);
        o.target_displacement_mm = [motion](double t) { return motion->Evaluate(t).position_mm; };
      }
      if (!args->fov.empty()) ScannerApplyFov(args->fov, o.probe);
      o.Validate();
      source = std::make_unique<imaging::sim::SimulatedScanner>(o);
    } else {
      igtl::PhantomOptions o;
      if (args->rate > 0) o.rate_hz = args->rate;
      source = std::make_unique<igtl::PhantomSource>(o);
    }
    if (args->stamp_delay_s > 0 && args->record.empty())
      throw std::invalid_argument("scanner --stamp-delay: only with --record FILE");
    if (!args->record.empty()) {
      RecordFrames(*source, args->record, args->frames > 0 ? args->frames : 25, args->json,
                   args->stamp_delay_s);
      return;
    }
    igtl::ImageServerOptions so;
    so.bind_address = args->bind;
    so.port = args->port;
    if (args->rate >= 0) so.rate_hz = args->rate;
    so.max_duration_s = args->duration;
    so.max_frames = args->frames;
    so.min_clients = args->min_clients;
    so.timestamps = args->stamps == "wall" ? igtl::ImageServerOptions::Timestamps::kSendTime
                                           : igtl::ImageServerOptions::Timestamps::kSource;
    Serve(*source, so, args->json);
  });
}

}  // namespace echoservo::apps
