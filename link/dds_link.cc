#include "link/dds_link.h"

#include <arpa/inet.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/attributes/LibrarySettingsAttributes.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string_view>
#include <thread>

#include "echoservo_msgs/msg/CatheterStatePubSubTypes.h"
#include "echoservo_msgs/msg/ServoCommandPubSubTypes.h"
#include "echoservo_msgs/msg/TargetEstimatePubSubTypes.h"
#include "link/clock.h"
#include "link/message_conversion.h"
#include "msg/checked_pubsub_type.h"

namespace echoservo::link {

namespace dds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastdds::rtps;
using eprosima::fastrtps::Duration_t;
using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

namespace {

constexpr int kMaxDomainId = 232;
constexpr double kPollPeriodS = 0.01;
// Unicast discovery (loopback mode, initial peers without a port) announces to the
// well-known ports of this many participants per host.
constexpr std::uint32_t kInitialPeersRange = 16;

// Participant ids in use by this process. Fast DDS 2.9 numbers participants 0, 1, 2, ...
// for the life of the process, and unicast discovery only reaches the first
// kInitialPeersRange ids of a host; taking the smallest id free in this process keeps a
// process that creates participants again and again (tests, restarts of the link)
// reachable. Another process's participant on the same ports moves to the next free
// port pair, as Fast DDS does for ids of its own.
class ParticipantIds {
 public:
  static int Acquire() {
    std::lock_guard lock(mu());
    int id = 0;
    while (used().count(id) != 0) ++id;
    used().insert(id);
    return id;
  }
  static void Release(int id) {
    std::lock_guard lock(mu());
    used().erase(id);
  }

 private:
  static std::mutex& mu() {
    static std::mutex m;
    return m;
  }
  static std::set<int>& used() {
    static std::set<int> ids;
    return ids;
  }
};

// What a topic needs: its generated types, its name and its QoS (docs/dds.md).
struct TopicQos {
  bool reliable;
  bool transient_local;
  int writer_depth;
  int reader_depth;
  bool liveliness;  // writers assert an automatic lease of kLivelinessLeaseS
};

template <class Sample>
struct TopicTraits;

template <>
struct TopicTraits<TargetEstimateSample> {
  using Message = echoservo_msgs::msg::TargetEstimate;
  // never throws on a malformed payload (msg/checked_pubsub_type.h)
  using Type = echoservo::msg::CheckedPubSubType<echoservo_msgs::msg::TargetEstimatePubSubType>;
  static constexpr std::string_view kName = kTargetTopic;
  // A stream: only the newest estimate matters, a lost one is replaced 20+ ms later.
  static constexpr TopicQos kQos{false, false, 1, 4, true};
};

template <>
struct TopicTraits<CatheterStateSample> {
  using Message = echoservo_msgs::msg::CatheterState;
  // never throws on a malformed payload (msg/checked_pubsub_type.h)
  using Type = echoservo::msg::CheckedPubSubType<echoservo_msgs::msg::CatheterStatePubSubType>;
  static constexpr std::string_view kName = kStateTopic;
  // Mode and fault changes must arrive; a late monitor gets the newest state at once.
  static constexpr TopicQos kQos{true, true, 1, 1, true};
};

template <>
struct TopicTraits<ServoCommandSample> {
  using Message = echoservo_msgs::msg::ServoCommand;
  // never throws on a malformed payload (msg/checked_pubsub_type.h)
  using Type = echoservo::msg::CheckedPubSubType<echoservo_msgs::msg::ServoCommandPubSubType>;
  static constexpr std::string_view kName = kCommandTopic;
  // Every command of a burst (enable, standoff, stop) arrives, in order; no lease so
  // that any ROS 2 publisher matches.
  static constexpr TopicQos kQos{true, true, 8, 8, false};
};

Duration_t ToDuration(double s) { return Duration_t(static_cast<long double>(s)); }

double ToSeconds(const Duration_t& d) {
  if (d == eprosima::fastrtps::c_TimeInfinite) return std::numeric_limits<double>::infinity();
  return static_cast<double>(d.seconds) + 1e-9 * static_cast<double>(d.nanosec);
}

template <class EntityQos>
void ApplyQos(const TopicQos& t, int depth, EntityQos& q) {
  q.reliability().kind =
      t.reliable ? dds::RELIABLE_RELIABILITY_QOS : dds::BEST_EFFORT_RELIABILITY_QOS;
  q.durability().kind =
      t.transient_local ? dds::TRANSIENT_LOCAL_DURABILITY_QOS : dds::VOLATILE_DURABILITY_QOS;
  q.history().kind = dds::KEEP_LAST_HISTORY_QOS;
  q.history().depth = depth;
  if (t.liveliness) {
    q.liveliness().kind = dds::AUTOMATIC_LIVELINESS_QOS;
    q.liveliness().lease_duration = ToDuration(kLivelinessLeaseS);
    q.liveliness().announcement_period = ToDuration(kLivelinessLeaseS / 4);
  }
}

template <class EntityQos>
EndpointQos ReadQos(const EntityQos& q) {
  EndpointQos e;
  e.reliable = q.reliability().kind == dds::RELIABLE_RELIABILITY_QOS;
  e.transient_local = q.durability().kind == dds::TRANSIENT_LOCAL_DURABILITY_QOS;
  e.depth = q.history().depth;
  e.liveliness_lease_s = ToSeconds(q.liveliness().lease_duration);
  return e;
}

// Polls `done` every 10 ms until it holds or `timeout_s` passes.
template <class Done>
bool PollUntil(Done done, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::duration<double>(kPollPeriodS));
  }
  return true;
}

