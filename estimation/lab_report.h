// The model lab's HTML report (`echoservo lab report`).
//
// One self-contained page — inline CSS, inline SVG charts (estimation/svg_plot.h), a few
// lines of inline JavaScript for the trial selector (the page is complete without it), no
// external URL, font or script — built from an error ladder (estimation/diagnosis.h)
// that starts at the model SPEC: the dataset (trials, samples, noise levels), the ladder
// (tip and force RMS of every model visited, the effect added at each step, whether the
// last is adequate), the diagnosis of SPEC (candidates, held-out excess explained,
// evidence, verdict), the fitted parameters with SDs of SPEC and of the final model,
// overlays of measured and model tip and force against time, hysteresis loops and
// residuals for the trials with the largest tip residual under SPEC, and the residual
// RMS by base speed, configuration (gap, total bend angle, tip load) and phase of motion
// (estimation/residual_breakdown.h). Residuals are model − measured. Units: mm, s, N.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "estimation/diagnosis.h"

namespace echoservo::estimation {

struct LabReportOptions {
  std::string dataset_path;     // as shown in the header
  std::string generated;        // date shown in the header; empty: now (UTC)
  int stride = 4;               // shown in the header (the dataset's residual stride)
  int max_rounds = 4;           // shown with the ladder
  std::size_t plot_trials = 4;  // trials plotted: those with the largest tip RMS under SPEC
};

// `ladder` is ErrorLadder(SPEC, dataset, ...): its first step is SPEC, its last the final
// model; every step's fit holds one TrialResult per trial of `dataset`. Returns the whole
// HTML document. Throws std::invalid_argument for an empty ladder or mismatched fits.
std::string RenderLabReport(const LabDataset& dataset, const std::vector<LadderStep>& ladder,
                            const LabReportOptions& options);

// Indices of the (at most) `count` trials of `fit` with the largest tip RMS, largest first.
std::vector<std::size_t> LargestTipResidualTrials(const FitResult& fit, std::size_t count);

}  // namespace echoservo::estimation
