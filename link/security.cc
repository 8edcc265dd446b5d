#include "link/security.h"

#include <fcntl.h>
#include <openssl/bio.h>
#include <openssl/bn.h>
#include <openssl/ec.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/objects.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "link/samples.h"

namespace echoservo::link {
namespace {

namespace fs = std::filesystem;

template <class T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using Bio = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;
using Key = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using KeyCtx = std::unique_ptr<EVP_PKEY_CTX, Deleter<EVP_PKEY_CTX, EVP_PKEY_CTX_free>>;
using Cert = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using Store = std::unique_ptr<X509_STORE, Deleter<X509_STORE, X509_STORE_free>>;
using StoreCtx = std::unique_ptr<X509_STORE_CTX, Deleter<X509_STORE_CTX, X509_STORE_CTX_free>>;
using Pkcs7 = std::unique_ptr<PKCS7, Deleter<PKCS7, PKCS7_free>>;
using Extension = std::unique_ptr<X509_EXTENSION, Deleter<X509_EXTENSION, X509_EXTENSION_free>>;

constexpr std::string_view kCaCert = "ca/ca_cert.pem";
constexpr std::string_view kCaKey = "ca/ca_key.pem";
constexpr std::string_view kGovernanceXml = "governance.xml";
constexpr std::string_view kGovernance = "governance.p7s";
constexpr std::string_view kCertificate = "cert.pem";
constexpr std::string_view kPrivateKey = "key.pem";
constexpr std::string_view kPermissionsXml = "permissions.xml";
constexpr std::string_view kPermissions = "permissions.p7s";
constexpr long kDayS = 86400;

struct Role {
  std::string_view name;
  std::vector<std::string_view> publish, subscribe;
};

const std::vector<Role>& Roles() {
  static const std::vector<Role> roles = {
      {"tracker", {kTargetTopic}, {kStateTopic}},
      {"servo", {kStateTopic}, {kTargetTopic, kCommandTopic}},
      {"operator", {kCommandTopic}, {kStateTopic}},
      {"monitor", {}, {kTargetTopic, kStateTopic, kCommandTopic}},
  };
  return roles;
}

// The OpenSSL error queue as text (and emptied).
std::string OpenSslErrors() {
  std::string out;
  while (const unsigned long e = ERR_get_error()) {
    char buf[256];
    ERR_error_string_n(e, buf, sizeof buf);
    if (!out.empty()) out += "; ";
    out += buf;
  }
  return out.empty() ? "no OpenSSL detail" : out;
}

[[noreturn]] void Fail(const std::string& what) {
  throw std::runtime_error("security: " + what + " (" + OpenSslErrors() + ")");
}

std::string BioText(BIO* b) {
  char* data = nullptr;
  const long n = BIO_get_mem_data(b, &data);
  return n > 0 ? std::string(data, static_cast<std::size_t>(n)) : std::string();
}

// Writes `text` to `path`; secrets are created mode 0600 (never readable by others).
void WriteFile(const fs::path& path, const std::string& text, bool secret) {
  const int fd =
      ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, secret ? 0600 : 0644);
  if (fd < 0)
    throw std::runtime_error("security: cannot write " + path.string() + ": " +
                             std::strerror(errno));
  if (secret) ::fchmod(fd, 0600);  // an existing file keeps its mode through O_TRUNC
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      throw std::runtime_error("security: cannot write " + path.string() + ": " + why);
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0)
    throw std::runtime_error("security: cannot write " + path.string() + ": " +
                             std::strerror(errno));
}

Key NewKey() {
  KeyCtx ctx(EVP_PKEY_CTX_new_id(EVP_PKEY_EC, nullptr));
  EVP_PKEY* key = nullptr;
  if (!ctx || EVP_PKEY_keygen_init(ctx.get()) != 1 ||
      EVP_PKEY_CTX_set_ec_paramgen_curve_nid(ctx.get(), NID_X9_62_prime256v1) != 1 ||
      EVP_PKEY_keygen(ctx.get(), &key) != 1) {
    Fail("cannot generate an ECDSA P-256 key");
  }
  return Key(key);
}

void AddExtension(X509* cert, X509V3_CTX* ctx, int nid, const char* value) {
  Extension ext(X509V3_EXT_conf_nid(nullptr, ctx, nid, value));
  if (!ext || X509_add_ext(cert, ext.get(), -1) != 1)
    Fail(std::string("cannot add extension ") + value);
}

