// Discovery beyond the catalog: when no candidate explains a model's excess residual,
// propose a new effect learned from the data, as an effect file (docs/effect_files.md).
//
// The library holds physically meaningful terms over the variables of `where`
// (lab/catheter_where.h): friction-like terms (a friction magnitude, so they carry the
// sign of the motion) that grow linearly or quadratically with a variable or form a bump
// along it (a tight spot in the sheath), scaled by the bend, gap or tip load; signed
// forces (guidewire inertia m·a, a spring k·x); tip-sensor terms (drift in time, a
// nonlinearity); a stiffening drive offset (F³). Each term has one coefficient (a bump
// also a centre and width, read off the residual's profile).
// Procedure, a sparse forward selection: (1) screening — for the variables that explain
// most of each channel's excess, every term's effect on the residual is linearised
// (coefficient × the term's signature in noise σ) and its coefficient fitted on the
// training folds; the held-out gain ranks the terms; (2) in that order, up to `refit`
// terms are fitted through the whole transmission model (the model plus the term as one
// effect, every parameter refitted) and cross-validated over trials, stopping at the first
// significant term that removes ≥ 80 % of its channel's excess; the best significant one
// (lab/candidate_ranking.h) is kept; (3) while a channel keeps a significant excess,
// the next term is added the same way (at most `max_terms`). The result: an effect file
// with the fitted values as defaults and bounds of ±10× around them, its equation in words
// and units, the SPEC that uses it, and its held-out RMS per channel.
// Units: mm, s, N; residual scores in noise variances.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "lab/catheter_where.h"
#include "lab/diagnosis.h"

namespace echoservo::lab {

// Proposes an effect for `model` on `dataset` given its diagnosis (base fit, held-out
// scores and residual table). Writes the effect file into `out_dir` when it is not empty
// (created if missing). nullopt when no term explains a significant part of the excess.
// On a dataset larger than the selection, `refit_all` false stops at the first term and
// leaves its figures on the selection (Proposal::cv_trials says so): the caller refits what
// it keeps.
std::optional<Proposal> DiscoverEffect(const std::vector<std::string>& model,
                                       const LabDataset& dataset, const Diagnosis& diagnosis,
                                       const ResidualTable& residuals,
                                       const DiagnoseOptions& options,
                                       const std::filesystem::path& out_dir, bool refit_all = true);

}  // namespace echoservo::lab
