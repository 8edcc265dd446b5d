// `lab compare|diagnose` on a target-motion trace (a CSV file instead of a dataset
// folder): the motion lab (lab/motion_diagnosis.h).
#pragma once

#include <string>

namespace echoservo::apps {

struct MotionLabFlags {
  std::string trace;
  std::string model;  // "seed" (the lab's default) means heartbeat:2
  std::string column;
  bool json = false;
};

void RunMotionCompare(const MotionLabFlags& flags);
void RunMotionDiagnose(const MotionLabFlags& flags);

}  // namespace echoservo::apps
