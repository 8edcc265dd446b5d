// Runs a study (tune/study_spec.h) into a STUDY folder (tune/study_files.h) on an executor
// (tune/executor.h: local processes or a Slurm job array): writes study.json, proposes
// parameter sets (set 0 = the default settings, then the search's), runs every trial not
// yet finished, records a failed trial (crash, timeout, exit status) with its reason and
// goes on. Searches: grid (every combination of the axes' values), random (uniform in each
// axis's range, integers rounded; seeded), adaptive (tune/search.h: a maintained derivative-free
// bounded optimiser over the continuous axes, the objective = mean over recordings).
// Resumable: a rerun with the same SPEC skips finished trials; a different SPEC in an
// existing STUDY is refused (naming what differs).
// Errors: std::invalid_argument for a bad spec or a STUDY of another spec;
// std::runtime_error when the STUDY folder cannot be written.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "tune/executor.h"
#include "tune/study_spec.h"

namespace echoservo::tune {

struct StudySummary {
  std::size_t sets = 0, trials = 0, skipped = 0, ran = 0, failed = 0;
  double wall_s = 0.0;
};

StudySummary RunStudy(const StudySpec& spec, const std::filesystem::path& study,
                      TrialExecutor& executor,
                      const std::function<void(const std::string&)>& log = nullptr);

}  // namespace echoservo::tune