// A certificate for `key` with subject O=organization, CN=common_name, signed by
// `issuer` (null: self-signed CA).
Cert NewCertificate(const std::string& organization, const std::string& common_name, EVP_PKEY* key,
                    X509* issuer, EVP_PKEY* issuer_key, int days) {
  Cert cert(X509_new());
  if (!cert || X509_set_version(cert.get(), 2) != 1) Fail("cannot create a certificate");
  unsigned char serial[16];
  if (RAND_bytes(serial, sizeof serial) != 1) Fail("no random serial number");
  serial[0] &= 0x7f;  // positive
  std::unique_ptr<BIGNUM, Deleter<BIGNUM, BN_free>> bn(BN_bin2bn(serial, sizeof serial, nullptr));
  if (!bn || BN_to_ASN1_INTEGER(bn.get(), X509_get_serialNumber(cert.get())) == nullptr)
    Fail("cannot set the serial");
  X509_gmtime_adj(X509_getm_notBefore(cert.get()), -kDayS);
  X509_gmtime_adj(X509_getm_notAfter(cert.get()), static_cast<long>(days) * kDayS);
  X509_NAME* name = X509_get_subject_name(cert.get());
  const auto add = [&](const char* field, const std::string& value) {
    if (X509_NAME_add_entry_by_txt(name, field, MBSTRING_UTF8,
                                   reinterpret_cast<const unsigned char*>(value.c_str()), -1, -1,
                                   0) != 1)
      Fail("cannot set the subject " + std::string(field) + "=" + value);
  };
  add("O", organization);
  add("CN", common_name);
  const bool ca = issuer == nullptr;
  if (X509_set_issuer_name(cert.get(), ca ? name : X509_get_subject_name(issuer)) != 1 ||
      X509_set_pubkey(cert.get(), key) != 1)
    Fail("cannot set the issuer or public key");
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, ca ? cert.get() : issuer, cert.get(), nullptr, nullptr, 0);
  AddExtension(cert.get(), &ctx, NID_basic_constraints,
               ca ? "critical,CA:TRUE" : "critical,CA:FALSE");
  // The CA also signs the governance and permissions documents (S/MIME): digitalSignature.
  AddExtension(cert.get(), &ctx, NID_key_usage,
               ca ? "critical,digitalSignature,keyCertSign,cRLSign"
                  : "critical,digitalSignature,keyAgreement");
  AddExtension(cert.get(), &ctx, NID_subject_key_identifier, "hash");
  if (!ca) AddExtension(cert.get(), &ctx, NID_authority_key_identifier, "keyid:always");
  if (X509_sign(cert.get(), ca ? key : issuer_key, EVP_sha256()) == 0)
    Fail("cannot sign the certificate of " + common_name);
  return cert;
}

std::string CertPem(X509* cert) {
  Bio b(BIO_new(BIO_s_mem()));
  if (!b || PEM_write_bio_X509(b.get(), cert) != 1) Fail("cannot encode a certificate");
  return BioText(b.get());
}

std::string KeyPem(EVP_PKEY* key) {
  Bio b(BIO_new(BIO_s_mem()));
  if (!b || PEM_write_bio_PrivateKey(b.get(), key, nullptr, nullptr, 0, nullptr, nullptr) != 1)
    Fail("cannot encode a private key");
  return BioText(b.get());
}

// The subject as Fast DDS compares it with a grant's subject_name (RFC 2253).
std::string SubjectRfc2253(X509* cert) {
  Bio b(BIO_new(BIO_s_mem()));
  if (!b || X509_NAME_print_ex(b.get(), X509_get_subject_name(cert), 0,
                               XN_FLAG_RFC2253 & ~ASN1_STRFLGS_ESC_MSB) < 0)
    Fail("cannot print a subject name");
  return BioText(b.get());
}

