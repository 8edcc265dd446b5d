#include "lab/lab_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <numbers>
#include <numeric>
#include <stdexcept>

#include "hw/effect_registry.h"
#include "lab/catheter_where.h"
#include "report/html_page.h"
#include "report/svg_plot.h"

namespace echoservo::lab {

namespace html = report::html;
namespace svg = report::svg;
namespace {

constexpr const char* kMeasured = "#222222";
constexpr const char* kSpecColor = "#e66101";
constexpr const char* kFinalColor = "#0571b0";
constexpr const char* kBaseColor = "#a0a0a0";
constexpr const char* kTipBar = "#4477aa";
constexpr const char* kForceBar = "#aa3377";
constexpr const char* kNoiseColor = "#2e7d32";
constexpr int kHalfWidth = 570;  // chart width in the two-column grid (px)

using html::Fix;
using html::Row;
using html::Sig;
using html::Tag;

std::string Esc(std::string_view s) { return svg::EscapeHtml(s); }

// Escaped, with a line-break opportunity after every '_' (long trial names).
std::string Breakable(std::string_view text) {
  std::string out;
  for (char ch : text) {
    out += Esc(std::string_view(&ch, 1));
    if (ch == '_') out += "<wbr>";
  }
  return out;
}

std::string PercentCell(double fraction) {
  if (!std::isfinite(fraction)) return "–";  // nothing to explain in that channel
  const double p = std::round(100.0 * fraction);
  return Fix(p == 0.0 ? 0.0 : p, 0) + "%";  // no "-0%"
}

std::string Spec(const std::vector<std::string>& effects) { return hw::FormatModelSpec(effects); }

// A verdict without its "adequate: " / "missing effect: " prefix (the page says it in
// bold before), as a sentence: "adequate: no catalog effect ..." → "No catalog effect ...".
std::string Sentence(std::string text) {
  for (const std::string prefix : {"adequate: ", "missing effect: ", "unexplained: "}) {
    if (text.rfind(prefix, 0) == 0) {
      text = text.substr(prefix.size());
      if (prefix != "missing effect: " && !text.empty() && text[0] >= 'a' && text[0] <= 'z') {
        text[0] = static_cast<char>(text[0] - 'a' + 'A');
      }
    }
  }
  if (!text.empty() && text.back() != '.') text += '.';
  return text;
}

double Duration(const formats::Trial& t) {
  return t.size() > 1 ? t.t_s.back() - t.t_s.front() : 0.0;
}

std::string ConfigText(const formats::CatheterConfig& c) {
  return "gap " + Fix(c.GapMm(), 2) + " mm (sheath " + Fix(c.sheath_id_mm, 2) + " mm, guidewire " +
         Fix(c.guidewire_od_mm, 2) + " mm) &middot; " + std::to_string(c.bends.size()) + " bend" +
         (c.bends.size() == 1 ? "" : "s") + ", total " +
         Fix(c.TotalBendRad() * 180.0 / std::numbers::pi, 0) + "&deg; &middot; tip load " +
         Fix(c.tip_load_n, 2) + " N";
}

std::string EffectList(const std::vector<std::string>& effects) {
  std::string s;
  for (const std::string& e : effects) s += (s.empty() ? "" : ", ") + Esc(e);
  return s.empty() ? "no effects" : s;
}

struct Context {
  const LabDataset& ds;
  const std::vector<LadderStep>& ladder;
  const LabReportOptions& o;
  const FitResult& spec_fit;
  const FitResult& final_fit;
  std::string spec;
  std::string final_spec;
  bool single = false;  // the final model is SPEC itself
};

std::string HeaderHtml(const Context& c) {
  std::size_t samples = 0;
  double seconds = 0.0;
  for (const LabTrial& t : c.ds.trials) {
    samples += t.trial.size();
    seconds += Duration(t.trial);
  }
  std::vector<std::pair<std::string, std::string>> facts = {
      {"Dataset", "<code>" + Esc(c.o.dataset_path) + "</code>"},
      {"Trials",
       std::to_string(c.ds.trials.size()) +
           (c.ds.skipped.empty() ? "" : " (" + std::to_string(c.ds.skipped.size()) + " skipped)")},
      {"Samples", std::to_string(samples) + " (" + Fix(seconds, 1) + " s); " +
                      std::to_string(c.ds.residual_samples()) + " in the fit (" +
                      (c.o.stride == 1 ? std::string("every sample")
                                       : "every " + std::to_string(c.o.stride) +
                                             (c.o.stride == 2   ? "nd"
                                              : c.o.stride == 3 ? "rd"
                                                                : "th")) +
                      ")"},
      {"Estimated noise (1&sigma;)", "tip " + Fix(c.ds.noise.tip_mm, 4) + " mm &middot; force " +
                                         Fix(c.ds.noise.force_n, 4) + " N"},
      {"Model SPEC",
       "<code>" + Esc(c.spec) + "</code> (" + EffectList(c.ladder.front().model) + ")"},
      {"Final ladder model",
       "<code>" + Esc(c.final_spec) + "</code> " +
           (c.ladder.back().diagnosis.adequate ? "<span class=\"tag yes\">adequate</span>"
                                               : "<span class=\"tag miss\">not adequate</span>")},
      {"Generated", Esc(c.o.generated.empty() ? html::NowUtc() : c.o.generated)},
  };
  std::string s =
      html::TopHeader("Model lab report",
                      "echoservo &middot; catheter model <b>" + Esc(c.spec) +
                          "</b> fitted to bench recordings, its error ladder and diagnosis",
                      facts);
  s += "<nav class=\"toc\"><a href=\"#ladder\">Error ladder</a><a href=\"#diagnosis\">Diagnosis</a>"
       "<a href=\"#parameters\">Parameters</a><a href=\"#trials\">Trials</a><a "
       "href=\"#breakdown\">Where the "
       "residual lies</a></nav>";
  if (!c.ds.skipped.empty()) {
    s += "<section><h2>Skipped trials</h2><ul>";
    for (const std::string& k : c.ds.skipped) s += "<li><code>" + Esc(k) + "</code></li>";
    s += "</ul></section>";
  }
  return s;
}

std::string LadderHtml(const Context& c) {
  const auto& L = c.ladder;
  std::string s =
      "<section id=\"ladder\"><h2>Error ladder</h2><p class=\"note\">Starting from <code>" +
      Esc(c.spec) +
      "</code>, each round diagnoses the current model and adds the catalog effect that removes "
      "the "
      "most held-out residual, until no candidate is significant (the model is adequate) or the "
      "round "
      "limit (" +
      std::to_string(c.o.max_rounds) + (c.o.max_rounds == 1 ? " effect" : " effects") +
      " added) is reached. RMS values are of model &minus; measured over all samples; held-out "
      "mean squares are in units of the noise variance (&asymp;&nbsp;1 when only noise is "
      "left).</p>";
  s += "<table>" + Row({"step", "model", "effect added", "tip RMS (mm)", "force RMS (N)",
                        "held-out tip MS", "held-out force MS", "adequate"},
                       "", true, 3);
  std::vector<std::string> categories;
  std::vector<double> tip, force;
  for (std::size_t i = 0; i < L.size(); ++i) {
    const Diagnosis& d = L[i].diagnosis;
    const std::string added = i == 0 ? std::string() : L[i - 1].diagnosis.candidates.front().effect;
    categories.push_back(i == 0 ? Spec(L[i].model) : "+" + added);
    tip.push_back(d.base.overall.tip_rms_mm);
    force.push_back(d.base.overall.force_rms_n);
    s += Row({std::to_string(i), "<code>" + Esc(Spec(L[i].model)) + "</code>",
              i == 0 ? "&ndash;" : "+" + Esc(added), Fix(d.base.overall.tip_rms_mm, 4),
              Fix(d.base.overall.force_rms_n, 4), Fix(d.base_cv.tip_mse, 2),
              Fix(d.base_cv.force_mse, 2), Tag(d.adequate)},
             i + 1 == L.size() ? "final" : "", false, 3);
  }
  s += "</table>";
  const Diagnosis& last = L.back().diagnosis;
  const std::string added =
      std::to_string(L.size() - 1) + " effect" + (L.size() == 2 ? "" : "s") + " added";
  s += std::string("<div class=\"verdict ") + (last.adequate ? "ok" : "miss") + "\"><b>" +
       (last.adequate ? "Adequate:" : "Not adequate:") + "</b>final model <code>" +
       Esc(c.final_spec) + "</code> (" + added + (last.adequate ? "" : ", the maximum") + "). " +
       (last.adequate                   ? ""
        : last.verdict == "unexplained" ? "Unexplained: "
                                        : "Still missing: ") +
       Esc(Sentence(last.summary)) + "</div>";
  svg::BarChart bt;
  bt.title = "Tip RMS along the ladder";
  bt.y_title = "tip RMS (mm)";
  bt.categories = categories;
  bt.series = {{"tip RMS", tip, kTipBar}};
  bt.references = {{"noise " + Fix(c.ds.noise.tip_mm, 4) + " mm", c.ds.noise.tip_mm, kNoiseColor}};
  bt.value_decimals = 4;
  bt.width = kHalfWidth;
  svg::BarChart bf = bt;
  bf.title = "Force RMS along the ladder";
  bf.y_title = "force RMS (N)";
  bf.series = {{"force RMS", force, kForceBar}};
  bf.references = {{"noise " + Fix(c.ds.noise.force_n, 4) + " N", c.ds.noise.force_n, kNoiseColor}};
  s += "<div class=\"grid2\"><div>" + svg::RenderBarChart(bt) + "</div><div>" +
       svg::RenderBarChart(bf) + "</div></div></section>";
  return s;
}

std::string DiagnosisHtml(const Context& c) {
  const Diagnosis& d = c.ladder.front().diagnosis;
  std::string s =
      "<section id=\"diagnosis\"><h2>Diagnosis of <code>" + Esc(c.spec) + "</code></h2>";
  s += std::string("<div class=\"verdict ") + (d.adequate ? "ok" : "miss") + "\"><b>" +
       (d.adequate                   ? "ADEQUATE:"
        : d.verdict == "unexplained" ? "UNEXPLAINED:"
                                     : "MISSING EFFECT:") +
       "</b>" + Esc(Sentence(d.summary)) + "</div>";
  s += "<p class=\"note\">Every catalog effect not in the model is added in turn and the model "
       "refitted; held-out "
       "scores come from cross-validation by trial. <code>" +
       Esc(c.spec) + "</code>: tip RMS " + Fix(d.base.overall.tip_rms_mm, 4) + " mm, force RMS " +
       Fix(d.base.overall.force_rms_n, 4) + " N; held-out mean square " +
       Fix(d.base_cv.tip_mse, 2) + " (tip), " + Fix(d.base_cv.force_mse, 2) +
       " (force) noise variances.</p>";
  s += "<table>" +
       Row({"rank", "candidate", "tip RMS (mm)", "force RMS (N)", "held-out tip excess explained",
            "held-out force excess explained", "channel", "significant"},
           "", true, 2);
  int rank = 1;
  for (const Candidate& k : d.candidates) {
    s += Row({std::to_string(rank++), "+" + Esc(k.effect), Fix(k.fit.overall.tip_rms_mm, 4),
              Fix(k.fit.overall.force_rms_n, 4), PercentCell(k.tip_explained),
              PercentCell(k.force_explained), Esc(k.channel), Tag(k.significant)},
             k.significant ? "sig" : "", false, 2);
  }
  s += "</table><h3>Evidence</h3><ol class=\"evidence\">";
  for (const Candidate& k : d.candidates)
    s += "<li><b>+" + Esc(k.effect) + "</b>: " + Esc(k.evidence) + "</li>";
  s += "</ol></section>";
  return s;
}

std::string LearningHtml(const Diagnosis& d);

// The held-out residual's binned mean along `variable`, one line per direction of motion.
svg::LinePlot WherePlot(const ResidualTable& t, const std::string& channel,
                        const std::string& variable, double noise, const char* unit) {
  const std::vector<double>& x = t.Variable(variable);
  const std::vector<double>& r = channel == "tip" ? t.tip : t.force;
  const std::vector<int> bins = QuantileBins(x, 16);
  const int nb = bins.empty() ? 0 : *std::max_element(bins.begin(), bins.end()) + 1;
  svg::LinePlot p;
  p.title = channel + " residual along " + variable;
  p.x_title = variable;
  p.y_title = channel + " residual (" + unit + "), binned mean";
  p.zero_line = true;
  p.width = kHalfWidth;
  p.height = 300;
  const char* colors[] = {"#d7191c", "#7b7b7b", "#2c7bb6"};
  const char* labels[] = {"moving \u2212", "at rest", "moving +"};
  for (int dir = -1; dir <= 1; ++dir) {
    std::vector<double> sx(static_cast<std::size_t>(nb), 0.0), sy(sx.size(), 0.0),
        n(sx.size(), 0.0);
    for (std::size_t i = 0; i < r.size(); ++i) {
      if (t.direction[i] != dir) continue;
      const auto b = static_cast<std::size_t>(bins[i]);
      sx[b] += x[i];
      sy[b] += r[i] * noise;
      n[b] += 1.0;
    }
    svg::Line line{labels[dir + 1], {}, {}, colors[dir + 1], 1.6, dir == 0, 1.0};
    for (std::size_t b = 0; b < sx.size(); ++b) {
      if (n[b] < 10) continue;
      line.x.push_back(sx[b] / n[b]);
      line.y.push_back(sy[b] / n[b]);
    }
    if (line.x.size() >= 2) p.lines.push_back(std::move(line));
  }
  return p;
}

// Where the SPEC's held-out residual lives, and the proposal when the catalog ends.
std::string WhereHtml(const Context& c) {
  const Diagnosis& d = c.ladder.front().diagnosis;
  if (d.base_cv.held_out.size() != c.ds.trials.size()) return "";
  const ResidualTable t = BuildResidualTable(c.ds, d.base_cv.held_out, 2);
  std::string s = "<section id=\"where\"><h2>Where <code>" + Esc(c.spec) +
                  "</code> fails</h2><p class=\"note\">Share of each channel&rsquo;s held-out "
                  "excess (mean square above the noise) that a smooth function of one variable, "
                  "learnt on other trials and taken jointly with the direction of motion, "
                  "predicts. Held-out excess: tip " +
                  Fix(d.tip_excess, 2) + ", force " + Fix(d.force_excess, 2) +
                  " noise variances.</p><table>" +
                  Row({"channel", "variable", "excess explained", "gain (noise var)"}, "", true, 2);
  std::vector<std::pair<std::string, std::string>> top;
  std::map<std::string, int> shown, plotted;
  for (const WhereEntry& e : d.where) {
    if (shown[e.channel]++ >= 4) continue;
    s += Row({Esc(e.channel), "<code>" + Esc(e.variable) + "</code>",
              PercentCell(e.explained_fraction), Fix(e.gain, 2)});
    const double excess = e.channel == "tip" ? d.tip_excess : d.force_excess;
    // The two best single variables are plotted; a pair's residual is shown by its learnt
    // shape (below), not by one binned mean.
    if (plotted[e.channel] < 2 && (excess >= 0.5 || e.gain >= 0.25) && !IsPair(e.variable)) {
      top.emplace_back(e.channel, e.variable);
      ++plotted[e.channel];
    }
  }
  s += "</table>";
  if (!top.empty()) {
    s += "<div class=\"grid2\">";
    for (const auto& [channel, variable] : top) {
      const bool tip = channel == "tip";
      s += "<div>" +
           svg::RenderLinePlot(WherePlot(t, channel, variable,
                                         tip ? c.ds.noise.tip_mm : c.ds.noise.force_n,
                                         tip ? "mm" : "N")) +
           "</div>";
    }
    s += "</div>";
  }
  for (const LadderStep& step : c.ladder) {
    if (!step.diagnosis.proposal) continue;
    const Proposal& p = *step.diagnosis.proposal;
    s += "<h3>Proposed effect (beyond the catalog)</h3><p><code>" + Esc(p.equation) +
         "</code></p><p>Held-out tip RMS " + Fix(p.rms_mm, 4) + " mm (noise " +
         Fix(c.ds.noise.tip_mm, 4) + " mm), force RMS " + Fix(p.force_rms_n, 4) + " N (noise " +
         Fix(c.ds.noise.force_n, 4) + " N). Effect file: <code>" + Esc(p.file) +
         "</code>; use it with <code>--model " + Esc(p.spec) + "</code>.</p>";
    s += LearningHtml(step.diagnosis);
  }
  return s + "</section>";
}

// What the ladder's last step learnt beyond the libraries: the chosen shape against its
// variables (one line per knot of the first variable for a pair) and the formulas' Pareto
// front with their held-out figures through the model.
std::string LearningHtml(const Diagnosis& d) {
  const ShapeLearning& l = d.learning;
  if (l.empty()) return "";
  const LearnedShape& shape = l.shapes.front();
  std::string s = "<h3>Learnt shape</h3><p class=\"note\">" + Esc(shape.Words()) +
                  ", fitted through the whole model with every other parameter and cross-"
                  "validated over trials: held-out tip " +
                  Fix(std::sqrt(std::max(shape.tip_mse, 0.0)), 2) + "&times;, force " +
                  Fix(std::sqrt(std::max(shape.force_mse, 0.0)), 2) + "&times; the noise floor. " +
                  Esc(l.note) + ".</p>";
  svg::LinePlot p;
  const auto& axes = shape.shape.axes;
  p.title = "learnt " + shape.hook + " along " + shape.inputs.front() +
            (axes.size() > 1 ? " and " + shape.inputs.back() : "");
  p.x_title = axes.back().variable;
  p.y_title = shape.hook + " (" + shape.unit + ")";
  p.zero_line = true;
  p.width = kHalfWidth;
  p.height = 300;
  const char* colors[] = {"#2c7bb6", "#d7191c", "#1a9641", "#7b3294", "#fdae61", "#636363"};
  const std::size_t rows = axes.size() > 1 ? axes[0].knots.size() : 1;
  const std::size_t cols = axes.back().knots.size();
  for (std::size_t r = 0; r < rows; ++r) {
    svg::Line line{axes.size() > 1 ? axes[0].variable + " = " + Sig(axes[0].knots[r], 3) : "shape",
                   {},
                   {},
                   colors[r % 6],
                   1.6,
                   false,
                   1.0};
    for (std::size_t c = 0; c < cols; ++c) {
      line.x.push_back(axes.back().knots[c]);
      line.y.push_back(shape.shape.values[r * cols + c]);
    }
    p.lines.push_back(std::move(line));
  }
  s += "<div class=\"grid2\"><div>" + svg::RenderLinePlot(p) + "</div></div>";
  if (!l.formulas.empty()) {
    s +=
        "<h3>Formulas (Pareto front)</h3><table>" +
        Row({"complexity", "form", "formula", "held-out tip (x noise)", "held-out force (x noise)"},
            "", true);
    for (const FormulaCandidate& f : l.formulas) {
      s += Row({std::to_string(f.formula.complexity), Esc(f.formula.form),
                "<code>" + Esc(f.formula.words) + "</code>",
                f.fitted ? Fix(std::sqrt(std::max(f.tip_mse, 0.0)), 2) : "&ndash;",
                f.fitted ? Fix(std::sqrt(std::max(f.force_mse, 0.0)), 2) : "&ndash;"});
    }
    s += "</table>";
  }
  return s;
}

std::string ParameterTable(const std::string& title, const FitResult& r) {
  std::string s =
      "<div><h3>" + title + "</h3><table>" + Row({"parameter", "value", "SD", "unit"}, "", true);
  for (const ParameterEstimate& e : r.estimates) {
    s += Row({"<code>" + Esc(e.name) + "</code>", Sig(e.value, 5), Sig(e.sd, 2), Esc(e.unit)});
  }
  if (r.estimates.empty()) s += "<tr><td colspan=\"4\">no physical parameters</td></tr>";
  return s + "</table></div>";
}

std::string ParametersHtml(const Context& c) {
  std::string s =
      "<section id=\"parameters\"><h2>Fitted parameters</h2><p class=\"note\">Shared by all "
      "trials; "
      "SD from the covariance of the fit scaled by the reduced &chi;&sup2; (&ndash; when the "
      "parameter is not determined by the data).</p><div class=\"grid2\">";
  s += ParameterTable("SPEC <code>" + Esc(c.spec) + "</code>", c.spec_fit);
  if (!c.single)
    s += ParameterTable("Final model <code>" + Esc(c.final_spec) + "</code>", c.final_fit);
  s += "</div></section>";
  return s;
}

std::vector<double> Difference(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> d(std::min(a.size(), b.size()));
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = a[i] - b[i];
  return d;
}

std::string TrialPanel(const Context& c, std::size_t k, std::size_t slot) {
  const formats::Trial& t = c.ds.trials[k].trial;
  const Prediction& ps = c.spec_fit.trials[k].prediction;
  const Prediction& pf = c.final_fit.trials[k].prediction;
  const std::string spec_label = "SPEC " + c.spec;
  const std::string final_label = "final " + c.final_spec;
  auto models = [&](const std::vector<double>& x, const std::vector<double>& ys,
                    const std::vector<double>& yf) {
    std::vector<svg::Line> lines;
    lines.push_back(
        {c.single ? spec_label + " (final)" : spec_label, x, ys, kSpecColor, 1.6, false, 1.0});
    if (!c.single) lines.push_back({final_label, x, yf, kFinalColor, 1.6, true, 1.0});
    return lines;
  };
  auto plot = [&](const std::string& title, const std::string& xt, const std::string& yt) {
    svg::LinePlot p;
    p.title = title;
    p.x_title = xt;
    p.y_title = yt;
    p.width = kHalfWidth;
    p.height = 300;
    return p;
  };
  const svg::Line measured_tip{"measured tip", t.t_s, t.tip_mm, kMeasured, 1.2, false, 0.9};
  svg::LinePlot tip = plot("Tip position", "time (s)", "position (mm)");
  tip.lines = {{"measured base", t.t_s, t.base_mm, kBaseColor, 1.2, true, 1.0}, measured_tip};
  for (auto& l : models(t.t_s, ps.tip_mm, pf.tip_mm)) tip.lines.push_back(std::move(l));

  svg::LinePlot force = plot("Force", "time (s)", "force (N)");
  force.lines = {{"measured force", t.t_s, t.force_n, kMeasured, 1.2, false, 0.9}};
  for (auto& l : models(t.t_s, ps.force_n, pf.force_n)) force.lines.push_back(std::move(l));

  svg::LinePlot tip_res =
      plot("Tip residual (model \u2212 measured)", "time (s)", "tip residual (mm)");
  tip_res.zero_line = true;
  tip_res.lines = models(t.t_s, Difference(ps.tip_mm, t.tip_mm), Difference(pf.tip_mm, t.tip_mm));
  svg::LinePlot force_res =
      plot("Force residual (model \u2212 measured)", "time (s)", "force residual (N)");
  force_res.zero_line = true;
  force_res.lines =
      models(t.t_s, Difference(ps.force_n, t.force_n), Difference(pf.force_n, t.force_n));

  svg::LinePlot loop = plot("Hysteresis: tip vs base", "base position (mm)", "tip position (mm)");
  loop.lines = {{"measured", t.base_mm, t.tip_mm, kMeasured, 1.2, false, 0.9}};
  for (auto& l : models(t.base_mm, ps.tip_mm, pf.tip_mm)) loop.lines.push_back(std::move(l));
  svg::LinePlot floop = plot("Force vs base", "base position (mm)", "force (N)");
  floop.lines = {{"measured", t.base_mm, t.force_n, kMeasured, 1.2, false, 0.9}};
  for (auto& l : models(t.base_mm, ps.force_n, pf.force_n)) floop.lines.push_back(std::move(l));

  const ChannelStats& ss = c.spec_fit.trials[k].stats;
  const ChannelStats& fs = c.final_fit.trials[k].stats;
  std::string s =
      "<div class=\"trial-panel\" id=\"trial-plot-" + std::to_string(slot) + "\"><h3>" +
      std::to_string(slot + 1) + ". " + Esc(t.name) + "</h3><p class=\"cfg\">" +
      ConfigText(t.config) + " &middot; " + Fix(Duration(t), 2) + " s &middot; tip RMS " +
      Fix(ss.tip_rms_mm, 4) + " mm" + (c.single ? "" : " &rarr; " + Fix(fs.tip_rms_mm, 4) + " mm") +
      ", force RMS " + Fix(ss.force_rms_n, 4) + " N" +
      (c.single ? "" : " &rarr; " + Fix(fs.force_rms_n, 4) + " N") + "</p><div class=\"grid2\">";
  for (const svg::LinePlot* p : {&tip, &force, &tip_res, &force_res, &loop, &floop}) {
    s += "<div>" + svg::RenderLinePlot(*p) + "</div>";
  }
  return s + "</div></div>";
}

std::string TrialsHtml(const Context& c) {
  const std::vector<std::size_t> chosen = LargestTipResidualTrials(c.spec_fit, c.o.plot_trials);
  std::vector<int> slot(c.ds.trials.size(), -1);
  for (std::size_t j = 0; j < chosen.size(); ++j) slot[chosen[j]] = static_cast<int>(j);
  const std::string plotted =
      chosen.empty()
          ? std::string("No trial is plotted.")
          : "Plotted below: the " + std::to_string(chosen.size()) + " trial" +
                (chosen.size() == 1 ? "" : "s") + " with the largest tip residual under <code>" +
                Esc(c.spec) + "</code>" + (chosen.size() > 1 ? " (largest first)." : ".");
  std::string s =
      "<section id=\"trials\"><h2>Trials</h2><p class=\"note\">Per-trial RMS of model &minus; "
      "measured (each trial with its own tip-sensor offset and initial contact state). " +
      plotted + "</p>";
  std::vector<std::string> head = {"trial",    "gap (mm)",   "bend (&deg;)",
                                   "load (N)", "length (s)", "tip RMS SPEC (mm)"};
  if (!c.single) head.push_back("tip RMS final (mm)");
  head.push_back("force RMS SPEC (N)");
  if (!c.single) head.push_back("force RMS final (N)");
  for (std::size_t i = 5; i < head.size(); ++i) {  // two-line headers keep the table narrow
    const std::size_t cut = head[i].find(' ', head[i].find(' ') + 1);
    head[i] = head[i].substr(0, cut) + "<br>" + head[i].substr(cut + 1);
  }
  s += "<div class=\"scroll\"><table>" + Row(head, "", true);
  for (std::size_t k = 0; k < c.ds.trials.size(); ++k) {
    const formats::Trial& t = c.ds.trials[k].trial;
    std::string name = Breakable(t.name);
    if (slot[k] >= 0)
      name = "<a href=\"#trial-plot-" + std::to_string(slot[k]) + "\">" + name + "</a>";
    std::vector<std::string> row = {name,
                                    Fix(t.config.GapMm(), 2),
                                    Fix(t.config.TotalBendRad() * 180.0 / std::numbers::pi, 0),
                                    Fix(t.config.tip_load_n, 2),
                                    Fix(Duration(t), 2),
                                    Fix(c.spec_fit.trials[k].stats.tip_rms_mm, 4)};
    if (!c.single) row.push_back(Fix(c.final_fit.trials[k].stats.tip_rms_mm, 4));
    row.push_back(Fix(c.spec_fit.trials[k].stats.force_rms_n, 4));
    if (!c.single) row.push_back(Fix(c.final_fit.trials[k].stats.force_rms_n, 4));
    s += "<tr><td class=\"l name\">" + row.front() + "</td>";  // long names wrap
    for (std::size_t i = 1; i < row.size(); ++i) s += "<td>" + row[i] + "</td>";
    s += "</tr>";
  }
  s += "</table></div>";
  if (chosen.size() > 1) {
    s += "<div class=\"selector\" id=\"trial-selector\" hidden><label "
         "for=\"trial-select\">Show</label>"
         "<select id=\"trial-select\"><option value=\"all\">all " +
         std::to_string(chosen.size()) + " plotted trials</option>";
    for (std::size_t j = 0; j < chosen.size(); ++j) {
      s += "<option value=\"trial-plot-" + std::to_string(j) + "\">" + std::to_string(j + 1) +
           ". " + Esc(c.ds.trials[chosen[j]].trial.name) + "</option>";
    }
    s += "</select></div>";
  }
  for (std::size_t j = 0; j < chosen.size(); ++j) s += TrialPanel(c, chosen[j], j);
  return s + "</section>";
}

std::string GroupLabel(const std::string& kind, const GroupStat& g) {
  if (kind == "gap") return Fix(g.value, 2) + " mm";
  if (kind == "bend") return Fix(g.value, 0) + "\u00b0";
  if (kind == "load") return Fix(g.value, 2) + " N";
  std::string label = g.label;
  std::replace(label.begin(), label.end(), '_', ' ');
  return label;
}

std::string BreakdownBlock(const Context& c, const std::string& title, const std::string& kind,
                           const std::vector<GroupStat>& spec_groups,
                           const std::vector<GroupStat>& final_groups) {
  std::vector<std::string> categories;
  std::vector<double> st, sf, ft, ff;
  for (const GroupStat& g : spec_groups) {
    categories.push_back(GroupLabel(kind, g));
    st.push_back(g.tip_rms_mm);
    sf.push_back(g.force_rms_n);
    const auto it = std::find_if(final_groups.begin(), final_groups.end(),
                                 [&](const GroupStat& f) { return f.label == g.label; });
    ft.push_back(it != final_groups.end() ? it->tip_rms_mm : NAN);
    ff.push_back(it != final_groups.end() ? it->force_rms_n : NAN);
  }
  svg::BarChart tip;
  tip.title = "Tip RMS by " + title;
  tip.y_title = "tip RMS (mm)";
  tip.categories = categories;
  tip.series = {{c.single ? "SPEC " + c.spec + " (final)" : "SPEC " + c.spec, st, kSpecColor}};
  if (!c.single) tip.series.push_back({"final " + c.final_spec, ft, kFinalColor});
  tip.references = {{"noise " + Fix(c.ds.noise.tip_mm, 4) + " mm", c.ds.noise.tip_mm, kNoiseColor}};
  tip.value_decimals = 4;
  tip.width = kHalfWidth;
  tip.height = 280;
  svg::BarChart force = tip;
  force.title = "Force RMS by " + title;
  force.y_title = "force RMS (N)";
  force.series = {{tip.series[0].label, sf, kSpecColor}};
  if (!c.single) force.series.push_back({"final " + c.final_spec, ff, kFinalColor});
  force.references = {
      {"noise " + Fix(c.ds.noise.force_n, 4) + " N", c.ds.noise.force_n, kNoiseColor}};
  std::string s = "<h3>By " + Esc(title) + "</h3><div class=\"grid2\"><div>" +
                  svg::RenderBarChart(tip) + "</div><div>" + svg::RenderBarChart(force) +
                  "</div></div>";
  // The numbers, with each group's share of the samples and of the squared residual.
  std::vector<std::string> head = {"group",
                                   "samples",
                                   "share of samples",
                                   "SPEC tip RMS (mm)",
                                   "share of tip sq.",
                                   "SPEC force RMS (N)",
                                   "share of force sq."};
  if (!c.single) {
    for (const char* h :
         {"final tip RMS (mm)", "share of tip sq.", "final force RMS (N)", "share of force sq."}) {
      head.push_back(h);
    }
  }
  s += "<details><summary>numbers (RMS and each group&rsquo;s share of the samples and of the "
       "squared "
       "residual)</summary><table>" +
       Row(head, "", true);
  for (std::size_t i = 0; i < spec_groups.size(); ++i) {
    const GroupStat& g = spec_groups[i];
    std::vector<std::string> row = {Esc(GroupLabel(kind, g)),    std::to_string(g.samples),
                                    PercentCell(g.sample_share), Fix(g.tip_rms_mm, 4),
                                    PercentCell(g.tip_share),    Fix(g.force_rms_n, 4),
                                    PercentCell(g.force_share)};
    if (!c.single) {
      const auto f = std::find_if(final_groups.begin(), final_groups.end(),
                                  [&](const GroupStat& x) { return x.label == g.label; });
      const bool ok = f != final_groups.end();
      for (const std::string& v :
           {ok ? Fix(f->tip_rms_mm, 4) : "&ndash;", ok ? PercentCell(f->tip_share) : "&ndash;",
            ok ? Fix(f->force_rms_n, 4) : "&ndash;",
            ok ? PercentCell(f->force_share) : "&ndash;"}) {
        row.push_back(v);
      }
    }
    s += Row(row);
  }
  return s + "</table></details>";
}

std::string BreakdownHtml(const Context& c) {
  const Breakdown& bs = c.ladder.front().diagnosis.breakdown;
  const Breakdown& bf = c.ladder.back().diagnosis.breakdown;
  std::string s =
      "<section id=\"breakdown\"><h2>Where the residual lies</h2><p class=\"note\">Residual RMS "
      "over "
      "all samples grouped by phase of motion (from the measured base: within 80 ms after a "
      "reversal, "
      "accelerating, constant velocity, at rest), by base speed and by catheter configuration; "
      "SPEC "
      "against the final model, with the noise level for reference.</p>";
  s += BreakdownBlock(c, "phase of motion", "phase", bs.phase, bf.phase);
  s += BreakdownBlock(c, "base speed", "speed", bs.speed, bf.speed);
  s += BreakdownBlock(c, "gap", "gap", bs.gap, bf.gap);
  s += BreakdownBlock(c, "total bend angle", "bend", bs.bend, bf.bend);
  s += BreakdownBlock(c, "tip load", "load", bs.tip_load, bf.tip_load);
  return s + "</section>";
}

// Shows one plotted trial at a time; without JavaScript every trial stays visible.
constexpr const char* kSelectorScript =
    "<script>(function(){var box=document.getElementById('trial-selector');"
    "var sel=document.getElementById('trial-select');if(!box||!sel)return;box.hidden=false;"
    "sel.addEventListener('change',function(){var p=document.querySelectorAll('.trial-panel');"
    "for(var "
    "i=0;i<p.length;++i){p[i].hidden=!(sel.value==='all'||p[i].id===sel.value);}});})();</script>";

}  // namespace

std::vector<std::size_t> LargestTipResidualTrials(const FitResult& fit, std::size_t count) {
  std::vector<std::size_t> order(fit.trials.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return fit.trials[a].stats.tip_rms_mm > fit.trials[b].stats.tip_rms_mm;
  });
  order.resize(std::min(count, order.size()));
  return order;
}

