// KLV framing: universal keys, BER lengths and tags, and splitting buffers
// into packets, including garbage and random input.

#include "core/klv/decode.h"
#include "core/klv/klv.h"
#include "tests/core/klv/klv_test_util.h"

#include <gtest/gtest.h>

#include <random>

namespace saker::klv {
namespace {

using testing::HexBytes;
using testing::MakePacket;
using testing::PacketBytes;

TEST(UniversalKeyTest, ToHexGroupsFourBytes) {
  EXPECT_EQ(kSt0601Key.ToHex(), "060e2b34 020b0101 0e010301 01000000");
  EXPECT_EQ(kEg0104Key.ToHex(), "060e2b34 02010101 0e010102 01010000");
  EXPECT_EQ(kSt0903Key.ToHex(), "060e2b34 020b0101 0e010303 06000000");
}

TEST(UniversalKeyTest, MatchingIgnoresOnlyTheVersionByte) {
  UniversalKey other_version = kSt0601Key;
  other_version.bytes[kKeyVersionByte] = 0x0E;
  EXPECT_FALSE(other_version == kSt0601Key);
  EXPECT_TRUE(SameKeyIgnoringVersion(other_version, kSt0601Key));
  for (size_t i = 0; i < 16; ++i) {
    if (i == kKeyVersionByte) continue;
    UniversalKey changed = kSt0601Key;
    changed.bytes[i] ^= 0x01;
    EXPECT_FALSE(SameKeyIgnoringVersion(changed, kSt0601Key)) << "byte " << i;
  }
  EXPECT_FALSE(SameKeyIgnoringVersion(kSt0601Key, kEg0104Key));
  EXPECT_FALSE(SameKeyIgnoringVersion(kSt0601Key, kSt0903Key));
}

TEST(BerLengthTest, ShortForm) {
  size_t consumed = 0;
  auto length = ReadBerLength(HexBytes("05 ff"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 5u);
  EXPECT_EQ(consumed, 1u);
  length = ReadBerLength(HexBytes("7f"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 127u);
  length = ReadBerLength(HexBytes("00"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 0u);
}

TEST(BerLengthTest, LongForm) {
  size_t consumed = 0;
  auto length = ReadBerLength(HexBytes("81 80"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 128u);
  EXPECT_EQ(consumed, 2u);
  length = ReadBerLength(HexBytes("82 09 63 00"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 2403u);
  EXPECT_EQ(consumed, 3u);
  // A long form may encode a small value (non-minimal but legal).
  length = ReadBerLength(HexBytes("84 00 00 00 05"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, 5u);
  EXPECT_EQ(consumed, 5u);
  length = ReadBerLength(HexBytes("88 ff ff ff ff ff ff ff ff"), &consumed);
  ASSERT_TRUE(length.ok());
  EXPECT_EQ(*length, UINT64_MAX);
  EXPECT_EQ(consumed, 9u);
  EXPECT_TRUE(ReadBerLength(HexBytes("81 05"), nullptr).ok());
}

TEST(BerLengthTest, Errors) {
  size_t consumed = 1234;
  EXPECT_FALSE(ReadBerLength({}, &consumed).ok());
  EXPECT_FALSE(ReadBerLength(HexBytes("80"), &consumed).ok()) << "indefinite form";
  EXPECT_FALSE(ReadBerLength(HexBytes("89 00 00 00 00 00 00 00 00 01"), &consumed).ok())
      << "more than 8 length bytes";
  EXPECT_FALSE(ReadBerLength(HexBytes("ff"), &consumed).ok());
  EXPECT_FALSE(ReadBerLength(HexBytes("83 01 02"), &consumed).ok()) << "truncated";
  EXPECT_FALSE(ReadBerLength(HexBytes("81"), &consumed).ok()) << "truncated";
  EXPECT_EQ(consumed, 1234u) << "untouched on error";
}

TEST(BerOidTest, DecodesOneToFourBytes) {
  size_t consumed = 0;
  auto tag = ReadBerOid(HexBytes("05"), &consumed);
  ASSERT_TRUE(tag.ok());
  EXPECT_EQ(*tag, 5u);
  EXPECT_EQ(consumed, 1u);
  tag = ReadBerOid(HexBytes("7f 01"), &consumed);
  ASSERT_TRUE(tag.ok());
  EXPECT_EQ(*tag, 127u);
  tag = ReadBerOid(HexBytes("81 00"), &consumed);
  ASSERT_TRUE(tag.ok());
  EXPECT_EQ(*tag, 128u);
  EXPECT_EQ(consumed, 2u);
  tag = ReadBerOid(HexBytes("81 0f"), &consumed);
  ASSERT_TRUE(tag.ok());
  EXPECT_EQ(*tag, 143u);
  tag = ReadBerOid(HexBytes("ff ff ff 7f"), &consumed);
  ASSERT_TRUE(tag.ok());
  EXPECT_EQ(*tag, (uint64_t{1} << 28) - 1);
  EXPECT_EQ(consumed, 4u);
}

TEST(BerOidTest, Errors) {
  EXPECT_FALSE(ReadBerOid({}, nullptr).ok());
  EXPECT_FALSE(ReadBerOid(HexBytes("81"), nullptr).ok()) << "truncated";
  EXPECT_FALSE(ReadBerOid(HexBytes("81 82 83"), nullptr).ok()) << "truncated";
  EXPECT_FALSE(ReadBerOid(HexBytes("81 80 80 80 00"), nullptr).ok()) << "5 bytes";
  EXPECT_FALSE(ReadBerOid(HexBytes("81 80 80 80"), nullptr).ok()) << "4 bytes, unterminated";
}

// Every input byte is either in exactly one packet or counted as skipped, and
// every packet's bytes are the input slice at its offset.
void ExpectConsistent(ByteSpan data, const KlvSplitResult& result) {
  size_t covered = result.skipped_bytes;
  size_t previous_end = 0;
  for (const auto& packet : result.packets) {
    ASSERT_LE(packet.offset + packet.bytes.size(), data.size());
    ASSERT_GE(packet.offset, previous_end);
    previous_end = packet.offset + packet.bytes.size();
    ASSERT_TRUE(std::equal(packet.bytes.begin(), packet.bytes.end(), data.begin() + packet.offset));
    ASSERT_GE(packet.bytes.size(), 17 + packet.value.size());
    ASSERT_TRUE(std::equal(packet.value.begin(), packet.value.end(),
                           packet.bytes.end() - packet.value.size()));
    ASSERT_TRUE(std::equal(packet.key.bytes.begin(), packet.key.bytes.end(), packet.bytes.begin()));
    covered += packet.bytes.size();
  }
  EXPECT_EQ(covered, data.size());
  if (result.skipped_bytes > 0) {
    EXPECT_FALSE(result.errors.empty());
  }
}

TEST(SplitKlvPacketsTest, SeveralPacketsInOneBuffer) {
  std::vector<uint8_t> data = PacketBytes(kSt0601Key, HexBytes("41 01 11"));
  const auto second = PacketBytes(kSt0903Key, std::vector<uint8_t>(300, 0xAB));
  data.insert(data.end(), second.begin(), second.end());
  const KlvSplitResult result = SplitKlvPackets(data);
  ASSERT_EQ(result.packets.size(), 2u);
  EXPECT_TRUE(result.errors.empty());
  EXPECT_EQ(result.skipped_bytes, 0u);
  EXPECT_EQ(result.packets[0].key, kSt0601Key);
  EXPECT_EQ(result.packets[0].value, HexBytes("41 01 11"));
  EXPECT_EQ(result.packets[0].offset, 0u);
  EXPECT_EQ(result.packets[1].key, kSt0903Key);
  EXPECT_EQ(result.packets[1].value.size(), 300u);
  EXPECT_EQ(result.packets[1].offset, 20u);
  EXPECT_EQ(result.packets[1].bytes.size(), 16u + 3u + 300u) << "long-form length kept";
  ExpectConsistent(data, result);
}

TEST(SplitKlvPacketsTest, ResyncsAfterLeadingAndTrailingGarbage) {
  std::vector<uint8_t> data = HexBytes("00 11 06 0e 2b 99 22");  // 7 bytes, a false prefix start
  const auto packet = PacketBytes(kSt0601Key, HexBytes("41 01 11"));
  data.insert(data.end(), packet.begin(), packet.end());
  data.insert(data.end(), {0xDE, 0xAD});
  const KlvSplitResult result = SplitKlvPackets(data);
  ASSERT_EQ(result.packets.size(), 1u);
  EXPECT_EQ(result.packets[0].offset, 7u);
  EXPECT_EQ(result.skipped_bytes, 9u);
  EXPECT_EQ(result.errors.size(), 2u);
  ExpectConsistent(data, result);
}

TEST(SplitKlvPacketsTest, ResyncsAfterAnOverrunningLength) {
  // First packet claims 200 value bytes but the next packet starts after 3.
  std::vector<uint8_t> data(kSt0601Key.bytes.begin(), kSt0601Key.bytes.end());
  data.insert(data.end(), {0x81, 0xC8, 0x41, 0x01, 0x11});
  const auto good = PacketBytes(kEg0104Key, HexBytes("01 02 03"));
  data.insert(data.end(), good.begin(), good.end());
  const KlvSplitResult result = SplitKlvPackets(data);
  ASSERT_EQ(result.packets.size(), 1u);
  EXPECT_EQ(result.packets[0].key, kEg0104Key);
  EXPECT_EQ(result.packets[0].offset, 21u);
  ASSERT_EQ(result.errors.size(), 1u);
  EXPECT_NE(result.errors[0].find("overruns"), std::string::npos) << result.errors[0];
  EXPECT_EQ(result.skipped_bytes, 21u);
  ExpectConsistent(data, result);
}

TEST(SplitKlvPacketsTest, ResyncsAfterABadBerLength) {
  std::vector<uint8_t> data(kSt0601Key.bytes.begin(), kSt0601Key.bytes.end());
  data.push_back(0x80);  // indefinite length: not KLV
  const auto good = PacketBytes(kSt0601Key, HexBytes("41 01 11"));
  data.insert(data.end(), good.begin(), good.end());
  const KlvSplitResult result = SplitKlvPackets(data);
  ASSERT_EQ(result.packets.size(), 1u);
  EXPECT_EQ(result.packets[0].offset, 17u);
  EXPECT_EQ(result.errors.size(), 1u);
  ExpectConsistent(data, result);
}

TEST(SplitKlvPacketsTest, TruncatedPackets) {
  const auto whole = PacketBytes(kSt0601Key, HexBytes("41 01 11 02 08 00 00 00 00 00 00 00 01"));
  for (size_t size = 0; size < whole.size(); ++size) {
    const std::vector<uint8_t> cut(whole.begin(), whole.begin() + size);
    const KlvSplitResult result = SplitKlvPackets(cut);
    EXPECT_TRUE(result.packets.empty()) << size;
    EXPECT_EQ(result.skipped_bytes, size);
    EXPECT_EQ(result.errors.empty(), size == 0) << size;
    ExpectConsistent(cut, result);
  }
  const KlvSplitResult result = SplitKlvPackets(whole);
  EXPECT_EQ(result.packets.size(), 1u);
  EXPECT_TRUE(result.errors.empty());
}

TEST(SplitKlvPacketsTest, ZeroLengthValue) {
  std::vector<uint8_t> data = PacketBytes(kSt0601Key, {});
  const auto second = PacketBytes(kSt0601Key, {});
  data.insert(data.end(), second.begin(), second.end());
  const KlvSplitResult result = SplitKlvPackets(data);
  ASSERT_EQ(result.packets.size(), 2u);
  EXPECT_TRUE(result.packets[0].value.empty());
  EXPECT_EQ(result.packets[1].offset, 17u);
  EXPECT_TRUE(result.errors.empty());
  const DecodedPacket decoded = DecodePacket(result.packets[0]);
  EXPECT_TRUE(decoded.status.ok());
  ASSERT_TRUE(decoded.st0601.has_value());
  EXPECT_TRUE(decoded.st0601->items.empty());
  EXPECT_FALSE(decoded.st0601->checksum_ok);
}

TEST(SplitKlvPacketsTest, EmptyAndGarbageOnly) {
  EXPECT_TRUE(SplitKlvPackets({}).packets.empty());
  EXPECT_TRUE(SplitKlvPackets({}).errors.empty());
  const auto garbage = HexBytes("00 01 02 03 04 05 06 0e 2b");
  const KlvSplitResult result = SplitKlvPackets(garbage);
  EXPECT_TRUE(result.packets.empty());
  EXPECT_EQ(result.skipped_bytes, garbage.size());
  EXPECT_EQ(result.errors.size(), 1u);
}

// Random buffers, some seeded with key prefixes and plausible lengths so the
// parser's deeper paths run too. Run under ASan/UBSan this is the bounds test.
TEST(SplitKlvPacketsTest, RandomBuffersNeverCrash) {
  std::mt19937 rng(20240601);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> size_dist(0, 400);
  const UniversalKey keys[] = {kSt0601Key, kEg0104Key, kSt0903Key};
  size_t total_packets = 0;
  for (int round = 0; round < 2000; ++round) {
    std::vector<uint8_t> data(static_cast<size_t>(size_dist(rng)));
    for (auto& b : data) b = static_cast<uint8_t>(byte(rng));
    // Plant keys (with a random BER length after them) at random places.
    const int plants = byte(rng) % 4;
    for (int p = 0; p < plants && data.size() >= 20; ++p) {
      const size_t at = static_cast<size_t>(byte(rng)) % (data.size() - 19);
      const UniversalKey& key = keys[byte(rng) % 3];
      std::copy(key.bytes.begin(), key.bytes.end(), data.begin() + at);
      const size_t room = data.size() - at - 17;
      data[at + 16] = static_cast<uint8_t>(byte(rng) % 2 ? byte(rng) : room % 128);
    }
    const KlvSplitResult result = SplitKlvPackets(data);
    ExpectConsistent(data, result);
    for (const auto& packet : result.packets) {
      const DecodedPacket decoded = DecodePacket(packet);
      EXPECT_EQ(decoded.length, packet.value.size());
      if (decoded.st0601 || decoded.eg0104) {
        EXPECT_TRUE(decoded.raw.empty());
      } else {
        EXPECT_EQ(decoded.raw, packet.value);
      }
      EXPECT_FALSE(ToJson(decoded).dump().empty());
    }
    total_packets += result.packets.size();
  }
  EXPECT_GT(total_packets, 100u) << "the planted keys should give many packets";
}

TEST(BytesToHexTest, LowerCaseNoSeparators) {
  EXPECT_EQ(BytesToHex(HexBytes("00 0A ff 10")), "000aff10");
  EXPECT_EQ(BytesToHex({}), "");
}

TEST(ToValidUtf8Test, ReplacesOnlyInvalidBytes) {
  EXPECT_EQ(ToValidUtf8("MISSION01"), "MISSION01");
  EXPECT_EQ(ToValidUtf8(std::string("A\0B", 3)), std::string("A\0B", 3));
  EXPECT_EQ(ToValidUtf8("caf\xC3\xA9"), "caf\xC3\xA9");
  EXPECT_EQ(ToValidUtf8("\xFF"), "\xEF\xBF\xBD");
  EXPECT_EQ(ToValidUtf8("a\xC3"), "a\xEF\xBF\xBD") << "truncated sequence";
  EXPECT_EQ(ToValidUtf8("\xC0\xAF"), "\xEF\xBF\xBD\xEF\xBF\xBD") << "overlong";
  EXPECT_EQ(ToValidUtf8("\xED\xA0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD") << "surrogate";
}

}  // namespace
}  // namespace saker::klv