// `text` signed by the CA as S/MIME (multipart/signed, text/plain content): what
// `openssl smime -sign -text` writes and Fast DDS verifies with PKCS7_TEXT.
std::string SignSmime(const std::string& text, X509* ca, EVP_PKEY* ca_key) {
  constexpr int kFlags = PKCS7_DETACHED | PKCS7_TEXT | PKCS7_STREAM;
  Bio in(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
  Pkcs7 p7(in ? PKCS7_sign(ca, ca_key, nullptr, in.get(), kFlags) : nullptr);
  Bio out(BIO_new(BIO_s_mem()));
  if (!p7 || !out || SMIME_write_PKCS7(out.get(), p7.get(), in.get(), kFlags) != 1)
    Fail("cannot sign a document");
  return BioText(out.get());
}

std::string XmlTime(std::time_t t) {
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  return buf;
}

std::string DomainsXml(int max_domain_id, const char* indent) {
  std::ostringstream x;
  x << indent << "<domains>\n"
    << indent << "  <id_range><min>0</min><max>" << max_domain_id << "</max></id_range>\n"
    << indent << "</domains>\n";
  return x.str();
}

// Join access control, and the echoservo topics with discovery, liveliness, read and
// write access control, metadata (submessages) and data (payloads) encrypted; RTPS
// messages as a whole encrypted too. Other topics: open, as DDS-Security requires a rule.
std::string GovernanceXml(int max_domain_id) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
       "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
       "xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
       "omg_shared_ca_governance.xsd\">\n"
       "  <domain_access_rules>\n"
       "    <domain_rule>\n"
    << DomainsXml(max_domain_id, "      ")
    << "      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>\n"
       "      <enable_join_access_control>true</enable_join_access_control>\n"
       "      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>\n"
       "      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>\n"
       "      <rtps_protection_kind>ENCRYPT</rtps_protection_kind>\n"
       "      <topic_access_rules>\n"
       "        <topic_rule>\n"
       "          <topic_expression>rt/echoservo/*</topic_expression>\n"
       "          <enable_discovery_protection>true</enable_discovery_protection>\n"
       "          <enable_liveliness_protection>true</enable_liveliness_protection>\n"
       "          <enable_read_access_control>true</enable_read_access_control>\n"
       "          <enable_write_access_control>true</enable_write_access_control>\n"
       "          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>\n"
       "          <data_protection_kind>ENCRYPT</data_protection_kind>\n"
       "        </topic_rule>\n"
       "        <topic_rule>\n"
       "          <topic_expression>*</topic_expression>\n"
       "          <enable_discovery_protection>false</enable_discovery_protection>\n"
       "          <enable_liveliness_protection>false</enable_liveliness_protection>\n"
       "          <enable_read_access_control>false</enable_read_access_control>\n"
       "          <enable_write_access_control>false</enable_write_access_control>\n"
       "          <metadata_protection_kind>NONE</metadata_protection_kind>\n"
       "          <data_protection_kind>NONE</data_protection_kind>\n"
       "        </topic_rule>\n"
       "      </topic_access_rules>\n"
       "    </domain_rule>\n"
       "  </domain_access_rules>\n"
       "</dds>\n";
  return x.str();
}

std::string TopicsXml(const char* element, const std::vector<std::string_view>& topics) {
  if (topics.empty()) return "";
  std::ostringstream x;
  x << "        <" << element << ">\n          <topics>\n";
  for (const std::string_view t : topics) x << "            <topic>" << t << "</topic>\n";
  x << "          </topics>\n        </" << element << ">\n";
  return x.str();
}

std::string PermissionsXml(const Role& role, const std::string& subject, std::time_t from,
                           std::time_t until, int max_domain_id) {
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
       "<dds xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" "
       "xsi:noNamespaceSchemaLocation=\"http://www.omg.org/spec/DDS-SECURITY/20170901/"
       "omg_shared_ca_permissions.xsd\">\n"
       "  <permissions>\n"
       "    <grant name=\"echoservo_"
    << role.name << "\">\n"
    << "      <subject_name>" << subject << "</subject_name>\n"
    << "      <validity>\n        <not_before>" << XmlTime(from)
    << "</not_before>\n        <not_after>" << XmlTime(until) << "</not_after>\n      </validity>\n"
    << "      <allow_rule>\n"
    << DomainsXml(max_domain_id, "        ") << TopicsXml("publish", role.publish)
    << TopicsXml("subscribe", role.subscribe) << "      </allow_rule>\n"
    << "      <default>DENY</default>\n"
       "    </grant>\n"
       "  </permissions>\n"
       "</dds>\n";
  return x.str();
}

// --- checks -------------------------------------------------------------------------------

[[noreturn]] void Bad(const fs::path& file, const std::string& why) {
  ERR_clear_error();
  throw std::invalid_argument("security: " + file.string() + ": " + why);
}

Bio OpenForRead(const fs::path& file) {
  Bio b(BIO_new_file(file.c_str(), "r"));
  if (!b) Bad(file, "cannot be read");
  return b;
}

Cert ReadCert(const fs::path& file) {
  Bio b = OpenForRead(file);
  Cert c(PEM_read_bio_X509(b.get(), nullptr, nullptr, nullptr));
  if (!c) Bad(file, "not a PEM certificate");
  return c;
}

Key ReadKey(const fs::path& file) {
  Bio b = OpenForRead(file);
  Key k(PEM_read_bio_PrivateKey(b.get(), nullptr, nullptr, nullptr));
  if (!k) Bad(file, "not an unencrypted PEM private key");
  return k;
}

