#include "apps/cli.h"

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "apps/commands/bench_commands.h"
#include "apps/commands/calibrate_command.h"
#include "apps/commands/imaging_commands.h"
#include "apps/commands/lab_command.h"
#include "apps/commands/live_commands.h"
#include "apps/commands/motion_commands.h"
#include "apps/commands/report_command.h"
#include "apps/commands/tune_commands.h"

namespace echoservo::apps {
namespace {

// ECHOSERVO_PARSE_ONLY=1: parse and validate the arguments as usual (CLI11's checks
// included) but run no command: once the whole command line has been parsed and checked,
// before any command's callback, print the selected command's path and stop.
// ECHOSERVO_PARSE_ONLY=batch does that for one command line per line of stdin (arguments
// separated by tabs, without the program name), printing "--- rc N" on stdout and stderr
// after each, in one process. tests/apps/docs_commands_test.py checks the documentation's
// command lines this way (docs/reliability.md).
struct ParsedOnly {};

std::string SelectedPath(const CLI::App& app) {
  std::string path = "echoservo";
  for (const CLI::App* a = &app; !a->get_subcommands().empty(); a = a->get_subcommands().front())
    path += " " + a->get_subcommands().front()->get_name();
  return path;
}

int RunOnce(int argc, const char* const* argv, bool parse_only) {
  CLI::App app{
      "echoservo: ultrasound-guided motion-compensation catheter servo, simulator and model lab"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "echoservo 0.1.0");
  AddSimCommands(app);
  AddLabCommands(app);
  AddPredictCommand(app);
  AddInfoCommand(app);
  AddDetectCommand(app);
  AddRenderCommand(app);
  AddScannerCommand(app);
  AddIngestCommand(app);
  AddReplayCommand(app);
  AddReconstructCommand(app);
  AddBenchCommands(app);
  AddLiveCommands(app);
  AddReportCommand(app);
  AddCalibrateCommand(app);
  AddTuneCommand(app);
  // The root's parse-complete callback runs after all parsing and checks and before the
  // subcommands' callbacks (CLI::App::run_callback).
  if (parse_only) app.parse_complete_callback([] { throw ParsedOnly{}; });
  try {
    app.parse(argc, argv);
  } catch (const ParsedOnly&) {
    std::cout << "parse only: " << SelectedPath(app) << "\n";
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const std::exception& e) {
    std::cerr << "echoservo: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

int ParseBatch() {
  std::string line;
  while (std::getline(std::cin, line)) {
    std::vector<std::string> args{"echoservo"};
    if (!line.empty()) {
      std::size_t begin = 0;
      for (std::size_t tab; (tab = line.find('\t', begin)) != std::string::npos; begin = tab + 1)
        args.push_back(line.substr(begin, tab - begin));
      args.push_back(line.substr(begin));
    }
    std::vector<const char*> argv;
    for (const std::string& a : args) argv.push_back(a.c_str());
    const int rc = RunOnce(static_cast<int>(argv.size()), argv.data(), true);
    std::cout << "--- rc " << rc << std::endl;
    std::cerr << "--- rc " << rc << std::endl;
  }
  return 0;
}

// Redirects a standard stream into a string buffer for its lifetime.
class Redirect {
 public:
  explicit Redirect(std::ostream& stream) : stream_(stream), old_(stream.rdbuf(buffer_.rdbuf())) {}
  ~Redirect() { stream_.rdbuf(old_); }
  Redirect(const Redirect&) = delete;
  Redirect& operator=(const Redirect&) = delete;
  std::string str() const { return buffer_.str(); }

 private:
  std::ostream& stream_;
  std::ostringstream buffer_;
  std::streambuf* old_;
};

std::mutex program_mutex;
std::string program_path;  // empty: /proc/self/exe

}  // namespace

void SetProgramPath(const std::string& path) {
  std::lock_guard<std::mutex> lock(program_mutex);
  program_path = path;
}

std::string ProgramPath() {
  {
    std::lock_guard<std::mutex> lock(program_mutex);
    if (!program_path.empty()) return program_path;
  }
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec)
    throw std::runtime_error("cannot find this program (/proc/self/exe: " + ec.message() + ")");
  return self.string();
}

int RunCommand(const std::vector<std::string>& args, std::string& out, std::string& err) {
  std::vector<const char*> argv{"echoservo"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  int rc = 0;
  {
    Redirect cout_to(std::cout), cerr_to(std::cerr);
    rc = RunOnce(static_cast<int>(argv.size()), argv.data(), false);
    out = cout_to.str();
    err = cerr_to.str();
  }
  return rc;
}

int RunCli(int argc, char** argv) {
  const char* parse_only = std::getenv("ECHOSERVO_PARSE_ONLY");
  const std::string_view mode = parse_only != nullptr ? parse_only : "";
  if (mode == "batch") return ParseBatch();
  return RunOnce(argc, argv, mode == "1");
}

}  // namespace echoservo::apps
