// Registration of `echoservo report RUN`: the accuracy report of a tracking run against an
// EM-tracker log (estimation/accuracy_report.h).
#pragma once

namespace CLI {
class App;
}

namespace echoservo::apps {

void AddReportCommand(CLI::App& app);

}  // namespace echoservo::apps
