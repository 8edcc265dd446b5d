// RUN directories (formats/run_record.h), EM-tracker logs (formats/em_log.h) and the accuracy
// report (report/accuracy_report.h, `echoservo report`) in Python: columns as numpy arrays,
// the report's figures as the dict `report --json` prints, its error over time as arrays.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <optional>
#include <string>

#include "apps/commands/report_command.h"
#include "formats/em_log.h"
#include "formats/run_record.h"
#include "imaging/io/em_log_import.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

template <typename Row, typename F>
py::array_t<double> Column(const std::vector<Row>& rows, F f) {
  std::vector<double> v;
  v.reserve(rows.size());
  for (const Row& r : rows) v.push_back(f(r));
  return ToArray(v);
}

template <typename Row, typename F>
py::array_t<double> Points(const std::vector<Row>& rows, F f) {
  std::vector<Eigen::Vector3d> v;
  v.reserve(rows.size());
  for (const Row& r : rows) v.push_back(f(r));
  return ToArray(v);
}

py::dict RunDict(const formats::RunRecord& run) {
  py::dict d;
  d["dir"] = run.dir.string();
  py::dict targets;
  const auto& t = run.targets;
  targets["acquired_s"] = Column(t, [](const auto& r) { return r.acquired_s; });
  targets["arrived_s"] = Column(t, [](const auto& r) { return r.arrived_s; });
  targets["published_s"] = Column(t, [](const auto& r) { return r.published_s; });
  targets["found"] =
      Column(t, [](const auto& r) { return r.found ? 1.0 : 0.0; }).attr("astype")("bool");
  targets["target_mm"] = Points(t, [](const auto& r) { return r.target_mm; });
  targets["tip_mm"] = Points(t, [](const auto& r) { return r.tip_mm; });
  targets["axis"] = Points(t, [](const auto& r) { return r.axis; });
  targets["confidence"] = Column(t, [](const auto& r) { return r.confidence; });
  d["targets"] = targets;
  if (run.has_servo) {
    py::dict s;
    const auto& v = run.servo;
    s["t_s"] = Column(v, [](const auto& r) { return r.t_s; });
    py::list modes;
    for (const auto& r : v) modes.append(r.mode);
    s["mode"] = modes;
    s["setpoint_mm"] = Column(v, [](const auto& r) { return r.setpoint_mm; });
    s["base_mm"] = Column(v, [](const auto& r) { return r.base_mm; });
    s["tip_estimate_mm"] = Column(v, [](const auto& r) { return r.tip_estimate_mm; });
    s["faults"] = Column(v, [](const auto& r) { return r.faults; });
    d["servo"] = s;
  } else {
    d["servo"] = py::none();
  }
  if (run.has_truth) {
    py::dict s;
    s["t_s"] = Column(run.truth, [](const auto& r) { return r.t_s; });
    s["target_mm"] = Points(run.truth, [](const auto& r) { return r.target_mm; });
    s["tip_mm"] = Points(run.truth, [](const auto& r) { return r.tip_mm; });
    d["truth"] = s;
  } else {
    d["truth"] = py::none();
  }
  if (run.has_latency) {
    py::dict s;
    s["arrived_s"] = Column(run.latency, [](const auto& r) { return r.arrived_s; });
    s["applied_s"] = Column(run.latency, [](const auto& r) { return r.applied_s; });
    d["latency"] = s;
  } else {
    d["latency"] = py::none();
  }
  py::dict info;
  info["heart_rate_hz"] = run.info.heart_rate_hz ? py::object(py::float_(*run.info.heart_rate_hz))
                                                 : py::object(py::none());
  info["standoff_mm"] =
      run.info.standoff_mm ? py::object(py::float_(*run.info.standoff_mm)) : py::object(py::none());
  info["source"] = run.info.meta.source;
  info["em_to_image"] = run.info.meta.em_to_image ? py::object(ToArray(*run.info.meta.em_to_image))
                                                  : py::object(py::none());
  py::dict settings;
  for (const auto& [name, value] : run.info.meta.settings) settings[py::str(name)] = value;
  info["settings"] = settings;
  info["notes"] = run.info.notes;
  info["warnings"] = run.info.warnings;
  d["info"] = info;
  d["has_em"] = run.has_em;
  return d;
}

