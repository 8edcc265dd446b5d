// echoservo: the command-line entry point. Subcommands live in apps/commands/*.cc.
#include <glog/logging.h>

#include "apps/cli.h"

int main(int argc, char** argv) {
  // Ceres logs through glog; its warnings (e.g. a rank-deficient covariance, which the
  // lab reports as an undefined standard deviation) are not for the user's terminal.
  FLAGS_minloglevel = google::GLOG_ERROR;
  google::InitGoogleLogging(argv[0]);
  return echoservo::apps::RunCli(argc, argv);
}
