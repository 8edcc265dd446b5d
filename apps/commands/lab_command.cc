// `echoservo lab compare|diagnose|report`: the model lab.
#include "apps/commands/lab_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apps/commands/effect_catalog_flags.h"
#include "apps/commands/lab_json.h"
#include "apps/commands/lab_motion.h"
#include "apps/output.h"
#include "hw/effect_registry.h"
#include "lab/catheter_where.h"
#include "lab/diagnosis.h"
#include "lab/lab_report.h"
#include "lab/model_fit.h"
#include "lab/shape_learning.h"

namespace echoservo::apps {
namespace {

struct LabFlags {
  std::string dataset;
  std::string model;  // empty: seed for a dataset, heartbeat:2 for a motion trace
  bool skip_bad = false;
  bool json = false;
  int stride = 4;
  std::string residuals_dir;
  std::string column;                    // motion traces only
  std::string propose_dir;               // where `diagnose` writes a proposed effect file
  std::vector<std::string> learn_along;  // variables a shape is learnt along (`diagnose`)
  std::vector<std::string> candidates;   // extra candidates: effect files (@path) or plugin effects
  CatalogFlags catalog;
};

// The effect catalog (built-ins, plugins, and the effect files the SPEC names) and the
// model's effects.
struct Model {
  hw::EffectRegistry* catalog;
  std::vector<std::string> effects;
  std::string spec;  // printable, files as @path
};

Model ResolveModel(const LabFlags& f) {
  Model m;
  m.catalog = &BuildCatalog(f.catalog);
  m.effects = hw::ResolveModelSpec(f.model.empty() ? "seed" : f.model, *m.catalog);
  m.spec = hw::FormatModelSpec(m.effects, *m.catalog);
  return m;
}

// The diagnosis's candidates: every catalog effect not in the model plus the user's
// (--candidate). A user candidate that cannot be read is skipped and reported, the
// diagnosis goes on with the others.
std::vector<std::string> Candidates(const LabFlags& f, const Model& m,
                                    std::vector<std::string>& skipped) {
  std::vector<std::string> out;
  for (const std::string& e : m.catalog->Names()) {
    if (std::find(m.effects.begin(), m.effects.end(), e) == m.effects.end() &&
        m.catalog->Source(e).empty())
      out.push_back(e);
  }
  for (const std::string& token : f.candidates) {
    try {
      for (const std::string& e : hw::ResolveModelSpec(token, *m.catalog)) {
        if (std::find(m.effects.begin(), m.effects.end(), e) == m.effects.end() &&
            std::find(out.begin(), out.end(), e) == out.end())
          out.push_back(e);
      }
    } catch (const std::exception& e) {
      skipped.push_back(token + ": " + e.what());
      std::cerr << "echoservo: skipped candidate " << token << ": " << e.what() << "\n";
    }
  }
  return out;
}

// Default folder of proposals: beside the dataset, "<dataset>_proposal".
std::string ProposeDir(const LabFlags& f) {
  if (!f.propose_dir.empty()) return f.propose_dir;
  std::filesystem::path p = std::filesystem::path(f.dataset).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p.string() + "_proposal";
}

// The columns of a file's header line (first line, BOM and CR stripped, names trimmed).
std::vector<std::string> HeaderColumns(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::getline(in, line);
  if (line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= line.size()) {
    const std::size_t end = std::min(line.find(',', start), line.size());
    std::string name = line.substr(start, end - start);
    const auto first = name.find_first_not_of(" \t\r");
    const auto last = name.find_last_not_of(" \t\r");
    out.push_back(first == std::string::npos ? "" : name.substr(first, last - first + 1));
    start = end + 1;
  }
  return out;
}

std::string JoinColumns(const std::vector<std::string>& columns, std::size_t most = 6) {
  std::string out;
  for (std::size_t i = 0; i < columns.size() && i < most; ++i)
    out += (i == 0 ? "" : ", ") + columns[i];
  if (columns.size() > most) out += ", ...";
  return out;
}

// A catheter trial's CSV has all of the trial format's required columns
// (docs/trial_format.md).
bool IsCatheterTrialHeader(const std::vector<std::string>& columns) {
  for (const char* c : {"t", "base_cmd", "base", "tip", "force"})
    if (std::find(columns.begin(), columns.end(), c) == columns.end()) return false;
  return true;
}

bool IsMotionModelSpec(const std::string& model) { return model.rfind("heartbeat", 0) == 0; }

// The kind of data decides the lab: a folder is a catheter dataset (catheter models:
// seed[+effect...]); a regular file is a target-motion trace (motion models:
// heartbeat:N[+...]), unless its columns are a catheter trial's. A model of the other
// kind, or a single catheter trial, is an error naming the file, its kind and the model.
// Returns true (and fills `m`) for a motion trace.
bool IsMotionTrace(const LabFlags& f, MotionLabFlags& m) {
  if (!std::filesystem::is_regular_file(f.dataset)) {
    if (IsMotionModelSpec(f.model) && std::filesystem::is_directory(f.dataset)) {
      throw std::invalid_argument(
          f.dataset + " is a catheter dataset (a folder of trials); --model '" + f.model +
          "' is a motion-trace model (for a motion-trace CSV); a catheter model is seed or "
          "seed+EFFECT (echoservo sim effects lists them)");
    }
    return false;
  }
  const std::vector<std::string> columns = HeaderColumns(f.dataset);
  if (IsCatheterTrialHeader(columns)) {
    std::filesystem::path dir = std::filesystem::path(f.dataset).parent_path();
    if (dir.empty()) dir = ".";
    const std::string model = f.model.empty() ? "seed" : f.model;
    throw std::invalid_argument(
        f.dataset + " is a catheter trial (columns " + JoinColumns(columns) + "), not a motion " +
        "trace; " +
        (IsMotionModelSpec(model)
             ? "--model '" + model + "' is a motion-trace model and does not apply to it; "
             : std::string()) +
        "the catheter lab fits a catheter model to the dataset folder that holds the trials "
        "(CSV + JSON pairs): echoservo lab compare " +
        dir.string() + " --model " + (IsMotionModelSpec(model) ? std::string("seed") : model));
  }
  if (!f.model.empty() && !IsMotionModelSpec(f.model)) {
    throw std::invalid_argument(
        f.dataset + " is a motion trace (columns " + JoinColumns(columns) + "); --model '" +
        f.model +
        "' is a catheter model (for a dataset folder of catheter trials); a motion model is "
        "heartbeat:N[+respiration][+rate_drift][+harmonic][+@term.json] (default heartbeat:2)");
  }
  m = {f.dataset, f.model.empty() ? "heartbeat:2" : f.model, f.column, f.json};
  return true;
}

// Writes each trial with its model predictions as extra columns (trial format).
void WriteResiduals(const std::string& dir, const lab::LabDataset& ds, const lab::FitResult& r) {
  for (std::size_t k = 0; k < r.trials.size(); ++k) {
    formats::Trial t = ds.trials[k].trial;
    t.extra_names = {"tip_model", "force_model", "velocity"};
    t.extra_columns = {r.trials[k].prediction.tip_mm, r.trials[k].prediction.force_n,
                       ds.trials[k].velocity_mm_s};
    formats::WriteTrial(dir, t);
  }
}

lab::LabDataset Load(const LabFlags& f) {
  lab::LabDatasetOptions o;
  o.skip_bad = f.skip_bad;
  o.stride = f.stride;
  lab::LabDataset ds = lab::LoadLabDataset(f.dataset, o);
  for (const std::string& s : ds.skipped) std::cerr << "echoservo: skipped " << s << "\n";
  return ds;
}

// Progress lines go to stderr, and only once the command has run for more than a second.
lab::FitOptions Options(const Model& m) {
  lab::FitOptions o;
  o.registry = m.catalog;
  const auto start = std::chrono::steady_clock::now();
  o.progress = [start](const std::string& line) {
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(1)) {
      std::cerr << "echoservo: " << line << "\n";
    }
  };
  return o;
}

nlohmann::json NullIfNan(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

std::string PercentOrDash(double fraction) {
  if (!std::isfinite(fraction)) return "-";
  const double pct = std::round(100.0 * fraction);
  return Fixed(pct == 0.0 ? 0.0 : pct, 0) + "%";  // never "-0%"
}

nlohmann::json ParamsJson(const lab::FitResult& r) {
  nlohmann::json p = nlohmann::json::object();
  for (const auto& e : r.estimates) {
    p[e.name] = {{"value", e.value},
                 {"sd", std::isfinite(e.sd) ? nlohmann::json(e.sd) : nlohmann::json(nullptr)},
                 {"unit", e.unit}};
  }
  return p;
}

nlohmann::json GroupsJson(const std::vector<lab::GroupStat>& groups) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& g : groups) {
    out.push_back({{"group", g.label},
                   {"samples", g.samples},
                   {"tip_rms_mm", g.tip_rms_mm},
                   {"force_rms_n", g.force_rms_n},
                   {"sample_share", g.sample_share},
                   {"tip_share", g.tip_share},
                   {"force_share", g.force_share}});
  }
  return out;
}

