// DDS-Security credentials for the link: a test certificate authority, one identity per
// participant role (certificate and private key), a governance document and per-role
// permissions signed by the CA, and the Fast DDS participant properties (dds.sec.*) that
// load them (ParticipantOptions::properties). Builtin plugins: PKI-DH, Access-Permissions,
// AES-GCM-GMAC; OpenSSL only in security.cc, no crypto of our own.
//
// Keys ECDSA P-256; validity from one day before creation (UTC) for validity_days; paths are
// file names, URIs file://. Errors: bad options and bad credential directories throw
// std::invalid_argument naming the file and why; a file that cannot be written or an
// OpenSSL failure throws std::runtime_error.
// Details: docs/dds.md#security
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace echoservo::link {

// The roles, and what each may do on the three topics (rt/echoservo/...):
//   tracker   publishes target_estimate; subscribes to catheter_state
//   servo     publishes catheter_state;  subscribes to target_estimate, servo_command
//   operator  publishes servo_command;   subscribes to catheter_state
//   monitor   publishes nothing;         subscribes to all three
// A participant's name in a credential directory is its role.
std::vector<std::string> SecurityRoles();

struct SecurityInitOptions {
  std::vector<std::string> participants = {"tracker", "servo", "operator", "monitor"};
  int validity_days = 365;  // certificates and permissions, 1..3650
  int max_domain_id = 232;  // governance and permissions cover domains 0..max_domain_id
  bool overwrite = false;   // replace credentials already in the directory
  std::string organization = "echoservo";  // O= of every subject

  // Throws std::invalid_argument naming the option: an unknown or repeated role, no
  // participants, days or domain out of range.
  void Validate() const;
};

// Writes into `dir` (created if needed; private keys mode 0600):
//   ca/ca_cert.pem, ca/ca_key.pem          the self-signed CA (identity and permissions CA)
//   governance.xml, governance.p7s         the domain's governance and its S/MIME signature
//   NAME/cert.pem, NAME/key.pem            each participant's identity, signed by the CA
//   NAME/permissions.xml, .p7s             its grant (subject = its certificate's subject)
// Returns the files written. Throws std::invalid_argument when `dir` already holds
// credentials and `overwrite` is off.
std::vector<std::string> InitSecurityDir(const std::string& dir,
                                         const SecurityInitOptions& options = {});

// Signs the XML file `document` with the CA (`ca_cert`, `ca_key`: PEM files) as S/MIME
// into `signed_out`: to re-sign an edited governance or permissions document. Throws
// std::invalid_argument naming an unreadable or unparseable input file.
void SignSecurityDocument(const std::string& document, const std::string& ca_cert,
                          const std::string& ca_key, const std::string& signed_out);

// The absolute paths of one participant's credentials.
struct SecurityFiles {
  std::string identity_ca;     // verifies remote identities
  std::string permissions_ca;  // verifies governance and permissions (local and remote)
  std::string certificate;
  std::string private_key;
  std::string governance;   // S/MIME-signed
  std::string permissions;  // S/MIME-signed
};

// Finds `participant`'s credentials in `dir` and checks them as Fast DDS will: each file
// present and parseable, the certificate issued by the CA and matching the key, the
// governance and permissions signatures verifying against the CA, and the permissions
// granting this certificate's subject. Throws std::invalid_argument naming the file.
SecurityFiles CheckSecurityDir(const std::string& dir, const std::string& participant);

// The dds.sec.* participant properties for `files` (file:// URIs), without checks (a test
// builds invalid sets with it).
std::vector<std::pair<std::string, std::string>> SecurityProperties(const SecurityFiles& files);

}  // namespace echoservo::link
