#pragma once

// Small builders shared by the KLV tests: hex parsing and packet assembly.

#include "core/klv/klv.h"
#include "core/klv/st0601.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace saker::klv::testing {

// "06 0e2B34" -> {0x06, 0x0E, 0x2B, 0x34}; spaces are ignored.
inline std::vector<uint8_t> HexBytes(std::string_view hex) {
  std::vector<uint8_t> out;
  int high = -1;
  for (char c : hex) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    const int digit = std::isdigit(static_cast<unsigned char>(c))
                          ? c - '0'
                          : std::tolower(static_cast<unsigned char>(c)) - 'a' + 10;
    EXPECT_TRUE(digit >= 0 && digit < 16) << "bad hex digit '" << c << "' in " << hex;
    if (high < 0) {
      high = digit;
    } else {
      out.push_back(static_cast<uint8_t>(high * 16 + digit));
      high = -1;
    }
  }
  EXPECT_EQ(high, -1) << "odd number of hex digits in " << hex;
  return out;
}

// Shortest BER length encoding of `n`.
inline std::vector<uint8_t> BerLength(uint64_t n) {
  if (n < 0x80) return {static_cast<uint8_t>(n)};
  std::vector<uint8_t> bytes;
  for (uint64_t rest = n; rest != 0; rest >>= 8) bytes.insert(bytes.begin(), rest & 0xFF);
  bytes.insert(bytes.begin(), static_cast<uint8_t>(0x80 | bytes.size()));
  return bytes;
}

// key + BER length + value.
inline std::vector<uint8_t> PacketBytes(const UniversalKey& key,
                                        const std::vector<uint8_t>& value) {
  std::vector<uint8_t> bytes(key.bytes.begin(), key.bytes.end());
  const auto length = BerLength(value.size());
  bytes.insert(bytes.end(), length.begin(), length.end());
  bytes.insert(bytes.end(), value.begin(), value.end());
  return bytes;
}

// A KlvPacket as SplitKlvPackets would return it.
inline KlvPacket MakePacket(const UniversalKey& key, const std::vector<uint8_t>& value) {
  KlvPacket packet;
  packet.key = key;
  packet.value = value;
  packet.bytes = PacketBytes(key, value);
  return packet;
}

// An ST 0601 packet holding `items` (concatenated TLVs) followed by a valid
// checksum item.
inline KlvPacket MakeSt0601Packet(const std::vector<uint8_t>& items) {
  std::vector<uint8_t> value = items;
  value.insert(value.end(), {0x01, 0x02, 0x00, 0x00});
  // The checksum covers the packet up to and including the checksum length.
  const std::vector<uint8_t> whole = PacketBytes(kSt0601Key, value);
  const uint16_t bcc = Bcc16(ByteSpan(whole).first(whole.size() - 2));
  value[value.size() - 2] = static_cast<uint8_t>(bcc >> 8);
  value[value.size() - 1] = static_cast<uint8_t>(bcc & 0xFF);
  return MakePacket(kSt0601Key, value);
}

// tag + BER length + value for a local set.
inline std::vector<uint8_t> Tlv(uint8_t tag, const std::vector<uint8_t>& value) {
  std::vector<uint8_t> out = {tag};
  const auto length = BerLength(value.size());
  out.insert(out.end(), length.begin(), length.end());
  out.insert(out.end(), value.begin(), value.end());
  return out;
}

}  // namespace saker::klv::testing
