// MISB ST 0601 decoding: checksum, per-tag vectors from the public test
// suites, the two MISB ST 0902 example packets, malformed sets and mutated
// real packets.

#include "core/klv/st0601.h"

#include "core/klv/decode.h"
#include "core/klv/st1201.h"
#include "tests/core/klv/klv_test_util.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <random>
#include <set>

namespace saker::klv {
namespace {

using testing::HexBytes;
using testing::MakePacket;
using testing::MakeSt0601Packet;
using testing::Tlv;

nlohmann::json ReadJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Decodes a one-item local set (no checksum).
St0601Item DecodeOne(const std::vector<uint8_t>& tlv) {
  auto set = DecodeSt0601(MakePacket(kSt0601Key, tlv));
  EXPECT_TRUE(set.ok()) << set.status().ToString();
  if (!set.ok() || set->items.size() != 1) {
    ADD_FAILURE() << "expected one item";
    return {};
  }
  return set->items[0];
}

// Days since 1970-01-01 of a proleptic Gregorian date.
int64_t DaysFromCivil(int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<int64_t>(doe) - 719468;
}

// "1995-04-16T12:44:54.670901Z" -> microseconds since 1970 UTC.
uint64_t ParseUtcMicros(const std::string& text) {
  int year = 0, month = 0, day = 0, hour = 0, minute = 0;
  double second = 0;
  EXPECT_EQ(std::sscanf(text.c_str(), "%d-%d-%dT%d:%d:%lfZ", &year, &month, &day, &hour, &minute,
                        &second),
            6)
      << text;
  const int64_t days =
      DaysFromCivil(year, static_cast<unsigned>(month), static_cast<unsigned>(day));
  const int64_t whole_seconds = days * 86400 + hour * 3600 + minute * 60;
  return static_cast<uint64_t>(whole_seconds * 1000000 + std::llround(second * 1e6));
}

TEST(Bcc16Test, MisbVector) {
  EXPECT_EQ(Bcc16(HexBytes("06 0E 2B 34 02 00 81 BB")), 0xB4FD);
  EXPECT_EQ(Bcc16({}), 0);
  EXPECT_EQ(Bcc16(HexBytes("12")), 0x1200) << "even offsets are the high byte";
  EXPECT_EQ(Bcc16(HexBytes("ff ff ff ff")), 0xFFFE) << "wraps modulo 2^16";
}

TEST(Bcc16Test, VectorsFromDataFile) {
  SAKER_REQUIRE_TEST_DATA(path, "st0601_vectors/st0601_tag_vectors.json");
  const auto vectors = ReadJson(path);
  int checked = 0;
  for (const auto& v : vectors.at("checksum_vectors")) {
    if (v.contains("bytes_hex")) {
      const auto expected = HexBytes(v.at("expected_bcc16").get<std::string>());
      EXPECT_EQ(Bcc16(HexBytes(v.at("bytes_hex").get<std::string>())),
                (expected[0] << 8) | expected[1]);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 1);
}

TEST(St0601TagNameTest, KnowsEveryTag) {
  EXPECT_STREQ(St0601TagName(1), "Checksum");
  EXPECT_STREQ(St0601TagName(13), "Sensor Latitude");
  EXPECT_STREQ(St0601TagName(65), "UAS Datalink LS Version Number");
  EXPECT_STREQ(St0601TagName(143), "Metadata Substream ID Pack");
  EXPECT_STREQ(St0601TagName(0), "Unknown tag");
  EXPECT_STREQ(St0601TagName(144), "Unknown tag");
  std::set<std::string> names;
  for (uint32_t tag = 1; tag <= 143; ++tag) {
    EXPECT_STRNE(St0601TagName(tag), "Unknown tag") << tag;
    names.insert(St0601TagName(tag));
  }
  EXPECT_EQ(names.size(), 143u) << "names are distinct";
}

// Per-tag TLV vectors: decode each and compare with the expected value.
TEST(St0601VectorsTest, TagVectors) {
  SAKER_REQUIRE_TEST_DATA(path, "st0601_vectors/st0601_tag_vectors.json");
  const auto vectors = ReadJson(path);
  int checked = 0;
  for (const auto& v : vectors.at("tag_vectors")) {
    const auto tag = v.at("tag").get<uint32_t>();
    SCOPED_TRACE("tag " + std::to_string(tag) + " " + v.at("tlv_hex").get<std::string>());
    const St0601Item item = DecodeOne(HexBytes(v.at("tlv_hex").get<std::string>()));
    ASSERT_EQ(item.tag, tag);
    const auto& expected = v.at("value");
    if (tag == 1) {
      ASSERT_TRUE(std::holds_alternative<uint64_t>(item.value));
      EXPECT_EQ(std::get<uint64_t>(item.value),
                std::stoul(expected.get<std::string>(), nullptr, 16));
    } else if (tag == 72) {
      ASSERT_TRUE(std::holds_alternative<uint64_t>(item.value));
      EXPECT_EQ(std::get<uint64_t>(item.value), ParseUtcMicros(expected.get<std::string>()));
    } else if (expected.is_string()) {
      ASSERT_TRUE(std::holds_alternative<std::string>(item.value));
      EXPECT_EQ(std::get<std::string>(item.value), expected.get<std::string>());
    } else if (expected.is_number_integer() && std::holds_alternative<uint64_t>(item.value)) {
      EXPECT_EQ(std::get<uint64_t>(item.value), expected.get<uint64_t>());
    } else {
      ASSERT_TRUE(std::holds_alternative<double>(item.value));
      const double got = std::get<double>(item.value);
      if (v.contains("decoded")) {
        EXPECT_NEAR(got, v.at("decoded").get<double>(), 1e-9);
      }
      const auto lsb = St0601Resolution(tag, item.raw.size());
      ASSERT_TRUE(lsb.has_value());
      EXPECT_NEAR(got, expected.get<double>(), *lsb);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 52);
}

std::vector<uint32_t> ParseTagList(const std::string& text) {
  std::vector<uint32_t> tags;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    const std::string part = text.substr(start, end - start);
    const size_t dots = part.find("..");
    if (dots == std::string::npos) {
      tags.push_back(static_cast<uint32_t>(std::stoul(part)));
    } else {
      const auto first = std::stoul(part.substr(0, dots));
      const auto last = std::stoul(part.substr(dots + 2));
      for (auto t = first; t <= last; ++t) tags.push_back(static_cast<uint32_t>(t));
    }
    start = end + 1;
  }
  return tags;
}

TEST(St0601VectorsTest, EdgeVectors) {
  SAKER_REQUIRE_TEST_DATA(path, "st0601_vectors/st0601_tag_vectors.json");
  const auto vectors = ReadJson(path);
  int checked = 0;
  for (const auto& v : vectors.at("edge_vectors")) {
    const auto value_bytes = HexBytes(v.at("value_hex").get<std::string>());
    const auto& expected = v.at("value");
    for (uint32_t tag : ParseTagList(v.at("tag").get<std::string>())) {
      SCOPED_TRACE("tag " + std::to_string(tag) + " " + v.at("name").get<std::string>());
      const St0601Item item = DecodeOne(Tlv(static_cast<uint8_t>(tag), value_bytes));
      if (expected.is_string()) {
        EXPECT_TRUE(std::holds_alternative<Absent>(item.value)) << "error indicator";
      } else {
        ASSERT_TRUE(std::holds_alternative<double>(item.value));
        const double tolerance = v.contains("tolerance") ? v.at("tolerance").get<double>() : 1e-12;
        EXPECT_NEAR(std::get<double>(item.value), expected.get<double>(), tolerance);
      }
      ++checked;
    }
  }
  EXPECT_EQ(checked, 5 * 8 + 12);
}

TEST(St0601DecodeTest, OffsetCornerLimitsAndErrorIndicator) {
  auto value = [](const char* hex) { return DecodeSt0601Value(26, HexBytes(hex)); };
  EXPECT_DOUBLE_EQ(std::get<double>(value("8001")), -0.075);
  EXPECT_DOUBLE_EQ(std::get<double>(value("7FFF")), 0.075);
  EXPECT_DOUBLE_EQ(std::get<double>(value("0000")), 0.0);
  EXPECT_TRUE(std::holds_alternative<Absent>(value("8000")));
  EXPECT_TRUE(std::holds_alternative<Absent>(DecodeSt0601Value(6, HexBytes("8000"))));
  EXPECT_TRUE(std::holds_alternative<Absent>(DecodeSt0601Value(13, HexBytes("80000000"))));
  EXPECT_TRUE(std::holds_alternative<Absent>(DecodeSt0601Value(89, HexBytes("80000000"))));
  EXPECT_DOUBLE_EQ(std::get<double>(DecodeSt0601Value(13, HexBytes("7FFFFFFF"))), 90.0);
  EXPECT_DOUBLE_EQ(std::get<double>(DecodeSt0601Value(14, HexBytes("80000001"))), -180.0);
  EXPECT_DOUBLE_EQ(std::get<double>(DecodeSt0601Value(5, HexBytes("FFFF"))), 360.0);
  EXPECT_DOUBLE_EQ(std::get<double>(DecodeSt0601Value(15, HexBytes("0000"))), -900.0);
}

TEST(St0601DecodeTest, IntegerTags) {
  EXPECT_EQ(std::get<int64_t>(DecodeSt0601Value(39, HexBytes("F6"))), -10);
  EXPECT_EQ(std::get<uint64_t>(DecodeSt0601Value(131, HexBytes("056f271b5e41b7"))),
            1529588637122999u)
      << "variable-length uint64";
  EXPECT_EQ(std::get<int64_t>(DecodeSt0601Value(137, HexBytes("012b8dc635"))), 5025678901);
  EXPECT_EQ(std::get<int64_t>(DecodeSt0601Value(136, HexBytes("ff"))), -1);
  EXPECT_EQ(std::get<uint64_t>(DecodeSt0601Value(2, HexBytes("000459F4A6AA4AA8"))),
            1224807209913000u);
}

TEST(St1201Test, ImapbDecoding) {
  // Values from the exhaustive KWIVER packet (tags 103, 109, 117, 118, 132).
  EXPECT_DOUBLE_EQ(*DecodeImapb(-900, 40000, HexBytes("2f921e")), 23456.234375);
  EXPECT_DOUBLE_EQ(*DecodeImapb(0, 21000, HexBytes("0001a0")), 1.625);
  EXPECT_DOUBLE_EQ(*DecodeImapb(-1000, 1000, HexBytes("3e90")), 1.0);
  EXPECT_DOUBLE_EQ(*DecodeImapb(-1000, 1000, HexBytes("3e8011")), 0.004150390625);
  EXPECT_DOUBLE_EQ(*DecodeImapb(1, 99999, HexBytes("0257c0")), 2400.0);
  EXPECT_DOUBLE_EQ(*DecodeImapb(0, 100, HexBytes("0000")), 0.0);
  EXPECT_DOUBLE_EQ(*DecodeImapb(-900, 40000, HexBytes("000000")), -900.0);
  // A range with a fractional zero offset (sF * min = -4915.2, zOffset 0.8):
  // zero is code 4916 and decodes exactly; code 0 lies just below min.
  EXPECT_NEAR(*DecodeImapb(-0.3, 1, HexBytes("1334")), 0.0, 1e-15);
  EXPECT_NEAR(*DecodeImapb(-0.3, 1, HexBytes("0000")), -0.3 - 0.8 / 16384, 1e-15);
  EXPECT_DOUBLE_EQ(ImapbResolution(-900, 40000, 3), 1.0 / 128);
  // Special values.
  EXPECT_TRUE(std::isinf(*DecodeImapb(0, 100, HexBytes("c800"))));
  EXPECT_GT(*DecodeImapb(0, 100, HexBytes("c800")), 0);
  EXPECT_LT(*DecodeImapb(0, 100, HexBytes("e800")), 0);
  EXPECT_TRUE(std::isnan(*DecodeImapb(0, 100, HexBytes("d000"))));
  EXPECT_TRUE(std::isnan(*DecodeImapb(0, 100, HexBytes("a000"))));
  EXPECT_FALSE(std::isnan(*DecodeImapb(0, 100, HexBytes("8000")))) << "MSB alone is normal";
  EXPECT_TRUE(std::holds_alternative<Absent>(DecodeSt0601Value(112, HexBytes("c800"))));
  // Errors.
  EXPECT_FALSE(DecodeImapb(0, 100, {}).ok());
  EXPECT_FALSE(DecodeImapb(0, 100, HexBytes("000000000000000000")).ok());
  EXPECT_FALSE(DecodeImapb(100, 0, HexBytes("00")).ok());
}

// MISB ST 0902.5 Annex C "dynamic only" example: valid checksum.
TEST(St0601PacketTest, DynamicOnlyExample) {
  SAKER_REQUIRE_TEST_DATA(path, "klvdata/DynamicOnlyMISMMSPacketData.bin");
  const auto bytes = saker::testing::ReadFileBytes(path);
  const KlvSplitResult split = SplitKlvPackets(bytes);
  ASSERT_EQ(split.packets.size(), 1u);
  EXPECT_TRUE(split.errors.empty());
  auto set = DecodeSt0601(split.packets[0]);
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  EXPECT_TRUE(set->checksum_ok);
  ASSERT_TRUE(set->stored_checksum.has_value());
  EXPECT_EQ(*set->stored_checksum, 0xC850);
  EXPECT_EQ(set->computed_checksum, 0xC850);
  EXPECT_TRUE(set->warnings.empty()) << set->warnings.front();

  std::vector<uint32_t> tags;
  for (const auto& item : set->items) tags.push_back(item.tag);
  const std::vector<uint32_t> expected_tags = {2,  5,  6,  7,  13, 14, 15, 16, 17, 18,
                                               19, 20, 21, 22, 23, 24, 25, 65, 1};
  EXPECT_EQ(tags, expected_tags);

  EXPECT_NEAR(*set->GetDouble(5), 159.974, 360.0 / 65535);
  EXPECT_NEAR(*set->GetDouble(13), 60.1768230, 1e-7);
  EXPECT_NEAR(*set->GetDouble(14), 128.4267590, 1e-7);
  EXPECT_NEAR(*set->GetDouble(15), 14190.7, 19900.0 / 65535);
  EXPECT_NEAR(*set->GetDouble(23), -10.5423886, 1e-7);
  EXPECT_NEAR(*set->GetDouble(24), 29.1578901, 1e-7);
  EXPECT_EQ(*set->GetUnsigned(65), 6u);
  EXPECT_EQ(*set->GetUnsigned(2), 1231798102000000u);
  EXPECT_FALSE(set->GetString(5).has_value());
  EXPECT_FALSE(set->GetDouble(3).has_value()) << "not present";

  const auto json = St0601ToJson(*set);
  ASSERT_EQ(json.at("items").size(), 19u);
  EXPECT_EQ(json.at("items")[0].at("tag"), 2);
  EXPECT_EQ(json.at("items")[0].at("name"), "Precision Time Stamp");
  EXPECT_EQ(json.at("items")[0].at("raw"), "00046050584e0180");
  EXPECT_EQ(json.at("items")[0].at("value"), 1231798102000000u);
  EXPECT_EQ(json.at("checksum").at("stored"), "c850");
  EXPECT_EQ(json.at("checksum").at("ok"), true);
}

// The "dynamic and constant" example: its stored checksum is wrong, and the
// packet must still decode, flagged.
TEST(St0601PacketTest, DynamicConstantExampleHasABadChecksum) {
  SAKER_REQUIRE_TEST_DATA(path, "klvdata/DynamicConstantMISMMSPacketData.bin");
  const auto bytes = saker::testing::ReadFileBytes(path);
  const KlvSplitResult split = SplitKlvPackets(bytes);
  ASSERT_EQ(split.packets.size(), 1u);
  auto set = DecodeSt0601(split.packets[0]);
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  EXPECT_FALSE(set->checksum_ok);
  EXPECT_EQ(*set->stored_checksum, 0xAA43);
  EXPECT_EQ(set->computed_checksum, 0x3E1E);
  ASSERT_EQ(set->warnings.size(), 1u);
  EXPECT_NE(set->warnings[0].find("checksum"), std::string::npos);

  EXPECT_EQ(*set->GetString(3), "Mission 12");
  EXPECT_EQ(*set->GetString(10), "Predator");
  EXPECT_NEAR(*set->GetDouble(13), 60.1768230, 1e-7);
  const St0601Item* security = set->Find(48);
  ASSERT_NE(security, nullptr);
  EXPECT_TRUE(std::holds_alternative<std::monostate>(security->value)) << "nested set kept raw";
  EXPECT_FALSE(security->raw.empty());
  const St0601Item* miis = set->Find(94);
  ASSERT_NE(miis, nullptr);
  EXPECT_TRUE(std::holds_alternative<std::monostate>(miis->value));
  EXPECT_EQ(set->items.back().tag, 1u);

  const auto json = St0601ToJson(*set);
  EXPECT_EQ(json.at("checksum").at("ok"), false);
  EXPECT_EQ(json.at("checksum").at("computed"), "3e1e");
  bool saw_security = false;
  for (const auto& item : json.at("items")) {
    if (item.at("tag") == 48) {
      saw_security = true;
      EXPECT_TRUE(item.at("value").is_null());
      EXPECT_EQ(item.at("raw").get<std::string>().size(), 2 * security->raw.size());
    }
  }
  EXPECT_TRUE(saw_security);
}

TEST(St0601PacketTest, SyntheticPacketChecksumVerifies) {
  const auto items = HexBytes("020800046050584E0180 0502 71C2 0D04 5595B66D 4101 11");
  const KlvPacket packet = MakeSt0601Packet(items);
  auto set = DecodeSt0601(packet);
  ASSERT_TRUE(set.ok());
  EXPECT_TRUE(set->checksum_ok);
  EXPECT_TRUE(set->warnings.empty());
  // Without the packet bytes the packet is rebuilt and checks the same.
  KlvPacket bare = packet;
  bare.bytes.clear();
  auto rebuilt = DecodeSt0601(bare);
  ASSERT_TRUE(rebuilt.ok());
  EXPECT_TRUE(rebuilt->checksum_ok);
  EXPECT_EQ(rebuilt->computed_checksum, set->computed_checksum);
  // A long value (BER long-form length) checks too, rebuilt or not.
  std::vector<uint8_t> long_items = items;
  const auto filler = Tlv(3, std::vector<uint8_t>(200, 'x'));
  long_items.insert(long_items.end(), filler.begin(), filler.end());
  KlvPacket long_packet = MakeSt0601Packet(long_items);
  EXPECT_TRUE(DecodeSt0601(long_packet)->checksum_ok);
  long_packet.bytes.clear();
  EXPECT_TRUE(DecodeSt0601(long_packet)->checksum_ok);
  // Flip one value bit: the checksum catches it and the set still decodes.
  KlvPacket corrupt = packet;
  corrupt.value[3] ^= 0x10;
  corrupt.bytes[17 + 3] ^= 0x10;
  auto bad = DecodeSt0601(corrupt);
  ASSERT_TRUE(bad.ok());
  EXPECT_FALSE(bad->checksum_ok);
  EXPECT_EQ(bad->items.size(), 5u);
}

TEST(St0601PacketTest, MissingChecksumIsAWarning) {
  auto set = DecodeSt0601(MakePacket(kSt0601Key, HexBytes("0502 71C2 4101 11")));
  ASSERT_TRUE(set.ok());
  EXPECT_FALSE(set->checksum_ok);
  EXPECT_FALSE(set->stored_checksum.has_value());
  ASSERT_EQ(set->warnings.size(), 1u);
  EXPECT_NE(set->warnings[0].find("no checksum"), std::string::npos);
  EXPECT_EQ(set->items.size(), 2u);
}

TEST(St0601PacketTest, ChecksumNotLastIsAWarning) {
  const KlvPacket good = MakeSt0601Packet(HexBytes("0502 71C2"));
  std::vector<uint8_t> value = good.value;
  value.insert(value.end(), {0x41, 0x01, 0x11});
  auto set = DecodeSt0601(MakePacket(kSt0601Key, value));
  ASSERT_TRUE(set.ok());
  EXPECT_EQ(set->items.size(), 3u);
  bool warned = false;
  for (const auto& w : set->warnings) warned |= w.find("not the last") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(St0601PacketTest, WrongLengthItemIsKeptRaw) {
  // Sensor latitude with 3 bytes, heading with 4, checksum with 1.
  auto set = DecodeSt0601(MakePacket(kSt0601Key, HexBytes("0D03 5595B6 0504 71C271C2 0801 93")));
  ASSERT_TRUE(set.ok());
  ASSERT_EQ(set->items.size(), 3u);
  EXPECT_TRUE(std::holds_alternative<std::monostate>(set->items[0].value));
  EXPECT_EQ(set->items[0].raw, HexBytes("5595B6"));
  EXPECT_TRUE(std::holds_alternative<std::monostate>(set->items[1].value));
  EXPECT_EQ(std::get<uint64_t>(set->items[2].value), 147u);
  EXPECT_FALSE(set->GetDouble(13).has_value());
  EXPECT_EQ(set->warnings.size(), 3u) << "two length warnings and no checksum";
}

TEST(St0601PacketTest, ZeroLengthItemsNeverCrash) {
  std::vector<uint8_t> items;
  for (uint32_t tag = 1; tag <= 143; ++tag) {
    if (tag < 128) {
      items.push_back(static_cast<uint8_t>(tag));
    } else {
      items.push_back(0x81);
      items.push_back(static_cast<uint8_t>(tag - 128));
    }
    items.push_back(0x00);
  }
  auto set = DecodeSt0601(MakePacket(kSt0601Key, items));
  ASSERT_TRUE(set.ok());
  ASSERT_EQ(set->items.size(), 143u);
  for (const auto& item : set->items) {
    EXPECT_TRUE(item.raw.empty());
    EXPECT_TRUE(std::holds_alternative<Absent>(item.value) ||
                std::holds_alternative<std::monostate>(item.value))
        << item.tag;
  }
  EXPECT_EQ(set->items[128].tag, 129u) << "two-byte BER-OID tags";
  EXPECT_TRUE(std::holds_alternative<Absent>(set->Find(13)->value));
  EXPECT_TRUE(std::holds_alternative<std::monostate>(set->Find(48)->value));
  EXPECT_EQ(St0601ToJson(*set).at("items")[12].at("value"), "absent");
}

TEST(St0601PacketTest, OverrunningItemEndsTheSet) {
  auto set = DecodeSt0601(MakePacket(kSt0601Key, HexBytes("0502 71C2 0D10 5595B66D")));
  ASSERT_TRUE(set.ok());
  ASSERT_EQ(set->items.size(), 1u);
  EXPECT_NEAR(*set->GetDouble(5), 159.974, 0.006);
  EXPECT_NE(set->warnings[0].find("overruns"), std::string::npos);
}

TEST(St0601PacketTest, Errors) {
  EXPECT_EQ(DecodeSt0601(MakePacket(kEg0104Key, HexBytes("0502 71C2"))).status().code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(DecodeSt0601(MakePacket(kSt0601Key, HexBytes("0285"))).status().code(),
            StatusCode::kInvalidData)
      << "first item unreadable";
  EXPECT_FALSE(DecodeSt0601(MakePacket(kSt0601Key, HexBytes("ff ff ff ff ff"))).ok());
  UniversalKey version_two = kSt0601Key;
  version_two.bytes[kKeyVersionByte] = 0x02;
  EXPECT_TRUE(DecodeSt0601(MakePacket(version_two, HexBytes("0502 71C2"))).ok());
}

// Random mutations (byte flips, insertions, deletions, truncations) of the
// real example packets: decoding and JSON never crash or throw.
TEST(St0601FuzzTest, MutatedRealPacketsNeverCrash) {
  SAKER_REQUIRE_TEST_DATA(dynamic_only, "klvdata/DynamicOnlyMISMMSPacketData.bin");
  SAKER_REQUIRE_TEST_DATA(dynamic_constant, "klvdata/DynamicConstantMISMMSPacketData.bin");
  const std::vector<uint8_t> originals[] = {saker::testing::ReadFileBytes(dynamic_only),
                                            saker::testing::ReadFileBytes(dynamic_constant)};
  std::mt19937 rng(601);
  std::uniform_int_distribution<int> byte(0, 255);
  int decoded_sets = 0;
  int bad_checksums = 0;
  for (int round = 0; round < 2000; ++round) {
    std::vector<uint8_t> data = originals[round % 2];
    const int mutations = 1 + byte(rng) % 6;
    for (int m = 0; m < mutations && !data.empty(); ++m) {
      const size_t at = static_cast<size_t>(rng() % data.size());
      switch (byte(rng) % 4) {
        case 0:
          data[at] = static_cast<uint8_t>(byte(rng));
          break;
        case 1:
          data.insert(data.begin() + static_cast<std::ptrdiff_t>(at),
                      static_cast<uint8_t>(byte(rng)));
          break;
        case 2:
          data.erase(data.begin() + static_cast<std::ptrdiff_t>(at));
          break;
        default:
          data.resize(at);
          break;
      }
    }
    for (const auto& packet : SplitKlvPackets(data).packets) {
      const DecodedPacket decoded = DecodePacket(packet);
      EXPECT_FALSE(ToJson(decoded).dump().empty());
      if (decoded.st0601) {
        ++decoded_sets;
        bad_checksums += !decoded.st0601->checksum_ok;
        for (const auto& item : decoded.st0601->items) {
          if (auto* d = std::get_if<double>(&item.value)) {
            EXPECT_TRUE(std::isfinite(*d));
          }
        }
      }
    }
  }
  EXPECT_GT(decoded_sets, 300);
  EXPECT_GT(bad_checksums, decoded_sets * 3 / 4) << "mutations are caught by the checksum";
}

}  // namespace
}  // namespace saker::klv
