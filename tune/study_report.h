// What a study found, for people (HTML) and machines (JSON): `echoservo tune report`.
//
// The objective of each parameter set is compared with the default settings' (set 0) on
// the same recordings (paired): the mean difference with a bootstrap confidence interval
// over recordings, and an exact sign-flip permutation test (p-value) of "no difference";
// sets are ranked by their mean objective over the recordings where every compared trial
// finished. Also: the objective against each tuned parameter (SVG scatter, one mark per
// trial, the per-set mean joined), per-recording winners and losers (each recording's best
// set, and the recordings where the overall best set does worse than the default), the
// failed trials with their reasons, and the commands that replay the best setting by hand
// (`echoservo tune trial …`, `echoservo track --replay … --set …`).
// Units: the objective metric's (tune/trial.h). Errors: std::invalid_argument naming the
// STUDY folder and why (no study.json, no trial with a value of the objective).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace echoservo::tune {

struct StudyReportOptions {
  int bootstrap_samples = 2000;  // [100, 1000000]
  double confidence = 0.95;      // (0, 1)
  std::uint64_t seed = 1;
};

std::string StudyReportJson(const std::filesystem::path& study, const StudyReportOptions& o);
std::string StudyReportHtml(const std::filesystem::path& study, const StudyReportOptions& o);

}  // namespace echoservo::tune