void PrintWhere(const std::vector<lab::WhereEntry>& where, std::size_t per_channel) {
  std::cout << "\nwhere the held-out residual lives (share of each channel's excess a smooth "
               "function of the variable explains on other trials):\n";
  Table t({"channel", "variable", "explained", "gain (noise var)"});
  std::map<std::string, std::size_t> shown;
  for (const auto& e : where) {
    if (shown[e.channel]++ >= per_channel) continue;
    t.AddRow({e.channel, e.variable, PercentOrDash(e.explained_fraction), Fixed(e.gain, 2)});
  }
  t.Print(std::cout);
}

nlohmann::json BreakdownJson(const lab::Breakdown& b) {
  return {{"phase", GroupsJson(b.phase)},       {"speed", GroupsJson(b.speed)},
          {"gap", GroupsJson(b.gap)},           {"bend", GroupsJson(b.bend)},
          {"tip_load", GroupsJson(b.tip_load)}, {"trial", GroupsJson(b.trial)}};
}

void PrintGroups(const char* title, const std::vector<lab::GroupStat>& groups) {
  std::cout << "\nby " << title << ":\n";
  Table t(
      {"group", "samples", "tip_rms_mm", "share_of_tip_sq", "force_rms_n", "share_of_force_sq"});
  for (const auto& g : groups) {
    t.AddRow({g.label, std::to_string(g.samples), Fixed(g.tip_rms_mm, 4),
              Fixed(100 * g.tip_share, 1) + "%", Fixed(g.force_rms_n, 4),
              Fixed(100 * g.force_share, 1) + "%"});
  }
  t.Print(std::cout);
}

