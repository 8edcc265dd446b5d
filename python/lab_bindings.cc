// Catheter trials (formats/trial_io.h, docs/trial_format.md) in Python: each trial's columns
// as arrays, for looking at the lab's residuals (`lab compare --residuals DIR` writes the
// model's tip and force beside the measurements) against any variable.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "formats/trial_io.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

py::dict TrialDict(const formats::Trial& t) {
  py::dict d;
  d["name"] = t.name;
  d["t_s"] = ToArray(t.t_s);
  d["base_cmd_mm"] = ToArray(t.base_cmd_mm);
  d["base_mm"] = ToArray(t.base_mm);
  d["tip_mm"] = ToArray(t.tip_mm);
  d["force_n"] = ToArray(t.force_n);
  py::dict extra;
  for (std::size_t i = 0; i < t.extra_names.size(); ++i)
    extra[py::str(t.extra_names[i])] = ToArray(t.extra_columns[i]);
  d["extra"] = extra;
  py::dict config;
  config["sheath_id_mm"] = t.config.sheath_id_mm;
  config["guidewire_od_mm"] = t.config.guidewire_od_mm;
  config["tip_load_n"] = t.config.tip_load_n;
  config["total_bend_rad"] = t.config.TotalBendRad();
  py::list bends;
  for (const auto& b : t.config.bends) {
    py::dict bd;
    bd["angle_deg"] = b.angle_deg;
    bd["radius_mm"] = b.radius_mm;
    bends.append(bd);
  }
  config["bends"] = bends;
  d["config"] = config;
  d["meta"] = FromJson(t.meta_json);
  d["warnings"] = t.warnings;
  return d;
}

}  // namespace

void RegisterLab(py::module_& m) {
  m.def(
      "read_trial", [](const std::filesystem::path& p) { return TrialDict(formats::ReadTrial(p)); },
      py::arg("csv_path"),
      "One catheter trial (CSV + sibling JSON): t_s, base_cmd_mm, base_mm, tip_mm, force_n,\n"
      "'extra' columns (e.g. tip_model, force_model, velocity from `lab compare --residuals`),\n"
      "'config' (sheath_id_mm, guidewire_od_mm, bends, tip_load_n, total_bend_rad), 'meta'.");
  m.def(
      "read_dataset",
      [](const std::filesystem::path& dir) {
        py::list out;
        for (const auto& t : formats::ReadDataset(dir)) out.append(TrialDict(t));
        return out;
      },
      py::arg("dir"),
      "Every trial of a dataset folder (sorted by name), as read_trial gives them.");
}

}  // namespace echoservo::python
