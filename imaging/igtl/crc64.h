// CRC-64 ECMA-182 as OpenIGTLink uses it for the header `crc` field: polynomial
// 0x42F0E1EBA9EA3693, MSB first (not reflected), initial value 0, no final XOR, computed
// over the message body only. Two implementations that give identical results:
//   - Crc64Ecma182: table-driven slice-by-8 (8 bytes per step, 8 KiB of tables), several
//     times faster than the byte-wise loop; the one the codec uses.
//   - Crc64Ecma182LibIgtl: libOpenIGTLink's own crc64() (byte-wise), kept as the reference
//     for conformance tests and the benchmark.
// Both are incremental: pass the previous result as `crc` to continue over a split buffer.
#pragma once

#include <cstdint>
#include <span>

namespace echoservo::imaging::openigtlink {

std::uint64_t Crc64Ecma182(std::span<const std::uint8_t> data, std::uint64_t crc = 0);
std::uint64_t Crc64Ecma182LibIgtl(std::span<const std::uint8_t> data, std::uint64_t crc = 0);

}  // namespace echoservo::imaging::openigtlink
