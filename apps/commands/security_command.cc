// `echoservo security init DIR [--participants tracker,servo,operator,monitor] [--days N]
// [--max-domain N] [--force]`: a test CA, per-participant identities and the signed
// governance and permissions documents for DDS-Security (link/security.h), which `track`,
// `servo`, `command` and `demo` load with --secure DIR.
// `echoservo security check DIR --participant NAME`: checks one participant's credentials
// as Fast DDS will and prints the dds.sec.* participant properties they give.
// Both take --json. Errors name the file and why.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "apps/commands/live_commands.h"
#include "link/security.h"

namespace echoservo::apps {
namespace {

struct SecurityArgs {
  std::string dir;
  link::SecurityInitOptions init;
  std::string participant;
  bool json = false;
};

void RunInit(const SecurityArgs& a) {
  const std::vector<std::string> files = link::InitSecurityDir(a.dir, a.init);
  if (a.json) {
    std::cout << nlohmann::json{{"dir", a.dir},
                                {"participants", a.init.participants},
                                {"files", files}}
                     .dump(2)
              << "\n";
    return;
  }
  for (const std::string& f : files) std::printf("%s\n", f.c_str());
  std::printf(
      "security: CA, %zu identities, governance and permissions in %s (private keys mode 0600); "
      "use --secure %s\n",
      a.init.participants.size(), a.dir.c_str(), a.dir.c_str());
}

void RunCheck(const SecurityArgs& a) {
  const auto properties = link::SecurityProperties(link::CheckSecurityDir(a.dir, a.participant));
  if (a.json) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [name, value] : properties) j[name] = value;
    std::cout
        << nlohmann::json{{"participant", a.participant}, {"ok", true}, {"properties", j}}.dump(2)
        << "\n";
    return;
  }
  for (const auto& [name, value] : properties)
    std::printf("%s = %s\n", name.c_str(), value.c_str());
  std::printf("security: %s's credentials in %s check out\n", a.participant.c_str(), a.dir.c_str());
}

}  // namespace

void AddSecurityCommand(CLI::App& app) {
  auto a = std::make_shared<SecurityArgs>();
  CLI::App* sec = app.add_subcommand(
      "security", "DDS-Security credentials: a test CA, identities, governance, permissions");
  sec->require_subcommand(1);
  CLI::App* init = sec->add_subcommand(
      "init",
      "write a test CA, per-participant keys and certificates, signed governance "
      "and permissions into DIR");
  init->add_option("dir", a->dir, "credential directory (created)")->required();
  init->add_option("--participants", a->init.participants,
                   "participants, comma-separated (roles: tracker, servo, operator, monitor; "
                   "default: all four)")
      ->delimiter(',');
  init->add_option("--days", a->init.validity_days,
                   "validity of the certificates and permissions, days")
      ->check(CLI::Range(1, 3650));
  init->add_option("--max-domain", a->init.max_domain_id,
                   "governance and permissions cover DDS domains 0..N")
      ->check(CLI::Range(0, 232));
  init->add_flag("--force", a->init.overwrite, "replace credentials already in DIR");
  init->add_flag("--json", a->json, "print the files written as JSON");
  init->callback([a] { RunInit(*a); });
  CLI::App* check =
      sec->add_subcommand("check", "check one participant's credentials in DIR as Fast DDS will");
  check->add_option("dir", a->dir, "credential directory")->required();
  check->add_option("--participant", a->participant, "the participant (identity) to check")
      ->required();
  check->add_flag("--json", a->json, "print the outcome and the dds.sec.* properties as JSON");
  check->callback([a] { RunCheck(*a); });
}

}  // namespace echoservo::apps
