// Conversions between the link's plain samples (link/samples.h) and the C++ types that
// fastddsgen generates from msg/echoservo_msgs/msg/*.idl, field by field with the same
// units. Declared with forward declarations so that this header stays free of Fast DDS;
// the definitions (message_conversion.cc) include the generated headers.
// From the wire nothing is checked (link/sample_validation.h does that); to the wire a
// motion model with more than kMaxHarmonics cosine or sine terms throws
// std::invalid_argument (the IDL's bounded sequences cannot carry it).
#pragma once

#include "link/samples.h"

namespace echoservo_msgs::msg {
class TargetEstimate;
class CatheterState;
class ServoCommand;
}  // namespace echoservo_msgs::msg

namespace echoservo::link {

void ToMessage(const TargetEstimateSample& s, echoservo_msgs::msg::TargetEstimate& m);
void FromMessage(const echoservo_msgs::msg::TargetEstimate& m, TargetEstimateSample& s);
void ToMessage(const CatheterStateSample& s, echoservo_msgs::msg::CatheterState& m);
void FromMessage(const echoservo_msgs::msg::CatheterState& m, CatheterStateSample& s);
void ToMessage(const ServoCommandSample& s, echoservo_msgs::msg::ServoCommand& m);
void FromMessage(const echoservo_msgs::msg::ServoCommand& m, ServoCommandSample& s);

}  // namespace echoservo::link
