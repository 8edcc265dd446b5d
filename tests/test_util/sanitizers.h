// Whether this test binary was built with AddressSanitizer + UndefinedBehaviorSanitizer
// (cmake/Sanitizers.cmake defines ECHOSERVO_SANITIZED). That build runs 3-10x slower and
// checks memory and undefined behaviour, not statistics: a statistical case that repeats a
// code path another case already takes under the sanitizers runs in the Release suite only
// (CI time, docs/reliability.md "CI time").
#pragma once

#include <gtest/gtest.h>

namespace echoservo::testing {

#if defined(ECHOSERVO_SANITIZED)
inline constexpr bool kUnderSanitizers = true;
#else
inline constexpr bool kUnderSanitizers = false;
#endif

}  // namespace echoservo::testing

// Skips the current test in the sanitizer build, saying why; in Release it does nothing.
#define ECHOSERVO_RELEASE_SUITE_ONLY(why)                                              \
  do {                                                                                 \
    if (::echoservo::testing::kUnderSanitizers)                                        \
      GTEST_SKIP() << "run in the Release suite only under the sanitizers: " << (why); \
  } while (0)
