// Motion traces and the heartbeat predictor (estimation/) in Python: `echoservo predict`'s
// competition on arrays, with the same figures and the same dict as `predict --json`.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <optional>
#include <string>

#include "apps/commands/motion_commands.h"
#include "estimation/motion_trace.h"
#include "estimation/realistic_heart_trace.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

estimation::MotionTrace TraceFrom(const py::handle& t_s, const py::handle& x_mm,
                                  const std::string& t_name, const std::string& x_name,
                                  const std::string& column) {
  estimation::MotionTrace trace;
  trace.source = x_name;  // the predictor's messages name the trace by its source
  trace.column = column;
  trace.t_s = FiniteVector(t_s, t_name, 2);
  trace.position_mm = FiniteVector(x_mm, x_name);
  if (trace.position_mm.size() != trace.t_s.size())
    throw py::value_error(x_name + ": " + std::to_string(trace.position_mm.size()) +
                          " values for " + std::to_string(trace.t_s.size()) + " times (" + t_name +
                          ")");
  for (std::size_t i = 1; i < trace.t_s.size(); ++i)
    if (!(trace.t_s[i] > trace.t_s[i - 1]))
      throw py::value_error(t_name + ": not strictly increasing at element " + std::to_string(i) +
                            " (" + std::to_string(trace.t_s[i - 1]) + " then " +
                            std::to_string(trace.t_s[i]) + ")");
  return trace;
}

py::tuple TraceArrays(const estimation::MotionTrace& t) {
  return py::make_tuple(ToArray(t.t_s), ToArray(t.position_mm));
}

}  // namespace

void RegisterMotion(py::module_& m) {
  m.def(
      "predict",
      [](const py::object& t_s, const py::object& position_mm, const py::object& truth_mm,
         const py::object& truth_t_s, double latency_s, double rate_hz,
         const std::string& harmonics, std::optional<bool> respiration, double noise_mm,
         double init_window_s, double min_hz, double max_hz, const std::string& combination,
         const std::string& column) {
        const estimation::MotionTrace trace =
            TraceFrom(t_s, position_mm, "t_s", "position_mm", column);
        std::optional<estimation::MotionTrace> truth;
        apps::PredictFlags f;
        if (!truth_mm.is_none()) {
          truth = truth_t_s.is_none()
                      ? TraceFrom(t_s, truth_mm, "t_s", "truth_mm", "truth")
                      : TraceFrom(truth_t_s, truth_mm, "truth_t_s", "truth_mm", "truth");
          f.truth = "truth";
        }
        f.latency_s = latency_s;
        f.rate_hz = rate_hz;
        f.harmonics = harmonics;
        f.respiration = respiration.value_or(false);
        f.no_respiration = respiration.has_value() && !*respiration;
        f.noise_mm = noise_mm;
        f.init_window_s = init_window_s;
        f.min_hz = min_hz;
        f.max_hz = max_hz;
        f.combination = combination;
        apps::PredictResult r;
        {
          py::gil_scoped_release release;
          r = apps::PredictInMemory(f, trace, truth ? &*truth : nullptr);
        }
        py::dict d = FromJson(r.json);
        const auto& s = r.run.series;
        py::dict series;
        series["t_s"] = ToArray(s.t_s);
        series["truth_mm"] = ToArray(s.truth_mm);
        series["shipped_mm"] = ToArray(s.shipped_mm);
        py::array_t<int> chosen(static_cast<py::ssize_t>(s.chosen.size()));
        std::copy(s.chosen.begin(), s.chosen.end(), chosen.mutable_data());
        series["chosen"] = chosen;
        py::list names;
        for (const auto& c : r.run.competitors) names.append(c.name);
        series["competitors"] = names;
        d["series"] = series;
        return d;
      },
      py::arg("t_s"), py::arg("position_mm"), py::arg("truth_mm") = py::none(), py::kw_only(),
      py::arg("truth_t_s") = py::none(), py::arg("latency_s") = 0.1, py::arg("rate_hz") = 0.0,
      py::arg("harmonics") = "auto", py::arg("respiration") = py::none(), py::arg("noise_mm") = 0.0,
      py::arg("init_window_s") = 4.0, py::arg("min_hz") = 0.6, py::arg("max_hz") = 3.0,
      py::arg("combination") = "best", py::arg("column") = "position",
      "Prediction through the imaging delay on a motion trace, as `echoservo predict --json`:\n"
      "the competition the tracker ships (heartbeat EKF, autoregressive predictors, blend,\n"
      "baselines), each competitor alone, the autoregressive reference on the second half, and\n"
      "the heart rate (ekf.heart_rate_bpm: None unless a periodic component is significant).\n"
      "t_s (s, strictly increasing) and position_mm (mm) are 1-D arrays of equal length;\n"
      "truth_mm: score against it instead (e.g. noise-free), sampled at truth_t_s (default:\n"
      "t_s). latency_s: the horizon;\n"
      "rate_hz: measure at this rate by interpolation (0: every sample); harmonics: 'auto' or\n"
      "1-12; respiration: None (automatic), True or False. Returns the command's dict plus\n"
      "'series': at every scored instant the time predicted (t_s: a measurement's time +\n"
      "latency_s), the reference there (truth_mm), what shipped (shipped_mm) and the competitor\n"
      "chosen (chosen: index into series['competitors']).");
  m.def(
      "read_motion_trace",
      [](const std::filesystem::path& p, const std::string& column) {
        return TraceArrays(estimation::ReadMotionTrace(p, column));
      },
      py::arg("path"), py::arg("column") = "",
      "A motion-trace CSV (header with 't' in s and position columns in mm, as `echoservo sim\n"
      "motion` writes): (t_s, position_mm) arrays of `column` (default: the first after t).");
  m.def(
      "realistic_trace",
      [](const std::string& cls, std::uint64_t seed, double duration_s) {
        estimation::RealisticHeartOptions o = estimation::RealisticHeartClass(cls, seed);
        o.duration_s = duration_s;
        estimation::MotionTrace truth;
        const estimation::MotionTrace t = estimation::GenerateRealisticHeartTrace(o, &truth);
        py::dict d;
        d["t_s"] = ToArray(t.t_s);
        d["position_mm"] = ToArray(t.position_mm);
        d["truth_t_s"] = ToArray(truth.t_s);
        d["truth_mm"] = ToArray(truth.position_mm);
        return d;
      },
      py::arg("cls"), py::arg("seed") = 1, py::arg("duration_s") = 30.0,
      "A generated realistic heart trace (as `predict --realistic CLASS`): a dict of t_s and\n"
      "position_mm (the measured trace: noise, drop-outs) and truth_t_s, truth_mm (the\n"
      "noise-free motion). Classes: echoservo.realistic_classes().");
  m.def("realistic_classes", &estimation::RealisticHeartClasses,
        "The realistic trace classes (regular, ectopic, rate_steps, breathing, noisy, ...).");
}

}  // namespace echoservo::python