void RunCompare(const LabFlags& f) {
  if (MotionLabFlags m; IsMotionTrace(f, m)) return RunMotionCompare(m);
  const lab::LabDataset ds = Load(f);
  const Model model = ResolveModel(f);
  const auto& effects = model.effects;
  const lab::FitResult r = lab::FitModel(effects, ds, Options(model));
  if (!f.residuals_dir.empty()) WriteResiduals(f.residuals_dir, ds, r);
  const lab::Breakdown breakdown = lab::ComputeBreakdown(ds, r);
  // Where: the fit's own residuals (compare fits once), each variable's function learnt on
  // other trials.
  std::vector<lab::Prediction> predictions;
  for (const auto& t : r.trials) predictions.push_back(t.prediction);
  const std::vector<lab::WhereEntry> where = lab::LocateResidual(
      lab::BuildResidualTable(ds, predictions, 2), r.tip_mse_norm - 1.0, r.force_mse_norm - 1.0);
  if (f.json) {
    nlohmann::json trials = nlohmann::json::array();
    for (const auto& t : r.trials) {
      trials.push_back({{"trial", t.name},
                        {"rms_mm", t.stats.tip_rms_mm},
                        {"mae_mm", t.stats.tip_mae_mm},
                        {"max_mm", t.stats.tip_max_mm},
                        {"force_rms_n", t.stats.force_rms_n},
                        {"tip_offset_mm", t.nuisance.tip_offset_mm},
                        {"contact", t.nuisance.contact}});
    }
    std::cout << nlohmann::json{{"model", model.spec},
                                {"rms_mm", r.overall.tip_rms_mm},
                                {"mae_mm", r.overall.tip_mae_mm},
                                {"max_mm", r.overall.tip_max_mm},
                                {"force_rms_n", r.overall.force_rms_n},
                                {"noise",
                                 {{"tip_mm", ds.noise.tip_mm}, {"force_n", ds.noise.force_n}}},
                                {"params", ParamsJson(r)},
                                {"trials", trials},
                                {"breakdown", BreakdownJson(breakdown)},
                                {"where", WhereJson(where)},
                                {"skipped", ds.skipped},
                                {"fit_seconds", r.seconds}}
                     .dump(2)
              << "\n";
    return;
  }
  std::cout << "model " << model.spec << ": tip RMS " << Fixed(r.overall.tip_rms_mm, 4)
            << " mm, MAE " << Fixed(r.overall.tip_mae_mm, 4) << " mm, max "
            << Fixed(r.overall.tip_max_mm, 3) << " mm; force RMS "
            << Fixed(r.overall.force_rms_n, 4) << " N (noise: tip " << Fixed(ds.noise.tip_mm, 4)
            << " mm, force " << Fixed(ds.noise.force_n, 4) << " N)\n\n";
  Table p({"parameter", "value", "sd", "unit"});
  for (const auto& e : r.estimates)
    p.AddRow({e.name, Fixed(e.value, 5), std::isfinite(e.sd) ? Fixed(e.sd, 5) : "-", e.unit});
  p.Print(std::cout);
  std::cout << "\n";
  Table t({"trial", "tip_rms_mm", "tip_mae_mm", "tip_max_mm", "force_rms_n"});
  for (const auto& tr : r.trials) {
    t.AddRow({tr.name, Fixed(tr.stats.tip_rms_mm, 4), Fixed(tr.stats.tip_mae_mm, 4),
              Fixed(tr.stats.tip_max_mm, 3), Fixed(tr.stats.force_rms_n, 4)});
  }
  t.Print(std::cout);
  std::cout << "\nWhere the model fails (share of each channel's squared residual):";
  PrintGroups("phase of motion", breakdown.phase);
  PrintGroups("base speed", breakdown.speed);
  PrintGroups("gap", breakdown.gap);
  PrintGroups("total bend angle", breakdown.bend);
  PrintGroups("tip load", breakdown.tip_load);
  PrintWhere(where, 4);
}

