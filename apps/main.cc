// echoservo: the command-line entry point. Subcommands live in apps/commands/*.cc.
#include "apps/cli.h"

int main(int argc, char** argv) { return echoservo::apps::RunCli(argc, argv); }
