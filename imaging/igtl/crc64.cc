#include "imaging/igtl/crc64.h"

#include <igtl_util.h>

#include <array>
#include <bit>
#include <cstring>

namespace echoservo::imaging::openigtlink {
namespace {

constexpr std::uint64_t kPoly = 0x42F0E1EBA9EA3693ULL;

using Tables = std::array<std::array<std::uint64_t, 256>, 8>;

constexpr Tables MakeTables() {
  Tables t{};
  for (std::uint64_t b = 0; b < 256; ++b) {
    std::uint64_t crc = b << 56;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & (1ULL << 63)) ? (crc << 1) ^ kPoly : (crc << 1);
    }
    t[0][b] = crc;
  }
  // t[k][b]: the CRC register contribution of byte b followed by k zero bytes.
  for (int k = 1; k < 8; ++k) {
    for (int b = 0; b < 256; ++b) {
      const std::uint64_t prev = t[k - 1][b];
      t[k][b] = (prev << 8) ^ t[0][prev >> 56];
    }
  }
  return t;
}

constexpr Tables kTables = MakeTables();

inline std::uint64_t LoadBigEndian64(const std::uint8_t* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return __builtin_bswap64(v);  // x86/ARM hosts here are little-endian
}

}  // namespace

std::uint64_t Crc64Ecma182(std::span<const std::uint8_t> data, std::uint64_t crc) {
  static_assert(std::endian::native == std::endian::little, "big-endian host not supported");
  const std::uint8_t* p = data.data();
  std::size_t n = data.size();
  const auto& t = kTables;
  while (n >= 8) {
    const std::uint64_t c = crc ^ LoadBigEndian64(p);
    crc = t[7][c >> 56] ^ t[6][(c >> 48) & 0xFF] ^ t[5][(c >> 40) & 0xFF] ^ t[4][(c >> 32) & 0xFF] ^
          t[3][(c >> 24) & 0xFF] ^ t[2][(c >> 16) & 0xFF] ^ t[1][(c >> 8) & 0xFF] ^ t[0][c & 0xFF];
    p += 8;
    n -= 8;
  }
  while (n-- > 0) {
    crc = t[0][(crc >> 56) ^ *p++] ^ (crc << 8);
  }
  return crc;
}

std::uint64_t Crc64Ecma182LibIgtl(std::span<const std::uint8_t> data, std::uint64_t crc) {
  // crc64() takes a non-const pointer but does not write through it.
  return crc64(const_cast<unsigned char*>(data.data()), data.size(), crc);
}

}  // namespace echoservo::imaging::openigtlink
