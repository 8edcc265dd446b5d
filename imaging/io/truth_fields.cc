#include "imaging/io/truth_fields.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace echoservo::imaging {
namespace {

// Built by appending: GCC 12 reports a false -Wrestrict on chained literal + string.
[[noreturn]] void Fail(const std::string& field, const std::string& why) {
  std::string msg = "ground truth: field '";
  msg += field;
  msg += "' ";
  msg += why;
  throw std::invalid_argument(msg);
}

std::string Flag(bool on) { return std::string(1, on ? '1' : '0'); }

std::string Vec(const Eigen::Vector3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g", v.x(), v.y(), v.z());
  return buf;
}

Eigen::Vector3d ParseVec(const std::map<std::string, std::string>& f, const std::string& name) {
  const auto it = f.find(name);
  if (it == f.end()) Fail(name, "is missing");
  Eigen::Vector3d v;
  const char* p = it->second.data();
  const char* end = p + it->second.size();
  for (int i = 0; i < 3; ++i) {
    while (p < end && *p == ' ') ++p;
    const auto [next, ec] = std::from_chars(p, end, v[i]);
    if (ec != std::errc() || !std::isfinite(v[i])) {
      Fail(name, "is not 3 finite numbers");
    }
    p = next;
  }
  while (p < end && *p == ' ') ++p;
  if (p != end) Fail(name, "has extra text after 3 numbers");
  return v;
}

bool ParseFlag(const std::map<std::string, std::string>& f, const std::string& name) {
  const auto it = f.find(name);
  if (it == f.end() || (it->second != "0" && it->second != "1")) {
    Fail(name, "must be 0 or 1");
  }
  return it->second == "1";
}

}  // namespace

void SetTruthFields(const FrameGroundTruth& t, std::map<std::string, std::string>& f) {
  f["CatheterVisible"] = Flag(t.catheter_visible);
  f["CatheterAxisPoint"] = Vec(t.axis_point_mm);
  f["CatheterAxisDirection"] = Vec(t.axis_direction);
  f["CatheterTip"] = Vec(t.tip_mm);
  f["TargetVisible"] = Flag(t.target_visible);
  f["Target"] = Vec(t.target_mm);
  if (t.acquisition_s) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.9f", *t.acquisition_s);
    f["AcquisitionTime"] = buf;
  }
}

std::optional<FrameGroundTruth> TruthFromFields(const std::map<std::string, std::string>& f) {
  if (f.find("CatheterVisible") == f.end()) return std::nullopt;
  FrameGroundTruth t;
  t.catheter_visible = ParseFlag(f, "CatheterVisible");
  t.axis_point_mm = ParseVec(f, "CatheterAxisPoint");
  t.axis_direction = ParseVec(f, "CatheterAxisDirection");
  t.tip_mm = ParseVec(f, "CatheterTip");
  t.target_visible = ParseFlag(f, "TargetVisible");
  t.target_mm = ParseVec(f, "Target");
  if (const auto it = f.find("AcquisitionTime"); it != f.end()) {
    double a = 0.0;
    const char* p = it->second.data();
    const char* end = p + it->second.size();
    const auto [next, ec] = std::from_chars(p, end, a);
    if (ec != std::errc() || next != end || !std::isfinite(a)) {
      Fail("AcquisitionTime", "is not a finite number");
    }
    t.acquisition_s = a;
  }
  if (std::abs(t.axis_direction.norm() - 1.0) > 1e-6) {
    Fail("CatheterAxisDirection", "is not a unit vector");
  }
  return t;
}

}  // namespace echoservo::imaging