nlohmann::json DiagnosisJson(const lab::Diagnosis& d, const lab::LabDataset& ds, const Model& m) {
  nlohmann::json candidates = nlohmann::json::array();
  for (const auto& c : d.candidates) {
    candidates.push_back(
        {{"effect", c.effect},
         {"replaces", c.replaces.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.replaces)},
         {"rms_mm", c.fit.overall.tip_rms_mm},
         {"mae_mm", c.fit.overall.tip_mae_mm},
         {"force_rms_n", c.fit.overall.force_rms_n},
         {"cv_tip_mse_noise", c.cv.tip_mse},
         {"cv_force_mse_noise", c.cv.force_mse},
         {"tip_explained", NullIfNan(c.tip_explained)},
         {"force_explained", NullIfNan(c.force_explained)},
         {"score", c.score},
         {"significant", c.significant},
         {"channel", c.channel},
         {"closes_gap", c.closes_gap},
         {"params", ParamsJson(c.fit)},
         {"evidence", c.evidence}});
  }
  nlohmann::json j = {{"model", hw::FormatModelSpec(d.model, *m.catalog)},
                      {"rms_mm", d.base.overall.tip_rms_mm},
                      {"mae_mm", d.base.overall.tip_mae_mm},
                      {"force_rms_n", d.base.overall.force_rms_n},
                      {"cv_tip_mse_noise", d.base_cv.tip_mse},
                      {"cv_force_mse_noise", d.base_cv.force_mse},
                      {"params", ParamsJson(d.base)},
                      {"adequate", d.adequate},
                      {"verdict", d.verdict},
                      {"summary", d.summary},
                      {"noise", {{"tip_mm", ds.noise.tip_mm}, {"force_n", ds.noise.force_n}}},
                      {"excess", {{"tip", d.tip_excess}, {"force", d.force_excess}}},
                      {"where", WhereJson(d.where)},
                      {"candidates", candidates},
                      {"partly_explained_by",
                       d.partial.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.partial)},
                      {"partly_explained_fraction",
                       d.partial.empty() ? nlohmann::json(nullptr) : NullIfNan(d.partial_fraction)},
                      {"closes_with", d.closes_with.empty() ? nlohmann::json(nullptr)
                                                            : nlohmann::json(d.closes_with)},
                      {"learning", LearningJson(d.learning)}};
  if (d.proposal) {
    const lab::Proposal& p = *d.proposal;
    j["proposal"] = {{"spec", p.spec},
                     {"file", p.file},
                     {"equation", p.equation},
                     {"terms", p.terms},
                     {"rms_mm", p.rms_mm},
                     {"force_rms_n", p.force_rms_n},
                     {"cv_tip_mse_noise", p.cv.tip_mse},
                     {"cv_force_mse_noise", p.cv.force_mse},
                     {"params", ParamsJson(p.fit)}};
  } else {
    j["proposal"] = nullptr;
  }
  return j;
}

