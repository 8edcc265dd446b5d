// `--set name=value` (repeatable) on `track`, `servo`, `demo`, `detect` and `tune trial`: a tunable
// parameter by its dotted name (live/pipeline_parameters.h, `echoservo tune params`), so a
// setting a study found can be replayed by hand. Checked when the command runs: an unknown
// name or a value outside its bounds is an error naming the flag and the parameter; so is a
// parameter whose stage the command does not run (ParsedFor: live::RequireStages, the one
// filter every command uses).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "live/pipeline_parameters.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

struct SetFlags {
  std::vector<std::string> assignments;  // as given
  // The parsed, checked assignments; throws std::invalid_argument naming --set.
  std::vector<live::Assignment> Parsed() const;
  // The same, each parameter's stage among `stages` (e.g. {"detector", "target"} for
  // `detect`); otherwise std::invalid_argument naming --set, the parameter and `command`.
  std::vector<live::Assignment> ParsedFor(std::string_view command,
                                          const std::vector<std::string>& stages) const;
};

// Adds --set NAME=VALUE (one assignment per occurrence, repeatable).
void AddSetFlags(CLI::App& cmd, SetFlags& flags);

}  // namespace echoservo::apps
