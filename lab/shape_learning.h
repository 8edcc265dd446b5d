// Learning a missing term as a shape inside the catheter model, and distilling it into a
// formula — what `lab diagnose` does when neither the catalog nor the discovery library
// (lab/effect_discovery.h) closes the gap between a model and the measurements.
//
// 1. Screening. For each of the top `where` variables of a channel with an excess (single
//    variables and trial-level × sample-level pairs, lab/catheter_where.h), the term is a
//    tabulated function at the right hook of the transmission model: a friction magnitude
//    (friction_n, so it carries the sign of the motion; along speed for velocity), a signed
//    force (force_n, while moving), a tip-sensor offset (sensor_offset_mm) or a drive offset
//    along the friction force (drive_offset_mm). Its effect on the held-out residual is
//    linear in the knot values, so a penalised spline (lab/smooth_shape.h: piecewise linear,
//    second-difference penalty, λ chosen by cross-validation over the trials' folds) is
//    learnt on the residual with what the model already absorbs (Coulomb and viscous
//    friction, the per-trial tip offset) fitted alongside; its held-out gain ranks it.
// 2. Through the model. The best `refit` shapes become tabulated effect files
//    (hw/effect_file.h, "tables") and are fitted with every other parameter of the model
//    (Ceres, lab/model_fit.h, with the same smoothness penalty) and cross-validated over
//    trials; the lowest held-out residual wins (chosen on at most 16 trials spread over a
//    larger dataset, then refitted and cross-validated on all).
// 3. Distillation. The chosen shape is searched by the formula grammar
//    (lab/formula_search.h) along the data's own inputs; the Pareto front's formulas are
//    written as expression effect files and fitted through the model. The simplest formula
//    whose held-out RMS in the shape's channel is within `formula_tolerance` (1.2×) of the
//    shape's is proposed; otherwise the shape itself is, and the note says so.
// A term is proposed only if it is significant (lab/candidate_ranking.h) against the model.
// Units: mm, s, N; scores in noise variances. Knots span the data (with a margin), and a
// tabulated term refuses inputs outside them.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "lab/catheter_where.h"
#include "lab/diagnosis.h"
#include "lab/learned_term.h"

namespace echoservo::lab {

// Learns a term for `model` (whose fit, held-out scores and held-out residual table are
// given) and fills `learning`; returns the proposal (its effect in memory: the caller
// writes the file), or nullopt when nothing learnt is significant.
std::optional<Proposal> LearnMissingTerm(const std::vector<std::string>& model,
                                         const LabDataset& dataset, const FitResult& fit,
                                         const CrossValidation& cv, const ResidualTable& residuals,
                                         const std::vector<WhereEntry>& where,
                                         const DiagnoseOptions& options, ShapeLearning& learning);

// Throws std::invalid_argument naming `option` when a name is not a variable a shape can be
// learnt along (a `where` variable other than a measured channel, or a pair "slow*fast" of
// bend_deg|gap_mm|tip_load_n with base_mm|velocity_mm_s|acceleration_mm_s2|time_s), listing
// the valid names.
void CheckLearnVariables(const std::vector<std::string>& names, const std::string& option);

// Refits a proposal (its effect file spec on top of `model`) and cross-validates it on every
// trial of `dataset`: its fit, held-out figures and the file's default values are updated.
void RefitProposal(Proposal& proposal, const std::vector<std::string>& model,
                   const LabDataset& dataset, const DiagnoseOptions& options);

}  // namespace echoservo::lab
