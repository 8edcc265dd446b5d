// The model lab's HTML report (`echoservo lab report`).
//
// One self-contained page (inline CSS, inline SVG charts from report/svg_plot.h, a few lines
// of inline JavaScript for the trial selector; no external URL, font or script) built from
// an error ladder (lab/diagnosis.h) that starts at the model SPEC: the dataset, the ladder,
// the diagnosis of SPEC, the fitted parameters, per-trial plots and the residual RMS by
// speed, configuration and phase of motion (lab/residual_breakdown.h).
// Residuals are model − measured. Units: mm, s, N.
// Errors: std::invalid_argument for an empty ladder or mismatched fits.
// Details: docs/model_lab.md#the-report-lab-report
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lab/diagnosis.h"

namespace echoservo::lab {

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

}  // namespace echoservo::lab
