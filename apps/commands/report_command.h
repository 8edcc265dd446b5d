// Registration of `echoservo report RUN`: the accuracy report of a tracking run against an
// EM-tracker log (report/accuracy_report.h).
#pragma once

#include <string>

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddReportCommand(CLI::App& app);

// The report of a RUN directory with its own em.csv and calibration, from `from_s` on (NaN:
// the scored window, report/scored_window.h, as `report RUN` gives by default), written to
// `html_path`; returns the tip-to-target RMS (mm). Throws like `report`.
double WriteRunReport(const std::string& run_dir, const std::string& html_path, double from_s);

}  // namespace echoservo::apps
