// The program's commands in this process (apps/cli.h RunCommand), for what the model lab,
// the simulators and the tuning studies do: the same code, checks and messages as
// `echoservo ARGS…`, their JSON returned as dicts. A failing command raises ValueError with
// the message the program prints.
#include <pybind11/stl.h>
#include <sys/mman.h>

#include <csignal>
#include <fstream>
#include <mutex>
#include <string>
#include <vector>

#include "apps/cli.h"
#include "python/arrays.h"

namespace echoservo::python {

namespace {

std::mutex& CommandMutex() {
  static std::mutex m;
  return m;
}

// Locked memory of this process (kB, /proc/self/status VmLck), -1 when unknown.
long LockedKb() {
  std::ifstream in("/proc/self/status");
  std::string key;
  while (in >> key) {
    if (key == "VmLck:") {
      long kb = -1;
      in >> kb;
      return kb;
    }
    in.ignore(1 << 16, '\n');
  }
  return -1;
}

// What a command may change in the process and the interpreter must get back: the SIGINT and
// SIGTERM handlers (`track` and `servo` install their own, to stop cleanly on Ctrl-C) and
// locked memory (the servo's real-time set-up locks all of it, now and future: the
// interpreter's too).
class ProcessStateGuard {
 public:
  ProcessStateGuard() : locked_kb_(LockedKb()) {
    sigaction(SIGINT, nullptr, &int_);
    sigaction(SIGTERM, nullptr, &term_);
  }
  ~ProcessStateGuard() {
    sigaction(SIGINT, &int_, nullptr);
    sigaction(SIGTERM, &term_, nullptr);
    if (locked_kb_ == 0) munlockall();
  }
  ProcessStateGuard(const ProcessStateGuard&) = delete;
  ProcessStateGuard& operator=(const ProcessStateGuard&) = delete;

