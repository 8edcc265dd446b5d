#include "tune/interrupt.h"

namespace echoservo::tune {
namespace {

volatile std::sig_atomic_t g_interrupt_signal = 0;
volatile std::sig_atomic_t g_interrupt_count = 0;

extern "C" void TuneOnInterrupt(int sig) {
  g_interrupt_signal = sig;
  g_interrupt_count = g_interrupt_count + 1;
}

}  // namespace

InterruptGuard::InterruptGuard() {
  g_interrupt_signal = 0;
  g_interrupt_count = 0;
  struct sigaction sa {};
  sa.sa_handler = TuneOnInterrupt;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a wait is cut short
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}

InterruptGuard::~InterruptGuard() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

int InterruptGuard::signal() { return g_interrupt_signal; }
int InterruptGuard::count() { return g_interrupt_count; }

}  // namespace echoservo::tune
