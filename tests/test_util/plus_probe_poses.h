// The probe's poses in a PLUS tracker sequence (.igs.mha), read line by line with nothing of
// echoservo's PLUS reader: the independent view the temporal-calibration tests compare
// against. Per frame: Timestamp (s), the ProbeToTrackerTransform's translation (mm) and its
// status text ("OK", "INVALID", …; empty when the file has none).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

namespace echoservo::testing {

struct RawProbePose {
  double t_s = 0.0;
  Eigen::Vector3d p_mm = Eigen::Vector3d::Zero();
  std::string status;
};

inline std::map<int, RawProbePose> ScanProbePoses(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::map<int, RawProbePose> poses;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("Seq_Frame", 0) != 0) continue;
    const auto us = line.find('_', 9);
    const int frame = std::stoi(line.substr(9, us - 9));
    const auto eq = line.find(" = ");
    const std::string key = line.substr(us + 1, eq - us - 1);
    std::istringstream value(line.substr(eq + 3));
    if (key == "Timestamp") {
      value >> poses[frame].t_s;
    } else if (key == "ProbeToTrackerTransformStatus") {
      value >> poses[frame].status;
    } else if (key == "ProbeToTrackerTransform") {
      double m[16];
      for (double& v : m) value >> v;
      poses[frame].p_mm = Eigen::Vector3d(m[3], m[7], m[11]);
    }
  }
  return poses;
}

}  // namespace echoservo::testing