 private:
  long locked_kb_;
  struct sigaction int_ {};
  struct sigaction term_ {};
};

// The command's stdout; ValueError with its message when it fails.
std::string Run(const std::vector<std::string>& args) {
  std::string out, err;
  int rc = 0;
  {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(CommandMutex());
    const ProcessStateGuard guard;
    rc = apps::RunCommand(args, out, err);
  }
  if (rc != 0) {
    std::string why = err;
    const std::string prefix = "echoservo: error: ";
    if (why.rfind(prefix, 0) == 0) why = why.substr(prefix.size());
    while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
    std::string line;
    for (const auto& a : args) line += " " + a;
    throw py::value_error(why.empty() ? "echoservo" + line + ": exit status " + std::to_string(rc)
                                      : why);
  }
  return out;
}

std::vector<std::string> Args(std::vector<std::string> head, const py::args& rest) {
  for (const auto& a : rest) {
    if (!py::isinstance<py::str>(a) && !py::isinstance<py::int_>(a) &&
        !py::isinstance<py::float_>(a))
      throw py::value_error("arguments: expected str or numbers, got " +
                            py::str(a.get_type()).cast<std::string>());
    head.push_back(py::str(a).cast<std::string>());
  }
  return head;
}

py::object Json(const std::vector<std::string>& args) {
  const std::string out = Run(args);
  try {
    return FromJson(out);
  } catch (const py::error_already_set&) {
    throw py::value_error("echoservo " + args.front() +
                          ": the output is not JSON: " + out.substr(0, 200));
  }
}

// The learned shapes of a diagnosis (`learning.shapes`, apps/commands/lab_json.cc): each
// shape's knots (one list per variable) and values as float64 arrays.
py::object WithShapeArrays(py::object d) {
  if (!py::isinstance<py::dict>(d) || !d.contains("learning")) return d;
  py::object learning = d["learning"];
  if (!py::isinstance<py::dict>(learning) || !learning.contains("shapes")) return d;
  py::module_ np = py::module_::import("numpy");
  for (py::handle shape : learning["shapes"]) {
    py::list knots;
    for (py::handle axis : shape["knots"]) knots.append(np.attr("asarray")(axis, "float64"));
    shape["knots"] = knots;
    shape["values"] = np.attr("asarray")(shape["values"], "float64");
  }
  return d;
}

}  // namespace

void RegisterCommands(py::module_& m) {
  m.def(
      "run_command", [](const std::vector<std::string>& args) { return Run(args); },
      py::arg("args"),
      "Run `echoservo ARGS...` in this process (a list of strings, without the program name) and\n"
      "return what it printed; ValueError with the program's message when it fails.");
  m.def(
      "lab_compare",
      [](const std::string& dataset, const py::args& args) {
        return Json(Args({"lab", "compare", dataset, "--json"}, args));
      },
      py::arg("dataset"),
      "`echoservo lab compare DATASET --json ARGS...` (a catheter dataset folder or a motion\n"
      "trace; e.g. '--model', 'full', '--set', 'friction.coulomb_n=1.2'): the model's fit,\n"
      "breakdown, residual groups and 'where' as a dict.");
  m.def(
      "lab_diagnose",
      [](const std::string& dataset, const py::args& args) {
        return WithShapeArrays(Json(Args({"lab", "diagnose", dataset, "--json"}, args)));
      },
      py::arg("dataset"),
      "`echoservo lab diagnose DATASET --json ARGS...`: verdict, where the model fails, the\n"
      "ranked candidate effects, the proposal and the learned shapes as a dict; each shape in\n"
      "learning['shapes'] has 'knots' (one float64 array per variable in 'variables') and\n"
      "'values' (float64: the shape at the knots, in its 'unit').");
  m.def(
      "simulate", [](const py::args& args) { return Run(Args({"sim"}, args)); },
      "`echoservo sim ARGS...` (e.g. 'effects', 'track', 'record', 'motion' with their flags):\n"
      "what it printed.");
  m.def(
      "simulate_trials",
      [](const std::string& effects, const std::string& out, const std::string& configs,
         const std::string& trajectories, double duration_s, const std::vector<std::string>& args) {
        std::vector<std::string> head = {"sim",        "record",     "--out",
                                         out,          "--effects",  effects,
                                         "--configs",  configs,      "--trajectories",
                                         trajectories, "--duration", std::to_string(duration_s)};
        head.insert(head.end(), args.begin(), args.end());
        Run(head);
        return py::module_::import("echoservo").attr("read_dataset")(out);
      },
      py::arg("effects"), py::arg("out"), py::kw_only(), py::arg("configs") = "seed",
      py::arg("trajectories") = "sine", py::arg("duration_s") = 4.0,
      py::arg("args") = std::vector<std::string>{},
      "Simulate catheter trials whose catheter has the effects of a model SPEC (e.g.\n"
      "'seed+capstan_friction' or 'seed+@my_effect.json'), as `echoservo sim record`, into the\n"
      "folder `out`, and return them as read_dataset gives them. configs: seed, lab or table1;\n"
      "trajectories: comma-separated specs (sine:A:F, triangle:A:V, mitral:BPM:P2P); more\n"
      "flags as args (e.g. ['--seed', '3', '--set', 'NAME=VALUE']).");
  m.def(
      "tune_study",
      [](const std::string& spec, const std::string& study, const py::args& args) {
        Run(Args({"tune", spec, "--out", study}, args));
        return Json({"tune", "report", study, "--json"});
      },
      py::arg("spec"), py::arg("study"),
      "Run a tuning study, as `echoservo tune SPEC --out STUDY ARGS...` (e.g. '--jobs', 2), and\n"
      "return its report's figures (`tune report STUDY --json`) as a dict.");
  m.def(
      "tune_trial",
      [](const py::args& args) {
        return Json(Args({"tune", "trial", "--json"}, args));
      },
      "`echoservo tune trial --json ARGS...` (e.g. '--recording', R, '--set', 'NAME=VALUE'):\n"
      "one trial's figures as a dict.");
  m.def(
      "tune_report",
      [](const std::string& study, const py::args& args) {
        return Json(Args({"tune", "report", study, "--json"}, args));
      },
      py::arg("study"),
      "`echoservo tune report STUDY --json ARGS...`: the study's figures as a dict.");
}

}  // namespace echoservo::python
