#include "apps/commands/set_flags.h"

#include <CLI/CLI.hpp>
#include <stdexcept>

namespace echoservo::apps {

std::vector<live::Assignment> SetFlags::Parsed() const {
  return live::ParseAssignments(assignments, "--set");
}

std::vector<live::Assignment> SetFlags::ParsedFor(std::string_view command,
                                                  const std::vector<std::string>& stages) const {
  return live::RequireStages(Parsed(), command, stages);
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
