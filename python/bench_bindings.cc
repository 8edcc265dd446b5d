// The C++ side of bench/python_detect_bench.py: the same calls as the Python loop (read a
// volume file, full detection), timed in C++ in the same process, so that the ratio measures
// what the bindings add.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <chrono>
#include <vector>

#include "imaging/io/volume_io.h"
#include "python/arrays.h"
#include "tracking/radon_detector.h"

namespace echoservo::python {

void RegisterBench(py::module_& m) {
  m.def(
      "_cpp_read_and_detect",
      [](const std::filesystem::path& path, int repetitions) {
        if (repetitions < 1) throw py::value_error("repetitions: at least 1");
        py::gil_scoped_release release;
        const tracking::RadonDetector detector;
        std::vector<double> seconds;
        for (int r = 0; r < repetitions; ++r) {
          const auto t0 = std::chrono::steady_clock::now();
          const imaging::Volume v = imaging::ReadVolume(path);
          const tracking::CatheterDetection d = detector.Detect(v);
          if (!d.found && d.confidence < 0) throw std::logic_error("unreachable");
          seconds.push_back(
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        }
        return seconds;
      },
      py::arg("path"), py::arg("repetitions"),
      "Benchmark helper: seconds of each of `repetitions` read_volume + Detector().detect made\n"
      "in C++ (bench/python_detect_bench.py).");
}

}  // namespace echoservo::python
