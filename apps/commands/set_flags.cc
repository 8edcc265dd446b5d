#include "apps/commands/set_flags.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <stdexcept>

namespace echoservo::apps {

std::vector<live::Assignment> SetFlags::Parsed() const {
  return live::ParseAssignments(assignments, "--set");
}

std::vector<live::Assignment> SetFlags::ParsedFor(std::string_view command,
                                                  const std::vector<std::string>& stages) const {
  std::vector<live::Assignment> parsed = Parsed();
  for (const live::Assignment& a : parsed) {
    const std::string& stage = live::RequireParameter(a.first).stage;
    if (std::find(stages.begin(), stages.end(), stage) != stages.end()) continue;
    std::string allowed;
    for (const std::string& s : stages) allowed += (allowed.empty() ? "" : ", ") + s + ".*";
    throw std::invalid_argument("--set " + live::FormatAssignment(a) +
                                ": the parameter does not apply to `" + std::string(command) +
                                "` (its stage '" + stage + "' does not run there; it takes " +
                                allowed + ")");
  }
  return parsed;
}

void AddSetFlags(CLI::App& cmd, SetFlags& flags) {
  cmd.add_option("--set", flags.assignments,
                 "a tunable parameter NAME=VALUE, e.g. --set detector.sheath_diameter_mm=2.5 "
                 "(repeatable; `echoservo tune params` lists them; overrides the dedicated "
                 "flags)")
      ->type_name("NAME=VALUE")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

}  // namespace echoservo::apps