Store StoreOf(X509* ca) {
  Store s(X509_STORE_new());
  if (!s || X509_STORE_add_cert(s.get(), ca) != 1) Fail("cannot build a certificate store");
  return s;
}

// The signed document's text, verified against `store` as Fast DDS does.
std::string VerifySmime(const fs::path& file, X509_STORE* store, const fs::path& ca_file) {
  Bio in = OpenForRead(file);
  BIO* content = nullptr;
  Pkcs7 p7(SMIME_read_PKCS7(in.get(), &content));
  Bio content_owner(content);
  if (!p7) Bad(file, "not an S/MIME signed document");
  Bio out(BIO_new(BIO_s_mem()));
  if (!out) Fail("out of memory");
  if (PKCS7_verify(p7.get(), nullptr, store, content, out.get(), PKCS7_TEXT) != 1)
    Bad(file,
        "its signature does not verify against " + ca_file.string() + " (" + OpenSslErrors() + ")");
  return BioText(out.get());
}

std::string Uri(const std::string& path) { return "file://" + path; }

}  // namespace

std::vector<std::string> SecurityRoles() {
  std::vector<std::string> names;
  for (const Role& r : Roles()) names.emplace_back(r.name);
  return names;
}

void SecurityInitOptions::Validate() const {
  if (participants.empty())
    throw std::invalid_argument("SecurityInitOptions.participants: none given");
  std::set<std::string> seen;
  for (const std::string& p : participants) {
    const auto known = SecurityRoles();
    if (std::find(known.begin(), known.end(), p) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw std::invalid_argument("SecurityInitOptions.participants: unknown participant '" + p +
                                  "' (roles: " + list + ")");
    }
    if (!seen.insert(p).second)
      throw std::invalid_argument("SecurityInitOptions.participants: '" + p + "' given twice");
  }
  if (validity_days < 1 || validity_days > 3650)
    throw std::invalid_argument("SecurityInitOptions.validity_days must be 1..3650");
  if (max_domain_id < 0 || max_domain_id > 232)
    throw std::invalid_argument("SecurityInitOptions.max_domain_id must be 0..232");
  const bool plain =
      !organization.empty() && std::all_of(organization.begin(), organization.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == ' ' || c == '-' || c == '_' ||
               c == '.';
      });
  if (!plain)
    throw std::invalid_argument(
        "SecurityInitOptions.organization: letters, digits, ' ', '-', '_', '.' only");
}

std::vector<std::string> InitSecurityDir(const std::string& dir, const SecurityInitOptions& o) {
  o.Validate();
  if (dir.empty()) throw std::invalid_argument("security init: empty directory name");
  const fs::path root = fs::absolute(dir);
  std::error_code ec;
  if (fs::exists(root, ec) && !fs::is_directory(root, ec))
    Bad(root, "exists and is not a directory");
  if (!o.overwrite) {
    std::vector<fs::path> existing = {root / kCaCert, root / kGovernance};
    for (const std::string& p : o.participants) existing.push_back(root / p / kCertificate);
    for (const fs::path& f : existing)
      if (fs::exists(f, ec))
        throw std::invalid_argument(
            "security init: " + f.string() +
            " exists: the directory already holds credentials (overwrite them with --force)");
  }
  fs::create_directories(root / "ca", ec);
  if (ec)
    throw std::runtime_error("security init: cannot create " + (root / "ca").string() + ": " +
                             ec.message());
  std::vector<std::string> written;
  const auto write = [&](const fs::path& f, const std::string& text, bool secret) {
    WriteFile(f, text, secret);
    written.push_back(f.string());
  };

  const Key ca_key = NewKey();
  const Cert ca = NewCertificate(o.organization, o.organization + " test CA", ca_key.get(), nullptr,
                                 nullptr, o.validity_days);
  write(root / kCaKey, KeyPem(ca_key.get()), true);
  write(root / kCaCert, CertPem(ca.get()), false);

  const std::string governance = GovernanceXml(o.max_domain_id);
  write(root / kGovernanceXml, governance, false);
  write(root / kGovernance, SignSmime(governance, ca.get(), ca_key.get()), false);

  const std::time_t now = std::time(nullptr);
  for (const std::string& name : o.participants) {
    const Role& role = *std::find_if(Roles().begin(), Roles().end(),
                                     [&](const Role& r) { return r.name == name; });
    const fs::path d = root / name;
    fs::create_directories(d, ec);
    if (ec)
      throw std::runtime_error("security init: cannot create " + d.string() + ": " + ec.message());
    const Key key = NewKey();
    const Cert cert =
        NewCertificate(o.organization, name, key.get(), ca.get(), ca_key.get(), o.validity_days);
    write(d / kPrivateKey, KeyPem(key.get()), true);
    write(d / kCertificate, CertPem(cert.get()), false);
    const std::string permissions = PermissionsXml(role, SubjectRfc2253(cert.get()), now - kDayS,
                                                   now + o.validity_days * kDayS, o.max_domain_id);
    write(d / kPermissionsXml, permissions, false);
    write(d / kPermissions, SignSmime(permissions, ca.get(), ca_key.get()), false);
  }
  return written;
}

