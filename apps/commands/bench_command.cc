// `echoservo bench detect [--volumes-per-class N] [--json] [--exhaustive] [--classes A,B]
// [--seed S] [--spine FILE] [--verbose]`: throughput and accuracy of the catheter detectors
// in one process (tracking/detector_accuracy.h) — the fast Radon detector (full search and
// tracking mode), the RANSAC baseline and, with --exhaustive, the exhaustive full-resolution
// Radon reference and its agreement with the fast detector — per simulated volume class and on
// the real catheter-free spine phantom volume. JSON:
//   {"volumes_per_class", "seed", "exhaustive", "throughput_ms": {METHOD: {"mean", "median",
//    "volumes"}}, "classes": [{"name", "description", "catheter", "volumes", "methods":
//    [{"method", "volumes", "detected", "detection_rate", "false_detections", "errors",
//    "angle_deg": {"median", "p95", "count"}, "offset_mm", "tip_mm", "tip_along_mm" (signed,
//    < 0: short of the true tip), "target_mm", "mean_ms",
//    "median_ms"}], "agreement": {"angle_deg", "offset_mm"} | null}], "agreement", "skipped"}
// (non-finite figures, e.g. a median over no volume, are null).
#include <CLI/CLI.hpp>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/commands/bench_commands.h"
#include "apps/output.h"
#include "tracking/accuracy_volumes.h"
#include "tracking/detector_accuracy.h"

namespace echoservo::apps {
namespace {

constexpr const char* kDefaultSpine = "data/plus/SpinePhantomFreehandReconstructed.mha";

struct BenchDetectArgs {
  int volumes_per_class = 3;
  bool json = false;
  bool exhaustive = false;
  bool verbose = false;
  std::vector<std::string> classes;
  std::uint64_t seed = 1;
  std::string spine;
};

nlohmann::json Number(double x) {
  return std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr);
}

nlohmann::json QuantilesJson(const tracking::Quantiles& q) {
  return {{"median", Number(q.median)}, {"p95", Number(q.p95)}, {"count", q.count}};
}

nlohmann::json MethodJson(const tracking::MethodStats& m) {
  return {{"method", m.method},
          {"volumes", m.volumes},
          {"detected", m.detected},
          {"detection_rate", m.detection_rate},
          {"false_detections", m.false_detections},
          {"errors", m.errors},
          {"angle_deg", QuantilesJson(m.angle_deg)},
          {"offset_mm", QuantilesJson(m.offset_mm)},
          {"tip_mm", QuantilesJson(m.tip_mm)},
          {"tip_along_mm", QuantilesJson(m.tip_along_mm)},
          {"target_mm", QuantilesJson(m.target_mm)},
          {"mean_ms", m.mean_detect_ms},
          {"median_ms", Number(m.median_detect_ms)}};
}

nlohmann::json AgreementJson(const tracking::Quantiles& angle, const tracking::Quantiles& offset) {
  if (angle.count == 0) return nullptr;
  return {{"angle_deg", QuantilesJson(angle)}, {"offset_mm", QuantilesJson(offset)}};
}

nlohmann::json ReportJson(const tracking::DetectorAccuracyReport& r, const BenchDetectArgs& a) {
  nlohmann::json j;
  j["volumes_per_class"] = a.volumes_per_class;
  j["seed"] = a.seed;
  j["exhaustive"] = a.exhaustive;
  nlohmann::json tp = nlohmann::json::object();
  for (const auto& m : r.overall)
    tp[m.method] = {
        {"mean", m.mean_detect_ms}, {"median", Number(m.median_detect_ms)}, {"volumes", m.volumes}};
  j["throughput_ms"] = tp;
  nlohmann::json classes = nlohmann::json::array();
  for (const auto& c : r.classes) {
    nlohmann::json cj = {{"name", c.name},
                         {"description", c.description},
                         {"catheter", c.catheter},
                         {"volumes", c.volumes}};
    cj["methods"] = nlohmann::json::array();
    for (const auto& m : c.methods) cj["methods"].push_back(MethodJson(m));
    cj["agreement"] = AgreementJson(c.agreement_angle_deg, c.agreement_offset_mm);
    classes.push_back(cj);
  }
  j["classes"] = classes;
  j["agreement"] = AgreementJson(r.agreement_angle_deg, r.agreement_offset_mm);
  j["skipped"] = r.skipped;
  return j;
}

std::string Cell(const tracking::Quantiles& q, int decimals) {
  if (q.count == 0) return "-";
  auto f = [&](double x) { return std::isfinite(x) ? Fixed(x, decimals) : std::string("inf"); };
  std::string s = f(q.median);
  s += " / ";
  s += f(q.p95);
  return s;
}

void PrintText(const tracking::DetectorAccuracyReport& r, const BenchDetectArgs& a,
               std::ostream& out) {
  out << "bench detect: " << a.volumes_per_class << " volume(s) per class, seed " << a.seed
      << "; times per volume in one process (steady_clock)\n\n";
  Table tp({"method", "volumes", "mean ms", "median ms"});
  for (const auto& m : r.overall)
    tp.AddRow({m.method, std::to_string(m.volumes), Fixed(m.mean_detect_ms, 1),
               Fixed(m.median_detect_ms, 1)});
  tp.Print(out);
  out << "\naccuracy (median / p95 over detected volumes; target: inf = no target found)\n";
  Table t({"class", "method", "detected", "angle deg", "offset mm", "tip mm", "target mm",
           "false det", "ms"});
  for (const auto& c : r.classes)
    for (const auto& m : c.methods) {
      std::string det = std::to_string(m.detected);
      det += "/";
      det += std::to_string(m.volumes);
      t.AddRow({c.name, m.method, det, Cell(m.angle_deg, 3), Cell(m.offset_mm, 3),
                Cell(m.tip_mm, 3), Cell(m.target_mm, 3),
                c.catheter ? std::string("-") : std::to_string(m.false_detections),
                Fixed(m.mean_detect_ms, 1)});
    }
  t.Print(out);
  if (a.exhaustive) {
    out << "\nagreement fast vs exhaustive (angle deg, offset of the fast tip mm; median / p95):\n";
    Table g({"class", "volumes", "angle deg", "offset mm"});
    for (const auto& c : r.classes)
      if (c.agreement_angle_deg.count > 0)
        g.AddRow({c.name, std::to_string(c.agreement_angle_deg.count),
                  Cell(c.agreement_angle_deg, 3), Cell(c.agreement_offset_mm, 3)});
    g.AddRow({"all", std::to_string(r.agreement_angle_deg.count), Cell(r.agreement_angle_deg, 3),
              Cell(r.agreement_offset_mm, 3)});
    g.Print(out);
  }
  for (const auto& s : r.skipped) out << "skipped: " << s << "\n";
}

void Run(const BenchDetectArgs& a, bool spine_given) {
  tracking::DetectorAccuracyOptions o;
  o.volumes_per_class = a.volumes_per_class;
  o.classes = a.classes;
  o.exhaustive = a.exhaustive;
  o.seed = a.seed;
  const std::filesystem::path spine = spine_given ? a.spine : kDefaultSpine;
  if (spine_given || std::filesystem::exists(spine)) o.spine_volume = spine;
  if (a.verbose) o.log = [](const std::string& line) { std::cerr << line << "\n"; };
  auto report = tracking::RunDetectorAccuracy(o);
  if (!spine_given && o.spine_volume.empty()) {
    for (auto& s : report.skipped)
      if (s.rfind("spine_phantom", 0) == 0) {
        s = "spine_phantom: ";
        s += kDefaultSpine;
        s += " not found from the working directory (give --spine FILE)";
      }
  }
  if (a.json) {
    std::cout << ReportJson(report, a).dump(2) << "\n";
  } else {
    PrintText(report, a, std::cout);
  }
}

}  // namespace