// UDPv4 on the whitelisted interfaces (all when empty), announcing to the initial peers'
// first kInitialPeersRange participant ports.
std::shared_ptr<rtps::UDPv4TransportDescriptor> Udp(std::vector<std::string> whitelist) {
  auto udp = std::make_shared<rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList = std::move(whitelist);
  udp->maxInitialPeersRange = kInitialPeersRange;
  return udp;
}

bool ValidIpv4(const std::string& address) {
  in_addr parsed{};
  return inet_pton(AF_INET, address.c_str(), &parsed) == 1;
}

// "A.B.C.D" or "A.B.C.D:PORT" → locator (port 0: Fast DDS tries the first participants'
// well-known ports). Throws std::invalid_argument.
Locator_t PeerLocator(const std::string& peer) {
  const std::size_t colon = peer.find(':');
  const std::string address = peer.substr(0, colon);
  if (!ValidIpv4(address)) {
    throw std::invalid_argument("ParticipantOptions.initial_peers: '" + peer +
                                "' is not an IPv4 address");
  }
  Locator_t locator;
  IPLocator::setIPv4(locator, address);
  if (colon != std::string::npos) {
    const std::string port = peer.substr(colon + 1);
    std::size_t used = 0;
    int value = -1;
    try {
      value = std::stoi(port, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != port.size() || port.empty() || value < 1 || value > 65535) {
      throw std::invalid_argument("ParticipantOptions.initial_peers: bad port in '" + peer + "'");
    }
    locator.port = static_cast<std::uint32_t>(value);
  }
  return locator;
}

}  // namespace

void ParticipantOptions::Validate() const {
  if (domain_id < 0 || domain_id > kMaxDomainId) {
    throw std::invalid_argument("ParticipantOptions.domain_id must be 0.." +
                                std::to_string(kMaxDomainId));
  }
  if (loopback_only && (!interfaces.empty() || !initial_peers.empty() || !shared_memory)) {
    throw std::invalid_argument(
        "ParticipantOptions.loopback_only excludes interfaces, initial_peers and shared_memory = "
        "false");
  }
  for (const std::string& address : interfaces) {
    if (!ValidIpv4(address)) {
      throw std::invalid_argument("ParticipantOptions.interfaces: '" + address +
                                  "' is not an IPv4 address");
    }
  }
  for (const std::string& peer : initial_peers) PeerLocator(peer);
  if (!profile.empty() && profiles_file.empty()) {
    throw std::invalid_argument("ParticipantOptions.profile needs profiles_file");
  }
  for (const auto& [property, value] : properties) {
    if (property.empty())
      throw std::invalid_argument("ParticipantOptions.properties: empty property name");
  }
}

// Intra-process delivery off, once, before the first participant: with it on, two
// participants of one process (the demo's tracker and servo) deliver each other's
// automatic liveliness messages from their event threads, each holding its own WLP lock
// while taking the other's — Fast DDS 2.9 deadlocks (seen as a DataWriter deletion that
// never returns). Samples then go through the same transports as between processes.
static void DisableIntraprocessDelivery() {
  static std::once_flag once;
  std::call_once(once, [] {
    eprosima::fastrtps::LibrarySettingsAttributes settings;
    settings.intraprocess_delivery = eprosima::fastrtps::INTRAPROCESS_OFF;
    eprosima::fastrtps::xmlparser::XMLProfileManager::library_settings(settings);
  });
}