void SignSecurityDocument(const std::string& document, const std::string& ca_cert,
                          const std::string& ca_key, const std::string& signed_out) {
  std::ifstream in(document, std::ios::binary);
  if (!in) Bad(document, "cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  const Cert ca = ReadCert(ca_cert);
  const Key key = ReadKey(ca_key);
  if (X509_check_private_key(ca.get(), key.get()) != 1) Bad(ca_key, "does not match " + ca_cert);
  WriteFile(signed_out, SignSmime(text.str(), ca.get(), key.get()), false);
}

SecurityFiles CheckSecurityDir(const std::string& dir, const std::string& participant) {
  if (participant.empty() || participant.find('/') != std::string::npos || participant == "." ||
      participant == "..")
    throw std::invalid_argument("security: bad participant name '" + participant + "'");
  const fs::path root = fs::absolute(dir);
  std::error_code ec;
  if (!fs::is_directory(root, ec))
    Bad(root, "not a directory (make one with `echoservo security init " + dir + "`)");
  SecurityFiles f;
  f.identity_ca = f.permissions_ca = (root / kCaCert).string();
  f.governance = (root / kGovernance).string();
  f.certificate = (root / participant / kCertificate).string();
  f.private_key = (root / participant / kPrivateKey).string();
  f.permissions = (root / participant / kPermissions).string();

  if (!fs::is_directory(root / participant, ec)) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(root, ec))
      if (fs::exists(e.path() / kCertificate)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    std::string held;
    for (const std::string& n : names) held += (held.empty() ? "" : ", ") + n;
    Bad(f.certificate, "missing: the directory holds no credentials for participant '" +
                           participant + "' (it has: " + (held.empty() ? "none" : held) +
                           "; add them with `echoservo security init " + dir +
                           " --participants ... --force`)");
  }
  for (const std::string* file :
       {&f.identity_ca, &f.governance, &f.certificate, &f.private_key, &f.permissions})
    if (!fs::is_regular_file(*file, ec)) Bad(*file, "missing");

  const Cert ca = ReadCert(f.identity_ca);
  const Cert cert = ReadCert(f.certificate);
  const Key key = ReadKey(f.private_key);
  const Store store = StoreOf(ca.get());
  StoreCtx ctx(X509_STORE_CTX_new());
  if (!ctx || X509_STORE_CTX_init(ctx.get(), store.get(), cert.get(), nullptr) != 1)
    Fail("cannot verify a certificate");
  if (X509_verify_cert(ctx.get()) != 1)
    Bad(f.certificate, "not issued by " + f.identity_ca + " (" +
                           X509_verify_cert_error_string(X509_STORE_CTX_get_error(ctx.get())) +
                           ")");
  if (X509_check_private_key(cert.get(), key.get()) != 1)
    Bad(f.private_key, "does not match " + f.certificate);
  VerifySmime(f.governance, store.get(), f.identity_ca);
  const std::string permissions = VerifySmime(f.permissions, store.get(), f.permissions_ca);
  const std::string subject = SubjectRfc2253(cert.get());
  if (permissions.find("<subject_name>" + subject + "</subject_name>") == std::string::npos)
    Bad(f.permissions, "grants nothing to " + f.certificate + "'s subject '" + subject + "'");
  return f;
}

std::vector<std::pair<std::string, std::string>> SecurityProperties(const SecurityFiles& f) {
  return {
      {"dds.sec.auth.plugin", "builtin.PKI-DH"},
      {"dds.sec.auth.builtin.PKI-DH.identity_ca", Uri(f.identity_ca)},
      {"dds.sec.auth.builtin.PKI-DH.identity_certificate", Uri(f.certificate)},
      {"dds.sec.auth.builtin.PKI-DH.private_key", Uri(f.private_key)},
      {"dds.sec.access.plugin", "builtin.Access-Permissions"},
      {"dds.sec.access.builtin.Access-Permissions.permissions_ca", Uri(f.permissions_ca)},
      {"dds.sec.access.builtin.Access-Permissions.governance", Uri(f.governance)},
      {"dds.sec.access.builtin.Access-Permissions.permissions", Uri(f.permissions)},
      {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"},
  };
}

}  // namespace echoservo::link
