// The catheter detector (tracking/radon_detector.h) in Python: the options and `--set` names
// of `echoservo detect`, one volume or array at a time; results in mm in the volume's image
// frame.
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "apps/commands/imaging_commands.h"
#include "imaging/io/volume_io.h"
#include "imaging/volume.h"
#include "live/pipeline_parameters.h"
#include "python/arrays.h"
#include "tracking/radon_detector.h"

namespace echoservo::python {

namespace {

using tracking::CatheterDetection;
using tracking::RadonDetector;

py::object Point(bool valid, const Eigen::Vector3d& p) {
  return valid ? py::object(ToArray(p)) : py::object(py::none());
}

// Detector settings: `set` (parameter name → value, as `detect --set`) and the named ones,
// which are the same parameters.
tracking::RadonDetectorOptions DetectorOptions(const py::dict& set,
                                               const std::optional<double>& sheath_diameter_mm,
                                               const std::optional<double>& wire_diameter_mm,
                                               const std::optional<double>& dynamic_range_db,
                                               const std::optional<double>& min_confidence,
                                               const py::handle& probe_apex_mm,
                                               const py::handle& beam_direction) {
  std::vector<live::Assignment> assignments;
  for (const auto& [key, value] : set) {
    if (!py::isinstance<py::str>(key))
      throw py::value_error(
          "set: the keys are parameter names (str), e.g. "
          "'detector.sheath_diameter_mm'");
    const std::string name = key.cast<std::string>();
    if (!py::isinstance<py::float_>(value) && !py::isinstance<py::int_>(value))
      throw py::value_error("set['" + name + "']: expected a number");
    assignments.emplace_back(name, value.cast<double>());
  }
  auto named = [&](const char* name, const std::optional<double>& v) {
    if (v) assignments.emplace_back(std::string("detector.") + name, *v);
  };
  named("sheath_diameter_mm", sheath_diameter_mm);
  named("wire_diameter_mm", wire_diameter_mm);
  named("dynamic_range_db", dynamic_range_db);
  named("min_confidence", min_confidence);
  for (const auto& [name, value] : assignments)
    live::CheckValue(live::RequireParameter(name), value);
  tracking::RadonDetectorOptions o =
      assignments.empty() ? tracking::RadonDetectorOptions{}
                          : apps::WithDetectSet(tracking::RadonDetectorOptions{}, assignments);
  if (!probe_apex_mm.is_none() && !beam_direction.is_none())
    throw py::value_error("probe_apex_mm, beam_direction: give one (a sector or a linear probe)");
  if (!probe_apex_mm.is_none())
    o.beams = tracking::BeamGeometry::FromApex(Vec3(probe_apex_mm, "probe_apex_mm"));
  if (!beam_direction.is_none()) {
    const Eigen::Vector3d d = Vec3(beam_direction, "beam_direction");
    if (!(d.norm() > 1e-9)) throw py::value_error("beam_direction: must be non-zero");
    o.beams = tracking::BeamGeometry::Parallel(d);
  }
  return o;
}

// The volume to detect in: a Volume, or a uint8 array with its spacing and origin.
std::shared_ptr<imaging::Volume> VolumeArgument(const py::object& volume,
                                                const py::object& spacing_mm,
                                                const py::object& origin_mm) {
  if (py::isinstance<imaging::Volume>(volume)) {
    if (!spacing_mm.is_none() || !origin_mm.is_none())
      throw py::value_error("spacing_mm, origin_mm: only with an array (a Volume has its own)");
    return volume.cast<std::shared_ptr<imaging::Volume>>();
  }
  if (volume.is_none())
    throw py::value_error("volume: expected a Volume or a uint8 (nz, ny, nx) array, got None");
  if (spacing_mm.is_none())
    throw py::value_error("spacing_mm: required with an array (the voxel pitch, mm)");
  py::object ctor = py::module_::import("echoservo").attr("Volume");
  return ctor(volume, spacing_mm,
              origin_mm.is_none() ? py::object(py::make_tuple(0, 0, 0)) : origin_mm)
      .cast<std::shared_ptr<imaging::Volume>>();
}

}  // namespace

void RegisterDetector(py::module_& m) {
  py::class_<CatheterDetection>(
      m, "Detection",
      "One volume's catheter: axis, guidewire tip and target ahead of it (mm, image frame).")
      .def_readonly("found", &CatheterDetection::found,
                    "a catheter was found (confidence >= min_confidence, a long enough run)")
      .def_property_readonly(
          "axis_point_mm", [](const CatheterDetection& d) { return Point(d.found, d.axis.point); },
          "a point on the catheter axis (None when not found)")
      .def_property_readonly(
          "axis_direction",
          [](const CatheterDetection& d) { return Point(d.found, d.axis.direction); },
          "unit axis direction, towards the tip (None when not found)")
      .def_property_readonly(
          "tip_mm", [](const CatheterDetection& d) { return Point(d.found, d.tip_mm); },
          "guidewire tip (None when not found)")
      .def_property_readonly(
          "target_mm",
          [](const CatheterDetection& d) { return Point(d.found && d.target_found, d.target_mm); },
          "tissue surface the catheter points at (None when none lies ahead)")
      .def_readonly("contact", &CatheterDetection::contact, "the tip touches the tissue")
      .def_property_readonly(
          "target_gap_mm",
          [](const CatheterDetection& d) {
            return d.found && d.target_found ? py::object(py::float_(d.target_gap_mm))
                                             : py::object(py::none());
          },
          "tip to target along the axis (mm), None without a target")
      .def_readonly("confidence", &CatheterDetection::confidence, "[0, 1]")
      .def_readonly("tubularity", &CatheterDetection::tubularity,
                    "~1 a tube (catheter), ~0 a line within a surface")
      .def_readonly("line_length_mm", &CatheterDetection::line_length_mm,
                    "bright run along the axis (mm)")
      .def_readonly("peak_z", &CatheterDetection::peak_z, "robust z-score of the Radon peak")
      .def_readonly("tracked", &CatheterDetection::tracked,
                    "the result of a tracking search (not a full one)")
      .def("__repr__", [](const CatheterDetection& d) {
        if (!d.found)
          return "<echoservo.Detection not found, confidence " + std::to_string(d.confidence) + ">";
        return "<echoservo.Detection tip " + py::str(ToArray(d.tip_mm)).cast<std::string>() +
               " mm, confidence " + std::to_string(d.confidence) + ">";
      });

  py::class_<RadonDetector>(
      m, "Detector",
      "The catheter detector of `echoservo detect` and the live tracker: Radon search, echo\n"
      "axis fit, tip and target edges, tube check (docs/detector.md). Settings by the tuning\n"
      "parameters' names (`echoservo tune params`, echoservo.parameters()), as `detect --set`.")
      .def(
          py::init([](const py::dict& set, std::optional<double> sheath, std::optional<double> wire,
                      std::optional<double> dr, std::optional<double> min_conf,
                      const py::object& apex, const py::object& beam) {
            return RadonDetector(DetectorOptions(set, sheath, wire, dr, min_conf, apex, beam));
          }),
          py::arg("set") = py::dict(), py::arg("sheath_diameter_mm") = py::none(),
          py::arg("wire_diameter_mm") = py::none(), py::arg("dynamic_range_db") = py::none(),
          py::arg("min_confidence") = py::none(), py::arg("probe_apex_mm") = py::none(),
          py::arg("beam_direction") = py::none(),
          "set: {'detector.NAME' or 'target.NAME': value} as `detect --set NAME=VALUE`;\n"
          "sheath_diameter_mm, wire_diameter_mm, dynamic_range_db, min_confidence: the same\n"
          "parameters (detector.*). probe_apex_mm (image frame, mm) or beam_direction (a linear\n"
          "probe's parallel beams): where the beams come from, for volumes without an\n"
          "ImageToProbe transform. ValueError naming the parameter for an unknown name or a value\n"
          "outside its bounds.")
      .def(
          "detect",
          [](const RadonDetector& d, const py::object& volume, const py::object& spacing_mm,
             const py::object& origin_mm) {
            const auto v = VolumeArgument(volume, spacing_mm, origin_mm);
            py::gil_scoped_release release;
            return d.Detect(*v);
          },
          py::arg("volume"), py::arg("spacing_mm") = py::none(), py::arg("origin_mm") = py::none(),
          "Full search on a Volume, or on a uint8 (nz, ny, nx) array with spacing_mm (and\n"
          "origin_mm). Stateless.")
      .def(
          "track",
          [](RadonDetector& d, const py::object& volume, const py::object& spacing_mm,
             const py::object& origin_mm) {
            const auto v = VolumeArgument(volume, spacing_mm, origin_mm);
            py::gil_scoped_release release;
            return d.Track(*v);
          },
          py::arg("volume"), py::arg("spacing_mm") = py::none(), py::arg("origin_mm") = py::none(),
          "Search near the previous track() result (a full search first, and whenever the\n"
          "tracked confidence falls below min_confidence), as `detect --track`. It keeps that\n"
          "result: call one Detector's track() from one thread at a time (detect() is stateless).")
      .def("reset", &RadonDetector::Reset,
           "forget the previous result (the next track() searches fully)");

  m.def(
      "parameters",
      [] {
        py::list out;
        for (const live::ParameterInfo& p : live::Parameters()) {
          py::dict d;
          d["name"] = p.name;
          d["unit"] = p.unit;
          d["min"] = p.min;
          d["max"] = p.max;
          d["default"] = p.default_value;
          d["stage"] = p.stage;
          d["description"] = p.description;
          out.append(d);
        }
        return out;
      },
      "Every tunable parameter (as `echoservo tune params`): name, unit, min, max, default,\n"
      "stage, description.");
}

}  // namespace echoservo::python