void AddBenchCommands(CLI::App& app) {
  auto* bench = app.add_subcommand("bench", "In-process benchmarks: throughput and accuracy");
  bench->require_subcommand(1);
  auto* cmd =
      bench->add_subcommand("detect",
                            "Catheter detectors on simulated volume classes and the spine phantom: "
                            "fast Radon (full, tracking), RANSAC, exhaustive Radon");
  auto args = std::make_shared<BenchDetectArgs>();
  auto* spine =
      cmd->add_option("--spine", args->spine,
                      "the real catheter-free volume (default: " + std::string(kDefaultSpine) +
                          " if present)")
          ->check(CLI::ExistingFile);
  cmd->add_option("--volumes-per-class", args->volumes_per_class,
                  "simulated volumes per class (default 3)")
      ->check(CLI::Range(1, 1000));
  cmd->add_flag("--json", args->json, "print JSON instead of tables");
  cmd->add_flag("--exhaustive", args->exhaustive,
                "also run the exhaustive full-resolution Radon reference (seconds per volume)");
  std::vector<std::string> names;
  for (const auto& c : tracking::VolumeClasses()) names.push_back(c.name);
  cmd->add_option("--classes", args->classes,
                  "volume classes to run, comma-separated (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(names));
  cmd->add_option("--seed", args->seed, "seed of the drawn poses and speckle (default 1)");
  cmd->add_flag("--verbose", args->verbose, "one line per volume on stderr");
  cmd->callback([args, spine] { Run(*args, spine->count() > 0); });
}

}  // namespace echoservo::apps
