// Registration of `echoservo report RUN`: the accuracy report of a tracking run against an
// EM-tracker log (report/accuracy_report.h).
#pragma once

#include <limits>
#include <optional>
#include <string>

#include "report/accuracy_report.h"

namespace CLI {
class App;
}

namespace echoservo::apps {

// `echoservo report`'s settings, one per flag.
struct ReportFlags {
  std::string run;
  std::string em;
  std::string em_format = "auto";
  std::string em_units;
  std::string sensor;
  std::string out;
  std::string em_to_image;
  std::string tracker_lag;  // s, or a `calibrate temporal --json` file
  std::optional<double> from_s;
  double max_offset_s = 2.0;
  double offset_center_s = std::numeric_limits<double>::quiet_NaN();
  int phase_bins = 10;
  bool json = false;
  bool force = false;
  std::string from_reason = "--from";
};

void AddReportCommand(CLI::App& app);

// What `report --json` prints (as text) and the metrics behind it (the error over time); the
// page is written only when f.out is not empty (the Python API: python/). Throws like `report`.
struct ReportResult {
  report::AccuracyMetrics metrics;
  std::string json;
};
ReportResult ProduceReport(const ReportFlags& f);

// The report of a RUN directory with its own em.csv and calibration, from `from_s` on (NaN:
// the scored window, report/scored_window.h, as `report RUN` gives by default), written to
// `html_path`; returns the tip-to-target RMS (mm). Throws like `report`.
double WriteRunReport(const std::string& run_dir, const std::string& html_path, double from_s);

}  // namespace echoservo::apps