struct Participant::Impl {
  dds::DomainParticipant* participant = nullptr;
  dds::Publisher* publisher = nullptr;
  dds::Subscriber* subscriber = nullptr;
  int participant_id = -1;  // from ParticipantIds, or -1 when a profile set one
  std::mutex mu;
  std::map<std::string, dds::Topic*, std::less<>> topics;

  explicit Impl(const ParticipantOptions& o) {
    DisableIntraprocessDelivery();
    auto* factory = dds::DomainParticipantFactory::get_instance();
    dds::DomainParticipantQos qos = factory->get_default_participant_qos();
    if (!o.profiles_file.empty()) {
      if (factory->load_XML_profiles_file(o.profiles_file) != ReturnCode_t::RETCODE_OK) {
        throw std::invalid_argument("ParticipantOptions.profiles_file: cannot load '" +
                                    o.profiles_file + "'");
      }
      if (!o.profile.empty() &&
          factory->get_participant_qos_from_profile(o.profile, qos) != ReturnCode_t::RETCODE_OK) {
        throw std::invalid_argument("ParticipantOptions.profile: no participant profile '" +
                                    o.profile + "'");
      }
    }
    qos.name(o.name);
    if (o.loopback_only) {
      qos.transport().use_builtin_transports = false;
      qos.transport().user_transports = {Udp({"127.0.0.1"})};
      Locator_t peer;
      IPLocator::setIPv4(peer, 127, 0, 0, 1);
      qos.wire_protocol().builtin.initialPeersList.push_back(peer);
    }
    if (!o.interfaces.empty() || !o.initial_peers.empty() || !o.shared_memory) {
      qos.transport().use_builtin_transports = false;
      qos.transport().user_transports = {Udp(o.interfaces)};
      if (o.shared_memory) {
        qos.transport().user_transports.push_back(
            std::make_shared<rtps::SharedMemTransportDescriptor>());
      }
    }
    for (const std::string& p : o.initial_peers)
      qos.wire_protocol().builtin.initialPeersList.push_back(PeerLocator(p));
    for (const auto& [property, value] : o.properties)
      qos.properties().properties().emplace_back(property, value);

    if (qos.wire_protocol().participant_id < 0) {
      participant_id = ParticipantIds::Acquire();
      qos.wire_protocol().participant_id = participant_id;
    }
    participant = factory->create_participant(static_cast<dds::DomainId_t>(o.domain_id), qos);
    if (participant == nullptr) {
      Destroy();
      throw std::runtime_error("DDS: cannot create the domain participant");
    }
    publisher = participant->create_publisher(dds::PUBLISHER_QOS_DEFAULT);
    subscriber = participant->create_subscriber(dds::SUBSCRIBER_QOS_DEFAULT);
    if (publisher == nullptr || subscriber == nullptr) {
      Destroy();
      throw std::runtime_error("DDS: cannot create the publisher or subscriber");
    }
  }
  ~Impl() { Destroy(); }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void Destroy() {
    if (participant != nullptr) {
      participant->delete_contained_entities();
      dds::DomainParticipantFactory::get_instance()->delete_participant(participant);
    }
    if (participant_id >= 0) ParticipantIds::Release(participant_id);
  }

  // The topic of `Sample`, created (and its type registered) on first use.
  template <class Sample>
  dds::Topic* TopicFor() {
    using Traits = TopicTraits<Sample>;
    std::lock_guard lock(mu);
    const auto it = topics.find(Traits::kName);
    if (it != topics.end()) return it->second;
    dds::TypeSupport type(new typename Traits::Type());
    if (type.register_type(participant) != ReturnCode_t::RETCODE_OK) {
      throw std::runtime_error("DDS: cannot register type " + type.get_type_name());
    }
    dds::Topic* topic = participant->create_topic(std::string(Traits::kName), type.get_type_name(),
                                                  dds::TOPIC_QOS_DEFAULT);
    if (topic == nullptr)
      throw std::runtime_error("DDS: cannot create topic " + std::string(Traits::kName));
    topics.emplace(std::string(Traits::kName), topic);
    return topic;
  }
};

Participant::Participant(const ParticipantOptions& options) {
  options.Validate();
  impl_ = std::make_shared<Impl>(options);
}

