// Test helpers for the project's error policy: user mistakes throw
// std::invalid_argument whose message names the offending field.
#pragma once

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace echoservo::testing {

// Runs `f` and returns the std::invalid_argument message (fails if nothing, or
// something else, is thrown).
template <class F>
std::string InvalidArgumentMessage(F&& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (...) {
    ADD_FAILURE() << "threw something other than std::invalid_argument";
    return {};
  }
  ADD_FAILURE() << "expected std::invalid_argument";
  return {};
}

inline void ExpectContains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << text << "' lacks '" << part << "'";
}

}  // namespace echoservo::testing