void RunDiagnose(const LabFlags& f) {
  if (MotionLabFlags m; IsMotionTrace(f, m)) return RunMotionDiagnose(m, f.propose_dir);
  const lab::LabDataset ds = Load(f);
  const Model model = ResolveModel(f);
  const auto& effects = model.effects;
  lab::DiagnoseOptions o;
  o.fit = Options(model);
  o.propose_dir = ProposeDir(f);
  o.learn_along = f.learn_along;
  std::vector<std::string> skipped_candidates;
  o.candidates = Candidates(f, model, skipped_candidates);
  const lab::Diagnosis d = lab::Diagnose(effects, ds, o);
  if (f.json) {
    nlohmann::json j = DiagnosisJson(d, ds, model);
    j["skipped"] = ds.skipped;
    j["skipped_candidates"] = skipped_candidates;
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << "model " << model.spec << ": tip RMS " << Fixed(d.base.overall.tip_rms_mm, 4)
            << " mm, force RMS " << Fixed(d.base.overall.force_rms_n, 4) << " N (noise: tip "
            << Fixed(ds.noise.tip_mm, 4) << " mm, force " << Fixed(ds.noise.force_n, 4)
            << " N)\n\n";
  Table t({"rank", "candidate", "tip_rms_mm", "force_rms_n", "held-out tip excess removed",
           "force excess removed", "significant"});
  int rank = 1;
  for (const auto& c : d.candidates) {
    t.AddRow({std::to_string(rank++), "+" + c.effect, Fixed(c.fit.overall.tip_rms_mm, 4),
              Fixed(c.fit.overall.force_rms_n, 4), PercentOrDash(c.tip_explained),
              PercentOrDash(c.force_explained), c.significant ? "yes" : "no"});
  }
  t.Print(std::cout);
  PrintWhere(d.where, 3);
  std::cout << "\n"
            << (d.verdict == "adequate"         ? "ADEQUATE"
                : d.verdict == "missing_effect" ? "MISSING EFFECT"
                                                : "UNEXPLAINED")
            << ": " << d.summary << "\n";
  PrintLearning(d.learning, std::cout);
  if (d.verdict == "missing_effect") {
    std::vector<std::string> next = effects;
    std::erase(next, d.candidates.front().replaces);
    next.push_back(d.candidates.front().effect);
    std::cout << "\nnext: echoservo lab compare " << f.dataset << " --model "
              << hw::FormatModelSpec(hw::ResolveModelSpec(hw::FormatModelSpec(next, *model.catalog),
                                                          *model.catalog),
                                     *model.catalog)
              << "\n";
  } else if (d.proposal) {
    std::cout << "\nproposed effect written to " << d.proposal->file << " (held-out tip RMS "
              << Fixed(d.proposal->rms_mm, 4) << " mm, force RMS "
              << Fixed(d.proposal->force_rms_n, 4) << " N)\nnext: echoservo lab compare "
              << f.dataset << " --model " << d.proposal->spec << "\n";
  }
}

void AddCommon(CLI::App* cmd, LabFlags& f) {
  cmd->add_option("DATASET", f.dataset,
                  "Folder of trials (CSV + JSON pairs, docs/trial_format.md), or a motion-trace "
                  "CSV (docs/predictor.md)")
      ->required();
  cmd->add_option(
      "--model", f.model,
      "Model SPEC: for a dataset folder a catheter model, e.g. seed or seed+capstan_friction "
      "(default seed); for a motion trace heartbeat:N[+respiration][+rate_drift] (default "
      "heartbeat:2). A model of the other kind is an error");
  cmd->add_option("--column", f.column,
                  "Motion traces: the position column (default: the first after 't')");
  cmd->add_flag("--skip-bad", f.skip_bad,
                "Skip invalid trials (each is listed) instead of failing");
  cmd->add_option("--stride", f.stride,
                  "Use every N-th sample as a residual (default 4: 250 Hz from 1 kHz)");
  cmd->add_flag("--json", f.json, "Print JSON");
  AddCatalogFlags(cmd, f.catalog);
}

// ---- `lab report`: the error ladder, diagnosis and plots as one self-contained HTML page.

struct LabReportFlags {
  LabFlags common;
  std::string out;
  int max_rounds = 4;
  int plot_trials = 4;
};

void RunLabReport(const LabReportFlags& f) {
  if (MotionLabFlags m; IsMotionTrace(f.common, m)) {
    throw std::invalid_argument(f.common.dataset +
                                " is a motion trace; lab report is for catheter dataset folders "
                                "only (lab compare|diagnose take a motion trace)");
  }
  const lab::LabDataset ds = Load(f.common);
  const Model model = ResolveModel(f.common);
  const auto& effects = model.effects;
  lab::DiagnoseOptions o;
  o.fit = Options(model);
  o.propose_dir = ProposeDir(f.common);
  const std::vector<lab::LadderStep> ladder = lab::ErrorLadder(effects, ds, o, f.max_rounds);
  lab::LabReportOptions ro;
  ro.dataset_path = f.common.dataset;
  ro.stride = f.common.stride;
  ro.max_rounds = f.max_rounds;
  ro.plot_trials = static_cast<std::size_t>(f.plot_trials);
  o.fit.progress("report: writing " + f.out);
  WriteFileAtomically(f.out, lab::RenderLabReport(ds, ladder, ro));
  std::vector<std::string> models;
  for (const auto& step : ladder) models.push_back(hw::FormatModelSpec(step.model, *model.catalog));
  const bool adequate = ladder.back().diagnosis.adequate;
  if (f.common.json) {
    std::cout << nlohmann::json{{"report", f.out},
                                {"ladder", models},
                                {"final_model", models.back()},
                                {"adequate", adequate},
                                {"verdict", ladder.back().diagnosis.verdict},
                                {"summary", ladder.back().diagnosis.summary}}
                     .dump(2)
              << "\n";
    return;
  }
  std::cout << "wrote " << f.out << ": ladder";
  for (std::size_t i = 0; i < models.size(); ++i) std::cout << (i == 0 ? " " : " -> ") << models[i];
  std::cout << " (" << (adequate ? "adequate" : "not adequate") << ")\n";
}

void AddReportCommand(CLI::App* lab) {
  auto flags = std::make_shared<LabReportFlags>();
  auto* report = lab->add_subcommand(
      "report", "Error ladder, diagnosis, parameters and plots as one self-contained HTML page");
  AddCommon(report, flags->common);
  report->add_option("--out", flags->out, "HTML file to write")->required();
  report
      ->add_option("--max-rounds", flags->max_rounds,
                   "Most effects the error ladder adds (default 4)")
      ->check(CLI::Range(0, 20));
  report
      ->add_option(
          "--plot-trials", flags->plot_trials,
          "Trials plotted: those with the largest tip residual under the model (default 4)")
      ->check(CLI::Range(0, 100));
  report->callback([flags] { RunLabReport(*flags); });
}

}  // namespace