Participant::~Participant() = default;

int Participant::domain_id() const { return static_cast<int>(impl_->participant->get_domain_id()); }

// ---------------------------------------------------------------------------------------
template <class Sample>
struct Publisher<Sample>::Impl {
  using Traits = TopicTraits<Sample>;
  std::shared_ptr<Participant::Impl> participant;
  dds::Topic* topic = nullptr;
  dds::DataWriter* writer = nullptr;
  std::mutex mu;                     // Publish from any thread
  typename Traits::Message message;  // reused: no allocation once warm

  explicit Impl(const Participant& p)
      : participant(p.impl()), topic(participant->template TopicFor<Sample>()) {
    dds::DataWriterQos qos = participant->publisher->get_default_datawriter_qos();
    ApplyQos(Traits::kQos, Traits::kQos.writer_depth, qos);
    writer = participant->publisher->create_datawriter(topic, qos);
    if (writer == nullptr)
      throw std::runtime_error("DDS: cannot create a writer on " + topic->get_name());
  }
  ~Impl() { participant->publisher->delete_datawriter(writer); }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  std::size_t matched() const {
    dds::PublicationMatchedStatus status;
    writer->get_publication_matched_status(status);
    return static_cast<std::size_t>(status.current_count);
  }
};

template <class Sample>
Publisher<Sample>::Publisher(Participant& participant)
    : impl_(std::make_unique<Impl>(participant)) {}

template <class Sample>
Publisher<Sample>::~Publisher() = default;

template <class Sample>
bool Publisher<Sample>::Publish(const Sample& s) {
  std::lock_guard lock(impl_->mu);
  ToMessage(s, impl_->message);
  return impl_->writer->write(&impl_->message);
}

template <class Sample>
std::size_t Publisher<Sample>::matched_subscribers() const {
  return impl_->matched();
}

template <class Sample>
bool Publisher<Sample>::WaitForSubscribers(std::size_t n, double timeout_s) const {
  return PollUntil([&] { return impl_->matched() >= n; }, timeout_s);
}

template <class Sample>
std::string Publisher<Sample>::topic_name() const {
  return impl_->topic->get_name();
}

template <class Sample>
std::string Publisher<Sample>::type_name() const {
  return impl_->topic->get_type_name();
}

template <class Sample>
EndpointQos Publisher<Sample>::qos() const {
  return ReadQos(impl_->writer->get_qos());
}

// ---------------------------------------------------------------------------------------
template <class Sample>
struct Subscriber<Sample>::Impl final : public dds::DataReaderListener {
  using Traits = TopicTraits<Sample>;
  std::shared_ptr<Participant::Impl> participant;
  dds::Topic* topic = nullptr;
  dds::DataReader* reader = nullptr;
  Callback on_sample;
  // Receive thread only.
  typename Traits::Message message;
  Sample incoming;
  std::optional<std::uint64_t> last_sequence;
  // Shared with the takers, under mu.
  mutable std::mutex mu;
  std::condition_variable fresh_cv;
  SampleValidator validator;
  SubscriberStats stats;
  std::uint32_t alive_count = 0;  // liveliness
  std::atomic<bool> gone{false};  // stats().publisher_gone(), kept current under mu
  Sample latest;
  double latest_received_s = 0.0;
  bool fresh = false;