py::dict EmDict(const formats::EmLog& em) {
  py::dict d;
  d["source"] = em.source.string();
  d["format"] = std::string(formats::EmLogFormatName(em.format));
  d["sensor"] = em.sensor;
  d["sensors"] = em.sensors;
  d["t_s"] = Column(em.samples, [](const auto& s) { return s.t_s; });
  d["position_mm"] = Points(em.samples, [](const auto& s) { return s.position_mm; });
  d["valid"] =
      Column(em.samples, [](const auto& s) { return s.valid ? 1.0 : 0.0; }).attr("astype")("bool");
  py::dict drop;
  for (const auto& [why, n] : em.dropouts_by_reason) drop[py::str(why)] = n;
  d["dropouts_by_reason"] = drop;
  d["notes"] = em.notes;
  return d;
}

formats::EmImportOptions EmOptions(const std::string& format, const std::string& units,
                                   const std::string& sensor) {
  formats::EmImportOptions o;
  o.format = formats::ParseEmLogFormat(format);
  if (!units.empty()) o.units = formats::ParseLengthUnit(units);
  o.sensor = sensor;
  return o;
}

}  // namespace

void RegisterRuns(py::module_& m) {
  m.def(
      "read_run",
      [](const std::filesystem::path& dir) { return RunDict(formats::ReadRunRecord(dir)); },
      py::arg("dir"),
      "A RUN directory (docs/report.md): 'targets' (acquired_s, arrived_s, published_s, found,\n"
      "target_mm (n, 3), tip_mm, axis, confidence), 'servo', 'truth', 'latency' (None when the\n"
      "file is absent) and 'info' (run.json: heart rate, standoff, EmToImage, settings).");
  m.def(
      "read_em_log",
      [](const std::filesystem::path& p, const std::string& format, const std::string& units,
         const std::string& sensor) {
        return EmDict(imaging::ReadEmLog(p, EmOptions(format, units, sensor)));
      },
      py::arg("path"), py::arg("format") = "auto", py::arg("units") = "", py::arg("sensor") = "",
      "An EM-tracker log (format 'auto', 'plus', 'aurora' or 'sim', as `report --em-format`):\n"
      "t_s, position_mm (n, 3) in mm, valid, the sensor, drop-outs by reason.");
  m.def(
      "report",
      [](const std::string& run, const std::string& em, const std::string& em_format,
         const std::string& em_units, const std::string& sensor, const std::string& em_to_image,
         const std::string& tracker_lag, std::optional<double> from_s, double max_offset_s,
         std::optional<double> offset_center_s, int phase_bins, bool force,
         const std::string& out) {
        apps::ReportFlags f;
        f.run = run;
        f.em = em;
        f.em_format = em_format;
        f.em_units = em_units;
        f.sensor = sensor;
        f.em_to_image = em_to_image;
        f.tracker_lag = tracker_lag;
        f.from_s = from_s;
        f.max_offset_s = max_offset_s;
        if (offset_center_s) f.offset_center_s = *offset_center_s;
        f.phase_bins = phase_bins;
        f.force = force;
        f.out = out;
        apps::ReportResult r;
        {
          py::gil_scoped_release release;
          r = apps::ProduceReport(f);
        }
        py::dict d = FromJson(r.json);
        py::dict series;
        series["t_s"] = ToArray(r.metrics.t_s);
        series["error_mm"] = ToArray(r.metrics.error_mm);
        series["tip_mm"] = ToArray(r.metrics.tip_mm);
        series["target_mm"] = ToArray(r.metrics.target_mm);
        d["series"] = series;
        return d;
      },
      py::arg("run"), py::kw_only(), py::arg("em") = "", py::arg("em_format") = "auto",
      py::arg("em_units") = "", py::arg("sensor") = "", py::arg("em_to_image") = "",
      py::arg("tracker_lag") = "", py::arg("from_s") = py::none(), py::arg("max_offset_s") = 2.0,
      py::arg("offset_center_s") = py::none(), py::arg("phase_bins") = 10, py::arg("force") = false,
      py::arg("out") = "",
      "The accuracy report of a RUN directory, as `echoservo report RUN --json` (the same\n"
      "options by the flags' names; out: also write the HTML page there): the dict it prints,\n"
      "plus 'series': the scored EM samples' t_s (pipeline time, s), error_mm, tip_mm (n, 3,\n"
      "EM tip mapped into the image frame) and target_mm.");
}

}  // namespace echoservo::python
