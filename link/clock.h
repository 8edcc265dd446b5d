// The shared clock of the DDS link: seconds since the UNIX epoch from
// std::chrono::system_clock (CLOCK_REALTIME), as a double (resolution ~0.2 µs today).
//
// Every timestamp on the link (acquisition, publication, state and command stamps) is on
// this clock. It is the clock the OpenIGTLink scanner stream already stamps volumes with,
// it is shared by all processes on one host, and it is the one PTP/NTP discipline, so
// two hosts can compare stamps once synchronised (chrony/ptp4l to well under the
// staleness limit). A monotonic clock (steady_clock) could not be compared across hosts
// at all. Across hosts without synchronisation, relax the stale/future checks
// (ValidationLimits in link/sample_validation.h). docs/dds.md has the details.
#pragma once

#include <chrono>

namespace echoservo::link {

inline double NowS() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace echoservo::link
