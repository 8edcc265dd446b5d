#include "apps/commands/em_connect_flags.h"

#include <CLI/CLI.hpp>

namespace echoservo::apps {

void AddEmConnectFlags(CLI::App& cmd, EmConnectFlags& flags) {
  cmd.add_option("--em-connect", flags.connect,
                 "HOST:PORT of a PLUS server's OpenIGTLink stream: one tool's TRANSFORM/TDATA "
                 "poses into RUN/em.csv, counts in RUN/em_stream.json");
  cmd.add_option("--em-tool", flags.tool,
                 "--em-connect: the tool to record (device or element name, e.g. "
                 "CatheterTipToTracker); default: the only tool streaming");
}

}  // namespace echoservo::apps
