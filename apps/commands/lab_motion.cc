#include "apps/commands/lab_motion.h"

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>

#include "apps/commands/lab_json.h"
#include "apps/output.h"
#include "lab/motion_diagnosis.h"

namespace echoservo::apps {
namespace {

lab::MotionModelSpec Spec(const MotionLabFlags& f) {
  return lab::ParseMotionModel(f.model.empty() ? "heartbeat:2" : f.model);
}

nlohmann::json Nullable(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json ParamsJson(const lab::MotionFit& fit) {
  nlohmann::json p = nlohmann::json::object();
  for (const auto& e : fit.estimates)
    p[e.name] = {{"value", e.value}, {"sd", Nullable(e.sd)}, {"unit", e.unit}};
  return p;
}

nlohmann::json GroupsJson(const std::vector<lab::MotionGroup>& groups) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& g : groups) {
    out.push_back({{"group", g.label},
                   {"samples", g.samples},
                   {"rms_mm", g.rms_mm},
                   {"sample_share", g.sample_share},
                   {"error_share", g.error_share}});
  }
  return out;
}

nlohmann::json MotionNoiseJson(const lab::MotionNoise& n) {
  return {{"position_mm", n.position_mm},
          {"difference_mm", Nullable(n.difference_mm)},
          {"difference_order", n.difference_order},
          {"local_fit_mm", Nullable(n.local_fit_mm)}};
}

// Learned shapes of the held-out residual (knots, values in mm) and the Pareto front of
// the formulas distilling the best one.
nlohmann::json MotionShapesJson(const lab::MotionDiagnosis& d) {
  nlohmann::json shapes = nlohmann::json::array();
  for (const auto& s : d.shapes) {
    nlohmann::json knots = nlohmann::json::array();
    for (const auto& a : s.shape.axes) knots.push_back(a.knots);
    shapes.push_back({{"where", s.where},
                      {"variables", s.variables},
                      {"units", s.units},
                      {"knots", knots},
                      {"values_mm", s.shape.values},
                      {"lambda", s.shape.lambda},
                      {"cv_mse_noise", s.held_out_mse},
                      {"gain_noise_var", s.gain}});
  }
  nlohmann::json front = nlohmann::json::array();
  for (const auto& f : d.formulas) {
    nlohmann::json constants = nlohmann::json::array();
    for (const auto& c : f.constants)
      constants.push_back({{"name", c.name}, {"unit", c.unit}, {"value", c.value}});
    front.push_back({{"form", f.form},
                     {"complexity", f.complexity},
                     {"expression", f.expression},
                     {"constants", constants},
                     {"offset", f.offset},
                     {"words", f.words},
                     {"held_out_mse_mm2", f.held_out_mse}});
  }
  return {{"shapes", shapes}, {"pareto_front", front}};
}

void PrintMotionWhere(const std::vector<lab::WhereEntry>& where, double excess) {
  std::cout << "\nwhere the held-out residual lies (excess " << Fixed(excess, 2)
            << " noise variances):\n";
  Table t({"variable", "gain_noise_var", "share_of_excess"});
  for (const auto& e : where)
    t.AddRow({e.variable, Fixed(e.gain, 3), Fixed(100 * e.explained_fraction, 0) + "%"});
  t.Print(std::cout);
}

void PrintGroups(const char* title, const std::vector<lab::MotionGroup>& groups) {
  std::cout << "\nby " << title << ":\n";
  Table t({"group", "samples", "rms_mm", "share_of_samples", "share_of_error_sq"});
  for (const auto& g : groups) {
    t.AddRow({g.label, std::to_string(g.samples), Fixed(g.rms_mm, 4),
              Fixed(100 * g.sample_share, 1) + "%", Fixed(100 * g.error_share, 1) + "%"});
  }
  t.Print(std::cout);
}

}  // namespace

