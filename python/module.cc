// The Python module `echoservo`: the volume and sequence files, the catheter detector, the
// heartbeat predictor, RUN directories, EM logs and the accuracy report, and the model lab and
// tuning commands, from the same libraries (and the same command code) as the `echoservo`
// program. numpy arrays in and out, in mm, s and rad, frames as in C++ (docs/python.md).
#include <dlfcn.h>
#include <glog/logging.h>
#include <pybind11/stl.h>

#include <filesystem>
#include <string>

#include "apps/cli.h"
#include "python/arrays.h"

namespace {

// This module's file ("" when unknown).
std::string ModuleFile() {
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&ModuleFile), &info) == 0 || !info.dli_fname) return {};
  return info.dli_fname;
}

// Effect plugins (hw/effect_plugin.h, `--plugin`) call the hw code of the program that loads
// them; here that code is in this module, which Python loads with RTLD_LOCAL: make its
// symbols global, as the program exports its own.
void ExportSymbolsToPlugins() {
  const std::string file = ModuleFile();
  if (!file.empty()) dlopen(file.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_GLOBAL);
}

// The echoservo program built beside this module (build/python/../bin/echoservo), empty when
// there is none: what `tune` starts for its trials (apps/cli.h SetProgramPath).
std::string ProgramBesideModule() {
  const std::string file = ModuleFile();
  if (file.empty()) return {};
  const std::filesystem::path p =
      std::filesystem::path(file).parent_path().parent_path() / "bin" / "echoservo";
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec) ? p.string() : std::string();
}

}  // namespace

PYBIND11_MODULE(echoservo, m) {
  m.doc() =
      "echoservo: ultrasound-guided motion-compensation catheter servo, simulator and model lab.\n"
      "Volumes and PLUS sequences as numpy arrays, the catheter detector, the heartbeat\n"
      "predictor, RUN directories and accuracy reports, the model lab and tuning studies: the\n"
      "same libraries and commands as the `echoservo` program (docs/python.md). Units: mm, s,\n"
      "rad; a C++ error arrives as ValueError (a bad input) or RuntimeError with its message.";
  // Ceres logs through glog; as in the program, only errors reach the terminal.
  FLAGS_minloglevel = google::GLOG_ERROR;
  if (!google::IsGoogleLoggingInitialized()) google::InitGoogleLogging("echoservo");
  m.attr("__version__") = "0.1.0";
  ExportSymbolsToPlugins();
  if (const std::string program = ProgramBesideModule(); !program.empty())
    echoservo::apps::SetProgramPath(program);
  m.def("set_program", &echoservo::apps::SetProgramPath, pybind11::arg("path"),
        "The echoservo program that commands starting processes of their own run (a tuning\n"
        "study's trials): by default the one built beside this module.");
  m.def("program", &echoservo::apps::ProgramPath, "The echoservo program set_program names.");
  echoservo::python::RegisterVolumes(m);
  echoservo::python::RegisterDetector(m);
  echoservo::python::RegisterMotion(m);
  echoservo::python::RegisterRuns(m);
  echoservo::python::RegisterCommands(m);
  echoservo::python::RegisterLab(m);
  echoservo::python::RegisterBench(m);
  echoservo::python::RegisterIgtl(m);
}
