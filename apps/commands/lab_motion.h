// `lab compare|diagnose` on a target-motion trace (a CSV file instead of a dataset
// folder): the motion lab (lab/motion_diagnosis.h). Text or JSON on stdout; `diagnose`
// writes a proposed motion-term file into `propose_dir` (empty: "<trace stem>_proposal"
// beside the trace) when the verdict is unexplained.
#pragma once

#include <string>

namespace echoservo::apps {

struct MotionLabFlags {
  std::string trace;
  std::string model;  // a motion model, heartbeat:N[+...]; empty means heartbeat:2
  std::string column;
  bool json = false;
};

void RunMotionCompare(const MotionLabFlags& flags);
void RunMotionDiagnose(const MotionLabFlags& flags, const std::string& propose_dir = "");

}  // namespace echoservo::apps
