// The cycle-timing calls made inside the 1 kHz cycle (LatencyHistogram::Add,
// CycleTimer::Woke/Finished) never allocate: counted with the replaced operator new of
// tests/control/alloc_counter.cc over many cycles that cover every branch (in range,
// overflow, negative, overruns). The counter itself is checked to count.
#include <gtest/gtest.h>

#include <cstdint>
#include <new>

#include "control/cycle_timing.h"
#include "tests/control/alloc_counter.h"

namespace echoservo::control {
namespace {

using testing::ThreadAllocations;

TEST(AllocCounterTest, CountsThisThreadsAllocations) {
  const std::uint64_t before = ThreadAllocations();
  void* p = ::operator new(64);  // a direct call: the compiler may not elide it
  ::operator delete(p);
  EXPECT_EQ(ThreadAllocations(), before + 1);
}

TEST(CycleTimingAllocTest, AddWokeFinishedDoNotAllocate) {
  LatencyHistogram histogram(1e-6, 1e-3);
  CycleTimer timer(1e-3);
  const std::uint64_t before = ThreadAllocations();
  for (int k = 0; k < 5000; ++k) {
    const double deadline = k * 1e-3;
    const double late_s = (k % 97 == 0) ? 0.08 : (k % 13) * 1e-6 - 2e-6;  // overflow, < 0
    histogram.Add(late_s);
    timer.Woke(deadline, deadline + late_s);
    timer.Finished(deadline + ((k % 50 < 3) ? 1.4e-3 : 0.4e-3));  // runs of overruns
  }
  EXPECT_EQ(ThreadAllocations(), before);
  EXPECT_EQ(timer.Report().cycles, 5000u);
  EXPECT_GT(timer.Report().overruns, 0u);
  EXPECT_GT(histogram.overflow(), 0u);
}

}  // namespace
}  // namespace echoservo::control
