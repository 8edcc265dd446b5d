#include "formats/run_metadata.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace echoservo::formats {
namespace {

constexpr double kRigidTolerance = 1e-3;

}  // namespace

std::string_view ToString(RunTimeBase base) {
  switch (base) {
    case RunTimeBase::kPipeline:
      return "pipeline";
    case RunTimeBase::kUnix:
      return "unix";
    case RunTimeBase::kRecording:
      return "recording";
    case RunTimeBase::kUnstated:
      break;
  }
  return "";
}

Eigen::Isometry3d ParseRigidTransform(std::string_view text, std::string_view where) {
  const std::string w(where);
  std::vector<double> v;
  std::size_t i = 0;
  while (i < text.size()) {
    if (text[i] == ',' || text[i] == ' ' || text[i] == '\t' || text[i] == '\n') {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < text.size() && text[j] != ',' && text[j] != ' ' && text[j] != '\t' &&
           text[j] != '\n')
      ++j;
    const std::string item(text.substr(i, j - i));
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (end != item.c_str() + item.size() || !std::isfinite(x))
      throw std::invalid_argument(w + ": '" + item + "' is not a finite number");
    v.push_back(x);
    i = j;
  }
  if (v.size() != 12 && v.size() != 16)
    throw std::invalid_argument(w +
                                ": expected 12 or 16 numbers (a 3x4 or 4x4 matrix, row-major, "
                                "mm), got " +
                                std::to_string(v.size()));
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  for (std::size_t k = 0; k < v.size(); ++k)
    m(static_cast<Eigen::Index>(k / 4), static_cast<Eigen::Index>(k % 4)) = v[k];
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > kRigidTolerance ||
      r.determinant() < 0.0 || (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 0.0)
    throw std::invalid_argument(w + ": not a rigid transform (a rotation and a translation)");
  Eigen::Isometry3d t;
  t.matrix() = m;
  return t;
}

std::string FormatRigidTransform(const Eigen::Isometry3d& t) {
  std::string out;
  char buf[32];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) {
      std::snprintf(buf, sizeof buf, "%.9g", t.matrix()(r, c));
      if (!out.empty()) out += ',';
      out += buf;
    }
  return out;
}

}  // namespace echoservo::formats