std::string RenderLabReport(const LabDataset& ds, const std::vector<LadderStep>& ladder,
                            const LabReportOptions& o) {
  if (ladder.empty()) throw std::invalid_argument("lab report: empty error ladder");
  for (const LadderStep& step : ladder) {
    if (step.diagnosis.base.trials.size() != ds.trials.size()) {
      throw std::invalid_argument("lab report: the fit of " + Spec(step.model) + " has " +
                                  std::to_string(step.diagnosis.base.trials.size()) +
                                  " trials, the dataset " + std::to_string(ds.trials.size()));
    }
  }
  for (std::size_t i = 0; i + 1 < ladder.size(); ++i) {
    if (ladder[i].diagnosis.candidates.empty())
      throw std::invalid_argument("lab report: ladder step without candidates");
  }
  const Context c{ds,
                  ladder,
                  o,
                  ladder.front().diagnosis.base,
                  ladder.back().diagnosis.base,
                  Spec(ladder.front().model),
                  Spec(ladder.back().model),
                  ladder.size() == 1};
  std::string page = html::PageStart("Model lab report: " + Esc(c.spec));
  page += HeaderHtml(c) + "\n";
  page += LadderHtml(c) + "\n";
  page += DiagnosisHtml(c) + "\n";
  page += WhereHtml(c) + "\n";
  page += ParametersHtml(c) + "\n";
  page += TrialsHtml(c) + "\n";
  page += BreakdownHtml(c) + "\n";
  page +=
      "<footer>Generated by <code>echoservo lab report</code>. Self-contained page: no external "
      "resources."
      "</footer></main>";
  page += kSelectorScript;
  page += "</body></html>\n";
  return page;
}

}  // namespace echoservo::lab
