#include "imaging/render/x_display.h"

#include <X11/Xlib.h>

#include <cstdlib>

namespace echoservo::imaging {

bool XDisplayAvailable(std::string* why) {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') {
    if (why != nullptr) *why = "DISPLAY is not set";
    return false;
  }
  Display* x = XOpenDisplay(display);
  if (x == nullptr) {
    if (why != nullptr) *why = std::string("cannot open X display '") + display + "'";
    return false;
  }
  XCloseDisplay(x);
  return true;
}

}  // namespace echoservo::imaging