void RunMotionCompare(const MotionLabFlags& f) {
  const estimation::MotionTrace trace = estimation::ReadMotionTrace(f.trace, f.column);
  const lab::MotionModelSpec spec = Spec(f);
  const lab::MotionNoise n = lab::EstimateMotionNoise(trace);
  const double noise = n.position_mm;
  const lab::MotionFit fit = lab::FitMotionModel(spec, trace, noise);
  const lab::MotionBreakdown b = lab::ComputeMotionBreakdown(trace, fit);
  const lab::MotionDiagnoseOptions o;
  const lab::MotionHeldOut held = lab::HeldOutMotion(spec, trace, noise, o, &fit.parameters);
  const std::vector<lab::WhereEntry> where = lab::MotionWhere(trace, fit, held, n, o.block_s);
  if (f.json) {
    std::cout << nlohmann::json{{"trace", f.trace},
                                {"column", trace.column},
                                {"model", lab::FormatMotionModel(spec)},
                                {"rms_mm", fit.rms_mm},
                                {"noise_mm", noise},
                                {"noise", MotionNoiseJson(n)},
                                {"mse_noise", fit.mse_norm},
                                {"cv_mse_noise", held.mse},
                                {"held_out_rms_mm", std::sqrt(held.mse) * noise},
                                {"excess", {{"position", held.mse - 1.0}}},
                                {"where", WhereJson(where)},
                                {"params", ParamsJson(fit)},
                                {"breakdown",
                                 {{"cardiac_phase", GroupsJson(b.cardiac_phase)},
                                  {"time", GroupsJson(b.time)}}},
                                {"fit_seconds", fit.seconds}}
                     .dump(2)
              << "\n";
    return;
  }
  std::cout << "model " << lab::FormatMotionModel(spec) << " on " << f.trace << " (" << trace.column
            << "): position RMS " << Fixed(fit.rms_mm, 4) << " mm (noise " << Fixed(noise, 4)
            << " mm)\n\n";
  Table p({"parameter", "value", "sd", "unit"});
  for (const auto& e : fit.estimates)
    p.AddRow({e.name, Fixed(e.value, 5), std::isfinite(e.sd) ? Fixed(e.sd, 5) : "-", e.unit});
  p.Print(std::cout);
  std::cout << "\nheld-out RMS " << Fixed(std::sqrt(held.mse) * noise, 4) << " mm\n";
  PrintMotionWhere(where, held.mse - 1.0);
  std::cout << "\nWhere the model fails (share of the squared residual):";
  PrintGroups("cardiac phase", b.cardiac_phase);
  PrintGroups("time", b.time);
}

void RunMotionDiagnose(const MotionLabFlags& f, const std::string& propose_dir) {
  const estimation::MotionTrace trace = estimation::ReadMotionTrace(f.trace, f.column);
  const lab::MotionModelSpec spec = Spec(f);
  lab::MotionDiagnoseOptions o;
  o.propose_dir = propose_dir;
  const lab::MotionDiagnosis d = lab::DiagnoseMotion(spec, trace, o);
  if (f.json) {
    nlohmann::json candidates = nlohmann::json::array();
    for (const auto& c : d.candidates) {
      candidates.push_back({{"effect", c.effect},
                            {"rms_mm", c.fit.rms_mm},
                            {"cv_mse_noise", c.cv_mse},
                            {"explained", Nullable(c.explained)},
                            {"score", c.score},
                            {"significant", c.significant},
                            {"params", ParamsJson(c.fit)},
                            {"evidence", c.evidence}});
    }
    nlohmann::json j{{"trace", f.trace},
                     {"column", trace.column},
                     {"model", lab::FormatMotionModel(spec)},
                     {"rms_mm", d.base.rms_mm},
                     {"noise_mm", d.noise_mm},
                     {"noise", MotionNoiseJson(d.noise)},
                     {"cv_mse_noise", d.base_cv_mse},
                     {"held_out_rms_mm", d.held_out_rms_mm},
                     {"excess", {{"position", d.excess}}},
                     {"params", ParamsJson(d.base)},
                     {"adequate", d.adequate},
                     {"verdict", d.verdict},
                     {"summary", d.summary},
                     {"where", WhereJson(d.where)},
                     {"candidates", candidates}};
    if (d.proposal) {
      j["proposal"] = {{"spec", d.proposal->spec},
                       {"file", d.proposal->file},
                       {"equation", d.proposal->equation},
                       {"terms", d.proposal->terms},
                       {"rms_mm", d.proposal->rms_mm},
                       {"cv_mse_noise", d.proposal->cv_mse},
                       {"noise_ratio", d.proposal->noise_ratio},
                       {"params", ParamsJson(d.proposal->fit)}};
    }
    if (!d.shapes.empty()) j["learned"] = MotionShapesJson(d);
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << "model " << lab::FormatMotionModel(spec) << ": position RMS "
            << Fixed(d.base.rms_mm, 4) << " mm (noise " << Fixed(d.noise_mm, 4) << " mm)\n\n";
  Table t({"rank", "candidate", "rms_mm", "held-out excess removed", "significant"});
  int rank = 1;
  for (const auto& c : d.candidates) {
    t.AddRow({std::to_string(rank++), "+" + c.effect, Fixed(c.fit.rms_mm, 4),
              std::isfinite(c.explained) ? lab::PercentText(c.explained) : "-",
              c.significant ? "yes" : "no"});
  }
  t.Print(std::cout);
  PrintMotionWhere(d.where, d.excess);
  std::cout << "\nverdict: " << d.verdict << "\n" << d.summary << "\n";
  if (d.proposal) {
    std::cout << "\nproposal (" << d.proposal->file << "): " << d.proposal->equation
              << "\nheld-out RMS " << Fixed(d.proposal->rms_mm, 4) << " mm (noise "
              << Fixed(d.noise_mm, 4) << " mm)\nnext: echoservo lab compare " << f.trace
              << " --model " << d.proposal->spec << "\n";
  } else if (d.verdict == "missing_effect") {
    std::cout << "\nnext: echoservo lab compare " << f.trace << " --model "
              << lab::FormatMotionModel(spec) << "+" << d.candidates.front().effect << "\n";
  }
}

}  // namespace echoservo::apps
