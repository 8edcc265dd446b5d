// CheckedPubSubType<T>: a fastddsgen type support (T = e.g.
// echoservo_msgs::msg::ServoCommandPubSubType) whose deserialize() never throws.
//
// Why. The code fastddsgen 2.x generates catches only fastcdr's NotEnoughMemoryException in
// deserialize(); a payload with an unknown encapsulation kind (the first two bytes) makes
// fastcdr throw BadParamException, and Fast DDS calls deserialize() on its own receive
// thread, so one malformed packet from any participant on the domain would terminate the
// servo (found by fuzz_dds_samples, docs/reliability.md). Here every fastcdr exception is a
// sample that does not deserialize (false), which Fast DDS drops. The link uses this type in
// place of the generated one (link/dds_link.cc); the sample's values are still checked by
// link/sample_validation.h.
#pragma once

#include <fastcdr/exceptions/Exception.h>
#include <fastdds/rtps/common/SerializedPayload.h>

namespace echoservo::msg {

template <class GeneratedType>
class CheckedPubSubType : public GeneratedType {
 public:
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    try {
      return GeneratedType::deserialize(payload, data);
    } catch (const eprosima::fastcdr::exception::Exception&) {
      return false;
    }
  }
};

}  // namespace echoservo::msg