void AddLabCommands(CLI::App& app) {
  auto* lab = app.add_subcommand(
      "lab", "The model lab: compare a catheter model with measurements, diagnose what it misses");
  lab->require_subcommand(1);
  auto flags = std::make_shared<LabFlags>();
  auto* compare = lab->add_subcommand(
      "compare", "Fit a model to all trials; errors, parameters, where it fails");
  AddCommon(compare, *flags);
  compare->add_option(
      "--residuals", flags->residuals_dir,
      "Write every trial with the model's tip and force as extra columns into this folder");
  compare->callback([flags] { RunCompare(*flags); });
  auto dflags = std::make_shared<LabFlags>();
  auto* diagnose = lab->add_subcommand(
      "diagnose", "Refit the model plus each missing catalog effect; rank them on held-out trials");
  AddCommon(diagnose, *dflags);
  diagnose->add_option("--candidate", dflags->candidates,
                       "Also try this effect as a candidate: an effect file as @path/effect.json "
                       "or a plugin's effect (repeatable); one that cannot be read is skipped "
                       "and reported");
  diagnose->add_option("--propose-dir", dflags->propose_dir,
                       "Where a proposed effect file is written when the verdict is unexplained "
                       "(default: DATASET_proposal beside the dataset)");
  diagnose
      ->add_option("--learn-along", dflags->learn_along,
                   "Learn the missing term along these variables only (repeatable or comma "
                   "separated: base_mm, velocity_mm_s, time_s, ..., or a pair such as "
                   "bend_deg*velocity_mm_s); default: where the residual lives")
      ->delimiter(',');
  diagnose->callback([dflags] {
    lab::CheckLearnVariables(dflags->learn_along, "--learn-along");
    RunDiagnose(*dflags);
  });
  AddReportCommand(lab);
}

}  // namespace echoservo::apps
