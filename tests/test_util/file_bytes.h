// Whole files as bytes, for tests that corrupt a real file and read it back.
#pragma once

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace echoservo::testing {

inline std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

inline void Spit(const std::filesystem::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << s;
}

}  // namespace echoservo::testing
