// The DDS link between the tracker, the servo and operator tools (Fast DDS underneath, none
// of its headers here): a Participant per process, typed publishers and subscribers of the
// three topics, and the QoS each topic uses.
//
// Subscribers validate every sample on the DDS receive thread (link/sample_validation.h),
// count rejections by reason and keep the newest accepted sample; TryTakeLatest never blocks
// and does not allocate once warm (the 1 kHz loop). A publisher that disappears shows as
// stats().publisher_gone() (liveliness), and without a lock as publisher_gone_now(). Times in s on
// the shared clock (link/clock.h); units and frames as in link/samples.h. Errors: options a user
// can get wrong throw std::invalid_argument; a DDS entity that cannot be created throws
// std::runtime_error. Details: docs/dds.md#using-it
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "link/sample_validation.h"
#include "link/samples.h"

namespace echoservo::link {

// Writers of the target and state topics assert liveliness automatically with this
// lease; their readers report a publisher gone once it lapses.
inline constexpr double kLivelinessLeaseS = 0.5;

struct ParticipantOptions {
  int domain_id = 0;  // 0..232 (UDP port mapping)
  std::string name = "echoservo";
  // The deterministic single-host mode: builtin transports off, one UDPv4 transport on
  // 127.0.0.1 only, 127.0.0.1 as initial peer (what link/loopback_profile.xml does).
  bool loopback_only = false;
  // Two hosts: the IPv4 addresses of the interfaces to use (empty: all; shared memory
  // stays on for the same host) and unicast peers "A.B.C.D" or "A.B.C.D:PORT" to announce
  // to where multicast does not pass (without a port: the first participants' ports).
  std::vector<std::string> interfaces;
  std::vector<std::string> initial_peers;
  // Fast DDS's shared-memory transport for peers on the same host (beside UDPv4). Off:
  // UDPv4 only, as between two hosts (network namespaces on one host share /dev/shm).
  bool shared_memory = true;
  // An XML profiles file and the participant profile in it to start from. Without one,
  // the default QoS, which Fast DDS reads from FASTRTPS_DEFAULT_PROFILES_FILE if set.
  std::string profiles_file;
  std::string profile;
  // Participant properties (name, value), passed to Fast DDS unchanged: the place for
  // DDS-Security ("dds.sec.auth.plugin" = "builtin.PKI-DH", ...).
  std::vector<std::pair<std::string, std::string>> properties;

  // Throws std::invalid_argument naming the option for a bad domain, address or port,
  // loopback_only with interfaces, peers or shared_memory off, or a profile without a
  // file.
  void Validate() const;
};

class Participant {
 public:
  explicit Participant(const ParticipantOptions& options = {});
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  int domain_id() const;

  struct Impl;  // dds_link.cc; endpoints share it so that it outlives them
  const std::shared_ptr<Impl>& impl() const { return impl_; }

 private:
  std::shared_ptr<Impl> impl_;
};

// The QoS an endpoint was created with, read back from DDS.
struct EndpointQos {
  bool reliable = false;
  bool transient_local = false;
  int depth = 0;  // keep-last depth
  double liveliness_lease_s = std::numeric_limits<double>::infinity();
};

template <class Sample>
class Publisher {
 public:
  explicit Publisher(Participant& participant);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  // Publishes `s` as it is: subscribers validate. Returns false when DDS refuses the
  // write. Throws std::invalid_argument for a sample the IDL cannot carry (more than
  // kMaxHarmonics harmonics).
  bool Publish(const Sample& s);
  std::size_t matched_subscribers() const;
  // Polls until at least `n` subscribers match or `timeout_s` passes.
  bool WaitForSubscribers(std::size_t n, double timeout_s) const;

  std::string topic_name() const;
  std::string type_name() const;  // as registered with DDS
  EndpointQos qos() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct SubscriberStats {
  std::uint64_t received = 0;       // samples DDS delivered
  RejectionCounters validation;     // accepted, and rejected by reason
  std::uint64_t sequence_gaps = 0;  // sequence numbers skipped between accepted samples
  std::uint64_t overwritten = 0;    // accepted samples replaced before they were taken
  std::uint64_t callback_errors = 0;
  std::uint32_t matched_publishers = 0;
  std::uint32_t alive_publishers = 0;  // liveliness asserted (matched, without a lease)
  std::uint64_t liveliness_lost = 0;   // times a publisher's lease lapsed
  bool ever_alive = false;             // a publisher has been alive
  // A publisher was alive and none is now (the tracker went away, cleanly or not). A
  // publisher that dies before its first liveliness assertion reaches this reader is
  // not reported: the staleness of its samples still is.
  bool publisher_gone() const { return ever_alive && alive_publishers == 0; }
};

template <class Sample>
class Subscriber {
 public:
  // Called on the DDS receive thread for each accepted sample (keep it short; exceptions
  // are caught and counted).
  using Callback = std::function<void(const Sample& s, double received_s)>;

  explicit Subscriber(Participant& participant, ValidationLimits limits = {},
                      Callback on_sample = {});
  ~Subscriber();
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;

  // Non-blocking: the newest accepted sample not taken yet into `out` (and its reception
  // time into `received_s`), true; false when there is none, or in the rare instant the
  // receive thread holds the slot (the next call gets it).
  bool TryTakeLatest(Sample& out, double* received_s = nullptr);
  // Blocks up to `timeout_s` for a new accepted sample (tools and tests, not the loop).
  bool WaitTakeLatest(Sample& out, double timeout_s, double* received_s = nullptr);
  // Polls until at least `n` publishers match or `timeout_s` passes.
  bool WaitForPublishers(std::size_t n, double timeout_s) const;

  SubscriberStats stats() const;
  // stats().publisher_gone() without the lock stats() takes: an atomic the receive thread
  // updates with the match and liveliness counts (the 1 kHz loop).
  bool publisher_gone_now() const;
  std::string topic_name() const;
  std::string type_name() const;
  EndpointQos qos() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

extern template class Publisher<TargetEstimateSample>;
extern template class Publisher<CatheterStateSample>;
extern template class Publisher<ServoCommandSample>;
extern template class Subscriber<TargetEstimateSample>;
extern template class Subscriber<CatheterStateSample>;
extern template class Subscriber<ServoCommandSample>;

using TargetPublisher = Publisher<TargetEstimateSample>;
using StatePublisher = Publisher<CatheterStateSample>;
using CommandPublisher = Publisher<ServoCommandSample>;
using TargetSubscriber = Subscriber<TargetEstimateSample>;
using StateSubscriber = Subscriber<CatheterStateSample>;
using CommandSubscriber = Subscriber<ServoCommandSample>;

}  // namespace echoservo::link
