// Whether an X server can be reached, for VTK rendering (which on this platform has neither
// OSMesa nor EGL and aborts the process when it cannot open a display). Kept apart from
// anything including Eigen: X11 headers define `Success`, which Eigen refuses.
#pragma once

#include <string>

namespace echoservo::imaging {

// True when $DISPLAY is set and that display opens; otherwise false, and `why` (if given)
// says what is missing ("DISPLAY is not set", "cannot open X display ':1'").
bool XDisplayAvailable(std::string* why = nullptr);

}  // namespace echoservo::imaging
