// The live pipeline's clock: seconds on the host's steady clock since the run's start
// (volume acquisition, delivery and servo cycles are scheduled on it), and its fixed offset
// to the DDS link's shared clock (link/clock.h: s since the UNIX epoch), taken once at
// construction so that a stamp converts both ways without drift inside one run.
#pragma once

#include <chrono>

#include "link/clock.h"

namespace echoservo::live {

class PipelineClock {
 public:
  using Steady = std::chrono::steady_clock;
  // Time 0 is `lead_s` from now (room to start the threads before the first deadline).
  explicit PipelineClock(double lead_s = 0.05)
      : start_(Steady::now() +
               std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(lead_s))),
        link_offset_s_(link::NowS() - Now()) {}

  double Now() const { return std::chrono::duration<double>(Steady::now() - start_).count(); }
  Steady::time_point At(double t_s) const {
    return start_ +
           std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(t_s));
  }
  // link time = pipeline time + link_offset_s().
  double link_offset_s() const { return link_offset_s_; }

 private:
  Steady::time_point start_;
  double link_offset_s_;
};

}  // namespace echoservo::live
