// `echoservo predict TRACE`: the predictor competition the live tracker ships (heartbeat
// EKF, autoregressive predictor, baselines; estimation/predictor_competition.h) and each
// competitor alone, on a motion trace.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apps/commands/motion_commands.h"
#include "apps/output.h"
#include "estimation/prediction_eval.h"
#include "estimation/realistic_heart_trace.h"

namespace echoservo::apps {
namespace {

int ParseHarmonics(const std::string& text) {
  if (text == "auto") return 0;
  int n = 0;
  try {
    std::size_t used = 0;
    n = std::stoi(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw std::invalid_argument("--harmonics: '" + text + "' is neither 'auto' nor a number");
  }
  if (n < 1 || n > estimation::HeartbeatEkf::kMaxHarmonics) {
    throw std::invalid_argument("--harmonics must be 'auto' or in [1, 12]");
  }
  return n;
}

std::string RespirationMode(const PredictFlags& f) {
  return f.respiration ? "on" : f.no_respiration ? "off" : "auto";
}

nlohmann::json ScoreJson(const estimation::PredictionScore& s) {
  return {{"rms_mm", s.rms_mm}, {"mae_mm", s.mae_mm}, {"max_mm", s.max_mm}};
}

// The autoregressive reference (null with a note when the trace is too short) and the
// second half's scores, where it is scored.
void AddReferenceJson(const estimation::PredictionRun& r, nlohmann::json& j) {
  if (!r.has_reference) {
    j["reference"] = nullptr;
    j["reference_note"] = r.reference_note;
    j["second_half"] = nullptr;
    return;
  }
  const auto& a = r.reference;
  const auto& h = r.second_half;
  nlohmann::json candidates = nlohmann::json::array();
  for (std::size_t i = 0; i < a.candidates.size(); ++i)
    candidates.push_back(
        {{"order", a.candidates[i]}, {"validation_rms_mm", a.validation_rms_mm[i]}});
  nlohmann::json ref = ScoreJson(h.reference);
  ref.update({{"model", "autoregressive direct, least squares on the first half"},
              {"order", a.order},
              {"stride", a.stride},
              {"history_s", a.history_s},
              {"split_s", a.split_s},
              {"trained_rows", a.trained},
              {"held", a.held},
              {"cross_validation", candidates}});
  j["reference"] = ref;
  nlohmann::json competitors = nlohmann::json::object();
  for (const auto& c : h.competitors) competitors[c.name] = ScoreJson(c);
  j["second_half"] = {{"from_s", h.split_s},
                      {"scored", h.scored},
                      {"shipped", ScoreJson(h.shipped)},
                      {"competitors", competitors},
                      {"shipped_over_reference", h.shipped.rms_mm / h.reference.rms_mm}};
}

// The trace must be a readable file: a folder or a missing path is named with why (the
// CSV reader would only say "read error" for a folder).
void CheckTraceFile(const std::string& path) {
  constexpr const char* kExpected =
      "expected a motion-trace CSV file: a header line with 't' (s) and position columns (mm), "
      "e.g. t,position,truth,heart_rate_bpm as `echoservo sim motion --out FILE` writes";
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status))
    throw std::invalid_argument(path + ": no such file; " + kExpected);
  if (std::filesystem::is_directory(status))
    throw std::invalid_argument(path + ": is a directory; " + kExpected);
  if (!std::filesystem::is_regular_file(status))
    throw std::invalid_argument(path + ": not a regular file; " + kExpected);
}

// The trace to predict and its reference: a file's columns, or a generated realistic trace
// (--realistic); o.truth points at `truth` when one is asked for.
void LoadPredictTraces(const PredictFlags& f, estimation::MotionTrace& trace,
                       estimation::MotionTrace& truth, estimation::PredictionRunOptions& o) {
  if (!f.realistic.empty()) {
    if (!f.trace.empty())
      throw std::invalid_argument("predict: give either TRACE or --realistic CLASS, not both");
    if (!f.column.empty() && f.column != "position")
      throw std::invalid_argument("predict --realistic: the trace has one column, 'position'");
    estimation::RealisticHeartOptions ro = estimation::RealisticHeartClass(f.realistic, f.seed);
    ro.duration_s = f.duration_s;
    trace = estimation::GenerateRealisticHeartTrace(ro, &truth);
    if (!f.truth.empty()) {
      if (f.truth != "truth")
        throw std::invalid_argument("predict --realistic: --truth must be 'truth' (noise-free)");
      o.truth = &truth;
    }
  } else {
    if (f.trace.empty())
      throw std::invalid_argument("predict: a TRACE file (or --realistic CLASS) is required");
    CheckTraceFile(f.trace);
    trace = estimation::ReadMotionTrace(f.trace, f.column);
    if (!f.truth.empty()) {
      truth = estimation::ReadMotionTrace(f.trace, f.truth);
      o.truth = &truth;
    }
  }
}

// `predict --json`'s object.
nlohmann::json PredictionJson(const PredictFlags& f, const estimation::MotionTrace& trace,
                              const estimation::PredictionRun& r) {
  const double zoh = r.baselines.front().rms_mm;
  const double bpm = r.heart_rate.bpm();
  const bool bpm_valid = r.heart_rate.significant;
  nlohmann::json baselines = nlohmann::json::object();
  for (const auto& b : r.baselines) baselines[b.name] = ScoreJson(b);
  nlohmann::json competitors = nlohmann::json::object();
  for (const auto& c : r.competitors) competitors[c.name] = ScoreJson(c);
  nlohmann::json chosen = nlohmann::json::object();
  for (const auto& [name, fraction] : r.chosen_fraction) chosen[name] = fraction;
  nlohmann::json shipped = ScoreJson(r.shipped);
  shipped["switches"] = r.switches;
  nlohmann::json j = {
      {"trace", f.trace},
      {"column", trace.column},
      {"reference", f.truth.empty() ? trace.column : f.truth},
      {"latency_s", f.latency_s},
      {"measurements", r.measurements},
      {"measurement_rate_hz", r.measurement_rate_hz},
      {"gaps", r.gaps},
      {"scored", r.scored},
      {"scored_from_s", r.scored_from_s},
      {"unscored_in_gaps", r.unscored_in_gaps},
      {"ekf_rms_mm", r.shipped.rms_mm},
      {"shipped", shipped},
      {"competitors", competitors},
      {"chosen", chosen},
      {"ekf",
       {{"rms_mm", r.ekf.rms_mm},
        {"mae_mm", r.ekf.mae_mm},
        {"max_mm", r.ekf.max_mm},
        {"harmonics", r.harmonics},
        {"heart_rate_bpm", bpm_valid ? nlohmann::json(bpm) : nlohmann::json(nullptr)},
        {"filter_rate_bpm", 60.0 * r.rate_hz},
        {"heart_rate",
         {{"significant", r.heart_rate.significant},
          {"candidate_bpm", r.heart_rate.bpm()},
          {"window_s", r.heart_rate_window_s},
          {"p_value", r.heart_rate.p_value},
          {"acf_period_s", r.heart_rate.acf_period_s},
          {"acf_at_period", r.heart_rate.acf_at_period},
          {"fundamental_share", r.heart_rate.fundamental_share},
          {"corrections", r.heart_rate.corrections},
          {"reason", r.heart_rate.reason}}},
        {"reacquisitions", r.reacquisitions},
        {"noise_mm", r.noise_mm},
        {"respiration", r.respiration},
        {"respiration_mode", RespirationMode(f)},
        {"offset_rate_q_mm_s", r.offset_rate_q_mm_s},
        {"accepted", r.accepted},
        {"rejected", r.rejected},
        {"initialisations", r.initialisations}}},
      {"autoregressive", {{"order", r.ar_order}, {"horizon_steps", r.ar_horizon_steps}}},
      {"autoregressive_ls", {{"order", r.ls_ar_order}, {"stride", r.ls_ar_stride}}},
      {"ekf_ar_blend",
       {{"ekf_weight", std::isfinite(r.blend_ekf_weight) ? nlohmann::json(r.blend_ekf_weight)
                                                         : nlohmann::json(nullptr)}}},
      {"baselines", baselines},
      {"zoh_over_ekf", zoh / r.shipped.rms_mm},
      {"constant_velocity_kf_accel_psd_mm2_s3", r.cv_accel_psd_mm2_s3}};
  AddReferenceJson(r, j);
  return j;
}

// The run's figures: JSON (--json) or a table and a line on the EKF.
void PrintPrediction(const PredictFlags& f, const estimation::MotionTrace& trace,
                     const estimation::PredictionRun& r) {
  const double zoh = r.baselines.front().rms_mm;
  // The heart rate from the newest window's fundamental: none unless significant.
  const double bpm = r.heart_rate.bpm();
  const bool bpm_valid = r.heart_rate.significant;
  if (f.json) {
    std::cout << PredictionJson(f, trace, r).dump(2) << "\n";
    return;
  }
  std::cout << "trace " << (f.realistic.empty() ? f.trace : trace.source) << " (column "
            << trace.column << ", " << r.measurements << " measurements at "
            << Fixed(r.measurement_rate_hz, 1) << " Hz, " << r.gaps << " gap(s)); prediction "
            << Fixed(1000.0 * f.latency_s, 0) << " ms ahead, scored on " << r.scored
            << " instants from t = " << Fixed(r.scored_from_s, 2) << " s against "
            << (f.truth.empty() ? trace.column : f.truth) << "\n\n";
  Table t({"predictor", "rms_mm", "mae_mm", "max_mm", "vs_zero_order_hold", "chosen"});
  t.AddRow({"shipped (competition)", Fixed(r.shipped.rms_mm, 3), Fixed(r.shipped.mae_mm, 3),
            Fixed(r.shipped.max_mm, 3), Fixed(r.shipped.rms_mm / zoh, 3),
            std::to_string(r.switches) + " switches"});
  for (std::size_t i = 0; i < r.competitors.size(); ++i) {
    const auto& c = r.competitors[i];
    t.AddRow({c.name, Fixed(c.rms_mm, 3), Fixed(c.mae_mm, 3), Fixed(c.max_mm, 3),
              Fixed(c.rms_mm / zoh, 3), Fixed(100.0 * r.chosen_fraction[i].second, 1) + " %"});
  }
  t.Print(std::cout);
  if (r.has_reference) {
    const auto& h = r.second_half;
    std::cout << "\nsecond half (from t = " << Fixed(h.split_s, 2) << " s, " << h.scored
              << " instants): shipped " << Fixed(h.shipped.rms_mm, 3)
              << " mm RMS, autoregressive reference (order " << r.reference.order << ", lags "
              << Fixed(1000.0 * r.reference.history_s, 0) << " ms, fitted on the first half) "
              << Fixed(h.reference.rms_mm, 3) << " mm: shipped/reference "
              << Fixed(h.shipped.rms_mm / h.reference.rms_mm, 3) << "\n";
  } else {
    std::cout << "\nno autoregressive reference: " << r.reference_note << "\n";
  }
  std::cout << "\nEKF: " << r.harmonics << " harmonics, heart rate "
            << (bpm_valid ? Fixed(bpm, 1) + " bpm"
                          : std::string("none (") + r.heart_rate.reason + ")")
            << " over the last " << Fixed(r.heart_rate_window_s, 1) << " s, filter rate "
            << Fixed(60.0 * r.rate_hz, 1) << " bpm at the end, " << r.reacquisitions
            << " rate re-acquisition(s), measurement noise " << Fixed(r.noise_mm, 3) << " mm, "
            << r.accepted << " accepted, " << r.rejected << " rejected, " << r.initialisations
            << " initialisation(s), respiration term "
            << (r.respiration ? "on (" + Fixed(r.offset_rate_q_mm_s, 2) + " mm/s/√s)" : "off")
            << " [" << RespirationMode(f) << "]\n";
}

// The prediction's options from the flags (o.truth is set by the caller).
estimation::PredictionRunOptions PredictOptions(const PredictFlags& f) {
  estimation::PredictionRunOptions o;
  if (f.combination == "weighted") {
    o.combination = estimation::Combination::kWeighted;
  } else if (f.combination != "best") {
    throw std::invalid_argument("--combination must be 'best' or 'weighted', not '" +
                                f.combination + "'");
  }
  o.latency_s = f.latency_s;
  o.measurement_rate_hz = f.rate_hz;
  o.ekf.harmonics = ParseHarmonics(f.harmonics);
  o.ekf.respiration = f.respiration      ? estimation::Respiration::kOn
                      : f.no_respiration ? estimation::Respiration::kOff
                                         : estimation::Respiration::kAuto;
  o.ekf.noise_mm = f.noise_mm;
  o.ekf.init_window_s = f.init_window_s;
  o.ekf.min_rate_hz = f.min_hz;
  o.ekf.max_rate_hz = f.max_hz;
  return o;
}

void RunPredict(const PredictFlags& f) {
  estimation::MotionTrace trace;
  estimation::MotionTrace truth;
  estimation::PredictionRunOptions o = PredictOptions(f);
  LoadPredictTraces(f, trace, truth, o);
  PrintPrediction(f, trace, estimation::RunPrediction(trace, o));
}

}  // namespace