  Impl(const Participant& p, ValidationLimits limits, Callback callback)
      : participant(p.impl()),
        topic(participant->template TopicFor<Sample>()),
        on_sample(std::move(callback)),
        validator(limits) {
    dds::DataReaderQos qos = participant->subscriber->get_default_datareader_qos();
    ApplyQos(Traits::kQos, Traits::kQos.reader_depth, qos);
    reader = participant->subscriber->create_datareader(topic, qos, this);
    if (reader == nullptr)
      throw std::runtime_error("DDS: cannot create a reader on " + topic->get_name());
  }
  ~Impl() override {
    reader->set_listener(nullptr);
    participant->subscriber->delete_datareader(reader);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void on_data_available(dds::DataReader* r) override {
    dds::SampleInfo info;
    while (r->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
      if (info.valid_data) Receive();
    }
  }

  void Receive() {
    const double now_s = NowS();
    FromMessage(message, incoming);
    {
      std::lock_guard lock(mu);
      ++stats.received;
      if (!validator.Accept(incoming, now_s)) return;
      if (last_sequence && incoming.sequence_number > *last_sequence + 1) {
        stats.sequence_gaps += incoming.sequence_number - *last_sequence - 1;
      }
      last_sequence = incoming.sequence_number;
      if (fresh) ++stats.overwritten;
      latest = incoming;  // copy-assignment reuses the slot's storage
      latest_received_s = now_s;
      fresh = true;
    }
    fresh_cv.notify_all();
    if (!on_sample) return;
    try {
      on_sample(incoming, now_s);
    } catch (...) {
      std::lock_guard lock(mu);
      ++stats.callback_errors;
    }
  }

  void on_subscription_matched(dds::DataReader*, const dds::SubscriptionMatchedStatus& s) override {
    std::lock_guard lock(mu);
    stats.matched_publishers = static_cast<std::uint32_t>(std::max(0, s.current_count));
    if (!Traits::kQos.liveliness && s.current_count > 0) stats.ever_alive = true;
    UpdateGoneLocked();
  }

  void on_liveliness_changed(dds::DataReader*, const dds::LivelinessChangedStatus& s) override {
    std::lock_guard lock(mu);
    alive_count = static_cast<std::uint32_t>(std::max(0, s.alive_count));
    if (s.alive_count > 0) stats.ever_alive = true;
    if (s.not_alive_count_change > 0)
      stats.liveliness_lost += static_cast<std::uint64_t>(s.not_alive_count_change);
    UpdateGoneLocked();
  }

  std::uint32_t AlivePublishersLocked() const {
    return Traits::kQos.liveliness ? std::min(alive_count, stats.matched_publishers)
                                   : stats.matched_publishers;
  }
  // After every change of alive_count, matched_publishers or ever_alive (under mu).
  void UpdateGoneLocked() {
    gone.store(stats.ever_alive && AlivePublishersLocked() == 0, std::memory_order_release);
  }

  bool TakeLocked(Sample& out, double* received_s) {
    if (!fresh) return false;
    out = latest;  // copy-assignment reuses out's vectors
    if (received_s != nullptr) *received_s = latest_received_s;
    fresh = false;
    return true;
  }
};

template <class Sample>
Subscriber<Sample>::Subscriber(Participant& participant, ValidationLimits limits,
                               Callback on_sample)
    : impl_(std::make_unique<Impl>(participant, limits, std::move(on_sample))) {}

template <class Sample>
Subscriber<Sample>::~Subscriber() = default;

template <class Sample>
bool Subscriber<Sample>::TryTakeLatest(Sample& out, double* received_s) {
  std::unique_lock lock(impl_->mu, std::try_to_lock);
  return lock.owns_lock() && impl_->TakeLocked(out, received_s);
}

template <class Sample>
bool Subscriber<Sample>::WaitTakeLatest(Sample& out, double timeout_s, double* received_s) {
  std::unique_lock lock(impl_->mu);
  impl_->fresh_cv.wait_for(lock, std::chrono::duration<double>(timeout_s),
                           [&] { return impl_->fresh; });
  return impl_->TakeLocked(out, received_s);
}

template <class Sample>
bool Subscriber<Sample>::WaitForPublishers(std::size_t n, double timeout_s) const {
  return PollUntil([&] { return stats().matched_publishers >= n; }, timeout_s);
}

template <class Sample>
SubscriberStats Subscriber<Sample>::stats() const {
  std::lock_guard lock(impl_->mu);
  SubscriberStats s = impl_->stats;
  s.validation = impl_->validator.counters();
  s.alive_publishers = impl_->AlivePublishersLocked();
  return s;
}

template <class Sample>
bool Subscriber<Sample>::publisher_gone_now() const {
  return impl_->gone.load(std::memory_order_acquire);
}

template <class Sample>
std::string Subscriber<Sample>::topic_name() const {
  return impl_->topic->get_name();
}

template <class Sample>
std::string Subscriber<Sample>::type_name() const {
  return impl_->topic->get_type_name();
}

template <class Sample>
EndpointQos Subscriber<Sample>::qos() const {
  return ReadQos(impl_->reader->get_qos());
}

template class Publisher<TargetEstimateSample>;
template class Publisher<CatheterStateSample>;
template class Publisher<ServoCommandSample>;
template class Subscriber<TargetEstimateSample>;
template class Subscriber<CatheterStateSample>;
template class Subscriber<ServoCommandSample>;

}  // namespace echoservo::link
