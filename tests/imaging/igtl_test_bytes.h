// Byte surgery on OpenIGTLink messages for the codec and stream tests: write a big-endian
// field, and recompute the header's body CRC after the body was changed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "imaging/igtl/crc64.h"
#include "imaging/igtl/image_message.h"

namespace echoservo::imaging::openigtlink::testing {

inline void PutBigEndian64(std::vector<std::uint8_t>& m, std::size_t at, std::uint64_t v) {
  for (int b = 0; b < 8; ++b) m[at + b] = static_cast<std::uint8_t>(v >> (56 - 8 * b));
}

inline void Recrc(std::vector<std::uint8_t>& m) {
  PutBigEndian64(m, 50, Crc64Ecma182({m.data() + kHeaderBytes, m.size() - kHeaderBytes}));
}

}  // namespace echoservo::imaging::openigtlink::testing
