// `lab compare|diagnose` on a target-motion trace: is the motion model adequate, which
// catalog effect is it missing, and if none, where does it fail and what term would fix
// it? The catheter lab's procedure (lab/diagnosis.h) and machinery
// (lab/candidate_ranking.h, lab/residual_structure.h).
//
// Noise: the model-free floor of lab/motion_noise.h (the same for every SPEC). Scores are
// held-out mean squares over time-block folds in noise variances; the excess is that − 1.
// Verdicts:
//   missing_effect: a catalog candidate (SPEC + effect) removes a significant part of the
//     held-out excess (SignificanceRule);
//   unexplained: no candidate does, but the excess is ≥ rule.min_excess or the held-out
//     residual has structure along a `where` variable (gain ≥ min_structure_gain);
//   adequate: neither.
// Where: the held-out residuals explained by a binned mean of time_s, cardiac_phase,
// heart_rate_bpm (local rate, lab/motion_noise.h) and cardiac_phase_x_time (8 phase × 4
// slow-time bins), ranked by gain. Discovery (unexplained only): forward selection of at
// most 3 library terms (lab/motion_terms.h), each refitted jointly with the model from
// several starts (periods from the residual's spectrum, the step's moment from its largest
// jump, a rate swing from the beats' local phase), the best start cross-validated (a
// beat_timing term's knots restarted at 0 in every fold) and kept while it lowers the
// held-out mean square by ≥ min_discovery_gain; the result is written as an effect file
// (defaults: the fitted values) and refitted from that file for its held-out RMS (a
// beat_timing term's knots with the penalty it was selected with).
// Learned shapes (unexplained only): the held-out residual (measured − model, mm) learnt as
// a smooth function (lab/smooth_shape.h, λ by the same time-block folds) of time_s,
// cardiac_phase_rad, heart_rate_bpm and the pair cardiac_phase_rad × time_s; the best is
// distilled into closed forms (lab/formula_search.h) whose Pareto front is reported.
// Units: t in s, position in mm, scores in noise variances.
// Details: docs/model_lab.md#motion-diagnosis-labmotion_diagnosish
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lab/candidate_ranking.h"
#include "lab/formula_search.h"
#include "lab/motion_model.h"
#include "lab/motion_noise.h"
#include "lab/residual_structure.h"
#include "lab/smooth_shape.h"

namespace echoservo::lab {

struct MotionGroup {
  std::string label;
  std::size_t samples = 0;
  double rms_mm = 0.0;
  double sample_share = 0.0;
  double error_share = 0.0;
};

struct MotionBreakdown {
  std::vector<MotionGroup> cardiac_phase;
  std::vector<MotionGroup> time;
};

MotionBreakdown ComputeMotionBreakdown(const estimation::MotionTrace& trace, const MotionFit& fit);

struct MotionDiagnoseOptions {
  int folds = 2;
  double block_s = 2.0;
  SignificanceRule rule;
  int threads = 2;
  // Structure along a variable is significant from this held-out gain (noise variances):
  // pure noise leaves ≤ 0 (about −0.01 on a 30 s trace), an effect of RMS σ/2 gives 0.25.
  double min_structure_gain = 0.25;
  bool discover = true;
  int max_terms = 3;
  double min_discovery_gain = 0.05;  // held-out mean square a term must remove
  bool learn_shapes = true;          // unexplained: learned shapes and their formulas
  // Folder of the proposed term file; empty: "<trace stem>_proposal" beside trace.source.
  std::string propose_dir;
};

// Held-out residuals of `spec` over time-block folds: blocks of `block_s` dealt into
// `folds` folds by index; each fold predicted by a fit to the others.
struct MotionHeldOut {
  double mse = 0.0;              // noise variances
  std::vector<double> residual;  // per sample, (model − measured)/σ
  std::vector<int> fold;         // per sample
};
MotionHeldOut HeldOutMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                            double noise_mm, const MotionDiagnoseOptions& options,
                            const std::vector<double>* initial);

// Where the held-out residual has structure: one entry per variable (channel "position"),
// ranked; explained_fraction = gain / (held_out.mse − 1), clipped to [0, 1].
std::vector<WhereEntry> MotionWhere(const estimation::MotionTrace& trace, const MotionFit& fit,
                                    const MotionHeldOut& held_out, const MotionNoise& noise,
                                    double block_s);

struct MotionProposal {
  std::vector<std::string> terms;  // library terms chosen, in order
  std::string spec;                // SPEC with the file, e.g. heartbeat:2+@dir/term.json
  std::string file;
  std::string equation;      // in words, with units
  MotionFit fit;             // of `spec`, refitted from the file
  double cv_mse = 0.0;       // held-out, noise variances
  double rms_mm = 0.0;       // held-out position RMS
  double noise_ratio = 0.0;  // rms_mm / the noise floor
};

// The held-out residual (measured − model, mm) learnt as a smooth function of one variable
// or of the pair (cardiac_phase_rad, time_s).
struct LearnedMotionShape {
  std::string where;                   // the `where` entry it belongs to, e.g. "time_s"
  std::vector<std::string> variables;  // time_s | cardiac_phase_rad | heart_rate_bpm, or the pair
  std::vector<std::string> units;      // s, rad, bpm
  SmoothShape shape;                   // knots, values (mm), λ; its gains and mses in mm²
  double held_out_mse = 0.0;           // model + shape, held out, noise variances
  double gain = 0.0;                   // held-out mean square it removes, noise variances
};

struct MotionCandidate {
  std::string effect;
  MotionFit fit;
  double cv_mse = 0.0;
  double explained = 0.0;  // NaN when the model leaves no excess
  double score = 0.0;
  bool significant = false;
  std::string evidence;
};

struct MotionDiagnosis {
  MotionModelSpec model;
  MotionNoise noise;
  double noise_mm = 0.0;  // noise.position_mm
  MotionFit base;
  double base_cv_mse = 0.0;
  double excess = 0.0;           // base_cv_mse − 1
  double held_out_rms_mm = 0.0;  // √base_cv_mse · noise
  MotionBreakdown breakdown;
  std::vector<MotionCandidate> candidates;  // best first
  std::vector<WhereEntry> where;            // ranked
  bool adequate = false;
  std::string verdict;                     // "adequate" | "missing_effect" | "unexplained"
  std::string summary;                     // the verdict in words
  std::optional<MotionProposal> proposal;  // unexplained, when discovery found a term
  std::vector<LearnedMotionShape> shapes;  // unexplained: lowest held-out mse first
  // unexplained: the Pareto front (held-out error against complexity) of formulas
  // distilling shapes.front() (target: the shape's values, held_out_mse in mm²).
  std::vector<Formula> formulas;
};

// Held-out mean square (noise variances) of `spec` over time-block folds.
double CrossValidateMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                           double noise_mm, const MotionDiagnoseOptions& options,
                           const std::vector<double>* initial);

MotionDiagnosis DiagnoseMotion(const MotionModelSpec& spec, const estimation::MotionTrace& trace,
                               const MotionDiagnoseOptions& options = {});

}  // namespace echoservo::lab
