// Counts the heap allocations made by the calling thread, for tests that check that a
// real-time cycle never allocates. alloc_counter.cc replaces the global operator new (all
// its forms) with one that increments a thread-local counter and then calls malloc; it is
// linked into control_rt_tests only, so no other test executable sees the replacement.
// Usage: `AllocationCount before = ThreadAllocations(); …; EXPECT_EQ(ThreadAllocations(),
// before);`. Counts are per thread, so other threads of the process (GoogleTest's, a
// publisher's) do not disturb a measurement; no errors are possible.
#pragma once

#include <cstdint>

namespace echoservo::testing {

// Number of operator new calls (any form) made so far by the calling thread.
std::uint64_t ThreadAllocations();

}  // namespace echoservo::testing
