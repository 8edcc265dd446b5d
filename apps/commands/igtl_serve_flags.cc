#include "apps/commands/igtl_serve_flags.h"

#include <CLI/CLI.hpp>

namespace echoservo::apps {

void AddIgtlServeFlags(CLI::App& cmd, IgtlServeFlags& f) {
  cmd.add_option("--igtl-serve", f.port,
                 "serve the detections over OpenIGTLink on this TCP port (3D Slicer's "
                 "OpenIGTLinkIF connects as a client; 0: any free port; docs/slicer.md)");
  cmd.add_flag("--igtl-volumes", f.volumes,
               "--igtl-serve: also send each volume as an IMAGE message (~5 MB each)");
  cmd.add_option("--igtl-bind", f.bind,
                 "--igtl-serve: the address to listen on (default 127.0.0.1; 0.0.0.0 serves "
                 "other hosts)");
}

}  // namespace echoservo::apps
