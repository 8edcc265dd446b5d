// The ROS 2 interface package (msg/echoservo_msgs/msg/*.msg) and the IDL that echoservo
// compiles (*.idl beside them) must describe the same CDR layout: the same fields, types,
// bounds and constants in the same order. Both files are parsed and their declarations
// compared in one canonical form ("float64[<=16] motion_cos_mm", "uint8 MODE_IDLE=0").
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

std::string Read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string StripComments(const std::string& text, const std::string& marker) {
  std::stringstream in(text), out;
  for (std::string line; std::getline(in, line);) out << line.substr(0, line.find(marker)) << "\n";
  return out.str();
}

// IDL → canonical declarations, in file order.
std::vector<std::string> IdlDeclarations(const std::string& path) {
  static const std::map<std::string, std::string> kTypes = {
      {"double", "float64"}, {"uint8", "uint8"}, {"uint32", "uint32"}, {"uint64", "uint64"}};
  const std::string text = StripComments(Read(path), "//");
  const std::regex decl(
      R"(const\s+(\w+)\s+(\w+)\s*=\s*(\w+)\s*;|sequence<\s*(\w+)\s*,\s*(\d+)\s*>\s+(\w+)\s*;|(\w+)\s+(\w+)\s*(\[(\d+)\])?\s*;)");
  std::vector<std::string> out;
  for (std::sregex_iterator it(text.begin(), text.end(), decl), end; it != end; ++it) {
    const std::smatch& m = *it;
    std::ostringstream d;  // (streams: GCC 12 -O3 warns falsely on string concatenation)
    if (m[1].matched) {
      d << kTypes.at(m[1]) << ' ' << m[2] << '=' << m[3];
    } else if (m[4].matched) {
      d << kTypes.at(m[4]) << "[<=" << m[5] << "] " << m[6];
    } else {
      d << kTypes.at(m[7]);
      if (m[9].matched) d << '[' << m[10] << ']';
      d << ' ' << m[8];
    }
    out.push_back(d.str());
  }
  return out;
}

// .msg → canonical declarations, in file order.
std::vector<std::string> MsgDeclarations(const std::string& path) {
  const std::string text = StripComments(Read(path), "#");
  const std::regex decl(R"(^\s*(\w+(\[(<=)?\d+\])?)\s+(\w+)\s*(=\s*(\w+))?\s*$)");
  std::vector<std::string> out;
  std::stringstream in(text);
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    EXPECT_TRUE(std::regex_match(line, m, decl)) << path << ": " << line;
    if (m.empty()) continue;
    std::ostringstream d;
    d << m[1] << ' ' << m[4];
    if (m[5].matched) d << '=' << m[6];
    out.push_back(d.str());
  }
  return out;
}

class Ros2MsgTest : public ::testing::TestWithParam<std::string> {};

TEST_P(Ros2MsgTest, MsgAndIdlDeclareTheSameLayout) {
  const std::string base = std::string(ECHOSERVO_MSG_DIR) + "/" + GetParam();
  const std::vector<std::string> idl = IdlDeclarations(base + ".idl");
  const std::vector<std::string> msg = MsgDeclarations(base + ".msg");
  ASSERT_FALSE(idl.empty());
  EXPECT_EQ(msg, idl);
}

INSTANTIATE_TEST_SUITE_P(Types, Ros2MsgTest,
                         ::testing::Values("TargetEstimate", "CatheterState", "ServoCommand"));

}  // namespace
