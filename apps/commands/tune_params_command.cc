// `echoservo tune params [--json] [--stage S]`: the tracker path's tunable parameters
// (live/pipeline_parameters.h): name, unit, default, bounds, stage and description, as a
// table or a JSON array [{"name", "unit", "kind", "default", "min", "max", "stage",
// "description"}], sorted by name. The names are what `--set NAME=VALUE` (track, demo,
// detect, tune trial) and a tuning SPEC accept.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "apps/commands/tune_commands.h"
#include "live/pipeline_parameters.h"

namespace echoservo::apps {
namespace {

const std::vector<std::string>& TuneParamsStages() {
  static const std::vector<std::string> stages = {"scanner",   "detector", "target",
                                                  "predictor", "follower", "servo"};
  return stages;
}

const char* TuneParamsKind(live::ParameterKind k) {
  switch (k) {
    case live::ParameterKind::kInteger:
      return "integer";
    case live::ParameterKind::kBool:
      return "bool";
    case live::ParameterKind::kReal:
      break;
  }
  return "real";
}

// The shortest text that reads back to v (as --set writes it).
std::string TuneParamsNumber(double v) { return live::FormatAssignment({"", v}).substr(1); }

void RunTuneParams(bool json, const std::string& stage) {
  const std::vector<std::string>& stages = TuneParamsStages();
  if (!stage.empty() && std::find(stages.begin(), stages.end(), stage) == stages.end()) {
    std::string known;
    for (const std::string& s : stages) known += (known.empty() ? "" : ", ") + s;
    throw std::invalid_argument("tune params --stage '" + stage + "': unknown stage (" + known +
                                ")");
  }
  std::vector<live::ParameterInfo> rows;
  for (const live::ParameterInfo& p : live::Parameters())
    if (stage.empty() || p.stage == stage) rows.push_back(p);
  if (json) {
    nlohmann::json out = nlohmann::json::array();
    for (const live::ParameterInfo& p : rows)
      out.push_back({{"name", p.name},
                     {"unit", p.unit},
                     {"kind", TuneParamsKind(p.kind)},
                     {"default", p.default_value},
                     {"min", p.min},
                     {"max", p.max},
                     {"stage", p.stage},
                     {"description", p.description}});
    std::cout << out.dump(2) << "\n";
    return;
  }
  // Columns: name, unit, default, min, max, stage (widths from the rows), description.
  std::vector<std::array<std::string, 6>> cells = {
      {"name", "unit", "default", "min", "max", "stage"}};
  for (const live::ParameterInfo& p : rows)
    cells.push_back({p.name, p.unit, TuneParamsNumber(p.default_value), TuneParamsNumber(p.min),
                     TuneParamsNumber(p.max), p.stage});
  std::array<std::size_t, 6> width{};
  for (const auto& row : cells)
    for (std::size_t c = 0; c < row.size(); ++c) width[c] = std::max(width[c], row[c].size());
  for (std::size_t r = 0; r < cells.size(); ++r) {
    for (std::size_t c = 0; c < cells[r].size(); ++c)
      std::printf("%-*s  ", static_cast<int>(width[c]), cells[r][c].c_str());
    std::printf("%s\n", r == 0 ? "description" : rows[r - 1].description.c_str());
  }
}

}  // namespace

void AddTuneParamsCommand(CLI::App& tune) {
  CLI::App* cmd = tune.add_subcommand(
      "params",
      "the tracker path's tunable parameters: name, unit, default, bounds, stage (what --set "
      "and a tuning SPEC accept)");
  auto json = std::make_shared<bool>(false);
  auto stage = std::make_shared<std::string>();
  cmd->add_flag("--json", *json, "print a JSON array instead of the table");
  cmd->add_option("--stage", *stage,
                  "only this stage's parameters: detector, target, predictor, follower, servo");
  cmd->callback([json, stage] { RunTuneParams(*json, *stage); });
}

}  // namespace echoservo::apps