PredictResult PredictInMemory(const PredictFlags& f, const estimation::MotionTrace& trace,
                              const estimation::MotionTrace* truth) {
  estimation::ValidateMotionTrace(trace);
  if (truth) estimation::ValidateMotionTrace(*truth);
  estimation::PredictionRunOptions o = PredictOptions(f);
  o.truth = truth;
  o.keep_series = true;
  PredictResult r;
  r.run = estimation::RunPrediction(trace, o);
  r.json = PredictionJson(f, trace, r.run).dump();
  return r;
}

void AddPredictCommand(CLI::App& app) {
  auto f = std::make_shared<PredictFlags>();
  auto* cmd = app.add_subcommand(
      "predict",
      "Prediction through the imaging delay on a motion trace: the predictor competition the "
      "tracker ships (heartbeat EKF, autoregressive, baselines) and each competitor alone");
  cmd->add_option("TRACE", f->trace,
                  "CSV with a header: time column 't' (s) and position columns (mm)");
  cmd->add_option("--realistic", f->realistic,
                  "Instead of TRACE, a generated realistic heart trace of this class: regular, "
                  "ectopic, rate_steps, breathing, noisy, sparse, fast "
                  "(estimation/realistic_heart_trace.h; --truth truth scores the noise-free "
                  "motion)");
  cmd->add_option("--seed", f->seed, "Seed of the --realistic trace (default 1)");
  cmd->add_option("--duration", f->duration_s, "Length of the --realistic trace, s (default 30)");
  cmd->add_option("--combination", f->combination,
                  "What ships: 'best' (the best recent predictor, default) or 'weighted' "
                  "(inverse-MSE mix)");
  cmd->add_option("--latency", f->latency_s,
                  "Prediction horizon past the newest measurement, s (default 0.1)");
  cmd->add_option("--column", f->column, "Position column (default: the first after 't')");
  cmd->add_option("--truth", f->truth,
                  "Score against this column (e.g. a noise-free one) instead of --column");
  cmd->add_option(
      "--rate", f->rate_hz,
      "Measure at this rate (Hz) by interpolating the trace, e.g. 25 for a volume rate; "
      "the full trace stays the reference (default: every sample)");
  cmd->add_option("--harmonics", f->harmonics,
                  "Harmonic count, 1-12, or auto (BIC at initialisation)");
  auto* on = cmd->add_flag("--respiration", f->respiration,
                           "Always carry the slow respiration (offset-rate) state (default: "
                           "automatic, when the data show a slow trend)");
  cmd->add_flag("--no-respiration", f->no_respiration, "Never carry the respiration state")
      ->excludes(on);
  cmd->add_option("--noise", f->noise_mm,
                  "Measurement noise sigma, mm (default: from the initial fit)");
  cmd->add_option("--init-window", f->init_window_s,
                  "Seconds of data for the initial fit (default 4)");
  cmd->add_option("--min-hz", f->min_hz, "Lowest heart rate searched, Hz (default 0.6 = 36 bpm)");
  cmd->add_option("--max-hz", f->max_hz, "Highest heart rate searched, Hz (default 3 = 180 bpm)");
  cmd->add_flag("--json", f->json, "Print JSON");
  cmd->callback([f] { RunPredict(*f); });
}

}  // namespace echoservo::apps
