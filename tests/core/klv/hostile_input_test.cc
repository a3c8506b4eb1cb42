// Hostile KLV built byte by byte: BER lengths that run past the end or use 5 to 9 length bytes,
// deeply nested local sets, and values that decode to NaN or infinity. Each gives a clear error
// or warning, or a graceful result (the value marked absent), never a crash, a huge allocation or
// a non-finite number handed to the rest of Saker. The fuzz harness tests/fuzz/fuzz_klv.cc
// checks the same promises on random input.

#include "core/klv/decode.h"
#include "core/klv/eg0104.h"
#include "core/klv/klv.h"
#include "core/klv/metadata.h"
#include "core/klv/st0601.h"
#include "tests/core/klv/klv_test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

namespace saker::klv {
namespace {

using testing::HexBytes;
using testing::MakePacket;
using testing::MakeSt0601Packet;
using testing::PacketBytes;
using testing::Tlv;

bool AnyWarningHas(const std::vector<std::string>& warnings, const std::string& text) {
  for (const auto& warning : warnings) {
    if (warning.find(text) != std::string::npos) return true;
  }
  return false;
}

std::vector<uint8_t> Concat(std::vector<uint8_t> a, const std::vector<uint8_t>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TEST(HostileBerTest, PacketLengthsOfFiveToEightBytesPastTheEnd) {
  // The length says 2^32 - 1 .. 2^64 - 1 bytes follow; 3 do. Nothing is allocated for the claim.
  for (const char* length : {"84 ff ff ff ff", "85 01 00 00 00 00", "88 ff ff ff ff ff ff ff ff",
                             "88 00 00 00 00 00 00 00 04"}) {
    SCOPED_TRACE(length);
    std::vector<uint8_t> bytes(kSt0601Key.bytes.begin(), kSt0601Key.bytes.end());
    bytes = Concat(bytes, HexBytes(length));
    bytes = Concat(bytes, HexBytes("02 01 7f"));
    const KlvSplitResult split = SplitKlvPackets(bytes);
    EXPECT_TRUE(split.packets.empty());
    ASSERT_EQ(split.errors.size(), 1u);
    EXPECT_NE(split.errors[0].find("offset 0"), std::string::npos) << split.errors[0];
    EXPECT_EQ(split.skipped_bytes, bytes.size());
  }
}

TEST(HostileBerTest, LongFormOfASmallLengthIsAccepted) {
  // Eight length bytes holding 3: legal BER, the packet is read.
  std::vector<uint8_t> bytes(kSt0601Key.bytes.begin(), kSt0601Key.bytes.end());
  bytes = Concat(bytes, HexBytes("88 00 00 00 00 00 00 00 03 02 01 7f"));
  const KlvSplitResult split = SplitKlvPackets(bytes);
  ASSERT_EQ(split.packets.size(), 1u);
  EXPECT_EQ(split.packets[0].value, HexBytes("02 01 7f"));
  EXPECT_TRUE(split.errors.empty());
}

TEST(HostileBerTest, NineOrMoreLengthBytesAreAnError) {
  for (const char* length : {"89 00 00 00 00 00 00 00 00 01", "8f 00", "ff"}) {
    SCOPED_TRACE(length);
    auto read = ReadBerLength(HexBytes(length), nullptr);
    ASSERT_FALSE(read.ok());
    EXPECT_EQ(read.status().code(), StatusCode::kInvalidData);
    EXPECT_NE(read.status().message().find("BER length"), std::string::npos);
  }
}

TEST(HostileBerTest, ItemLengthsPastTheEndEndTheSetWithAWarning) {
  // Tag 5 decodes; then tag 13 claims 2^40 (5 length bytes) or 2^64 - 1 (8) bytes.
  for (const char* length : {"85 01 00 00 00 00", "88 ff ff ff ff ff ff ff ff", "84 00 00 00 05"}) {
    SCOPED_TRACE(length);
    std::vector<uint8_t> items = Concat(HexBytes("05 02 71 c2 0d"), HexBytes(length));
    items = Concat(items, HexBytes("55 95 b6"));
    auto set = DecodeSt0601(MakePacket(kSt0601Key, items));
    ASSERT_TRUE(set.ok()) << set.status().ToString();
    ASSERT_EQ(set->items.size(), 1u);
    EXPECT_NEAR(*set->GetDouble(5), 159.974, 0.006);
    EXPECT_TRUE(AnyWarningHas(set->warnings, "tag 13")) << set->warnings[0];
    EXPECT_TRUE(AnyWarningHas(set->warnings, "overruns"));
  }
  // Nine length bytes in an item: named as a BER length problem.
  auto set = DecodeSt0601(
      MakePacket(kSt0601Key, HexBytes("05 02 71 c2 0d 89 00 00 00 00 00 00 00 00 04")));
  ASSERT_TRUE(set.ok());
  EXPECT_TRUE(AnyWarningHas(set->warnings, "BER length"));
  // When even the first item cannot be read, the packet is an error that says why.
  auto first = DecodeSt0601(MakePacket(kSt0601Key, HexBytes("0d 88 ff ff ff ff ff ff ff ff 00")));
  ASSERT_FALSE(first.ok());
  EXPECT_EQ(first.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(first.status().message().find("overruns"), std::string::npos);
}

TEST(HostileBerTest, EgItemLengthsPastTheEnd) {
  // A decodable item, then one whose 8-byte length claims 2^64 - 1 bytes.
  const UniversalKey altitude = Eg0104FieldKey(Eg0104Field::kDeviceAltitude);
  const UniversalKey latitude = Eg0104FieldKey(Eg0104Field::kDeviceLatitude);
  std::vector<uint8_t> value(altitude.bytes.begin(), altitude.bytes.end());
  value = Concat(value, HexBytes("04 44 83 d3 33"));
  value.insert(value.end(), latitude.bytes.begin(), latitude.bytes.end());
  value = Concat(value, HexBytes("88 ff ff ff ff ff ff ff ff 00 00"));
  auto set = DecodeEg0104(MakePacket(kEg0104Key, value));
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  ASSERT_EQ(set->items.size(), 1u);
  EXPECT_NEAR(*set->GetDouble(Eg0104Field::kDeviceAltitude), 1054.6, 0.1);
  ASSERT_EQ(set->warnings.size(), 1u);
  EXPECT_NE(set->warnings[0].find("overruns"), std::string::npos) << set->warnings[0];
}

// A VMTI local set (tag 74) holding itself `depth` times over, each level also carrying a nested
// security set (tag 48): the lengths all add up, only the nesting is absurd.
std::vector<uint8_t> NestedVmti(int depth) {
  std::vector<uint8_t> inner = Tlv(3, {0x00, 0x01});  // innermost: one VMTI item
  for (int level = 0; level < depth; ++level) {
    std::vector<uint8_t> payload = Tlv(48, Tlv(1, {0x01}));
    payload = Concat(payload, inner);
    inner = Tlv(74, payload);
  }
  return inner;
}

TEST(HostileNestingTest, DeeplyNestedSetsAreKeptRawWithoutRecursion) {
  const std::vector<uint8_t> nested = NestedVmti(2000);
  ASSERT_GT(nested.size(), 10000u);  // long-form lengths at the outer levels
  const KlvPacket packet = MakeSt0601Packet(Concat(HexBytes("05 02 71 c2"), nested));
  auto set = DecodeSt0601(packet);
  ASSERT_TRUE(set.ok()) << set.status().ToString();
  ASSERT_EQ(set->items.size(), 3u) << "heading, the outermost VMTI set, checksum";
  EXPECT_TRUE(set->checksum_ok);
  const St0601Item* vmti = set->Find(74);
  ASSERT_NE(vmti, nullptr);
  EXPECT_TRUE(std::holds_alternative<std::monostate>(vmti->value));
  // The raw value is the nested bytes after the outer tag (1 byte) and BER length (82 xx xx).
  EXPECT_EQ(vmti->raw, std::vector<uint8_t>(nested.begin() + 4, nested.end()));
  EXPECT_NEAR(*set->GetDouble(5), 159.974, 0.006);
  // The dump and the metadata of the whole packet are fine too.
  const DecodedPacket decoded = DecodePacket(packet);
  EXPECT_TRUE(decoded.status.ok());
  EXPECT_FALSE(ToJson(decoded).dump().empty());
}

TEST(HostileNestingTest, NestedSetWithALyingInnerLengthStaysInsideItsParent) {
  // The security set's inner item claims 200 bytes; the set itself is 4 bytes long. Its bytes are
  // kept raw and the next item of the parent still decodes.
  const std::vector<uint8_t> items =
      Concat(Tlv(48, HexBytes("01 81 c8 00")), HexBytes("05 02 71 c2"));
  auto set = DecodeSt0601(MakeSt0601Packet(items));
  ASSERT_TRUE(set.ok());
  ASSERT_NE(set->Find(48), nullptr);
  EXPECT_EQ(set->Find(48)->raw, HexBytes("01 81 c8 00"));
  EXPECT_NEAR(*set->GetDouble(5), 159.974, 0.006);
  EXPECT_TRUE(set->checksum_ok);
}

TEST(HostileValueTest, ImapbSpecialValuesAreAbsentNeverNanOrInfinity) {
  // Tag 104 Sensor Ellipsoid Height Extended (IMAPB -900..40000): +inf, -inf, quiet NaN,
  // signalling NaN, a reserved pattern, in 2 and 3 bytes.
  for (const char* raw :
       {"c8 00", "d8 00", "d0 00", "f0 00", "88 00", "80 01", "c8 00 00", "d0 00 01", "a0 00 00"}) {
    SCOPED_TRACE(raw);
    const St0601Value value = DecodeSt0601Value(104, HexBytes(raw));
    EXPECT_TRUE(std::holds_alternative<Absent>(value));
  }
  // A normal code still decodes to a finite number.
  const St0601Value normal = DecodeSt0601Value(104, HexBytes("10 00"));
  ASSERT_TRUE(std::holds_alternative<double>(normal));
  EXPECT_TRUE(std::isfinite(std::get<double>(normal)));
}

TEST(HostileValueTest, ReservedErrorIndicatorsLeaveMetadataAbsent) {
  // Sensor latitude (13) and longitude (14) 0x80000000, pitch (6) and roll (7) 0x8000, frame
  // centre (23, 24) reserved too: "out of range" in ST 0601, so absent, not a number.
  std::vector<uint8_t> items = Tlv(13, HexBytes("80 00 00 00"));
  items = Concat(items, Tlv(14, HexBytes("80 00 00 00")));
  items = Concat(items, Tlv(6, HexBytes("80 00")));
  items = Concat(items, Tlv(7, HexBytes("80 00")));
  items = Concat(items, Tlv(23, HexBytes("80 00 00 00")));
  items = Concat(items, Tlv(24, HexBytes("80 00 00 00")));
  items = Concat(items, Tlv(26, HexBytes("80 00")));  // offset corner error indicator
  const DecodedPacket decoded = DecodePacket(MakeSt0601Packet(items));
  ASSERT_TRUE(decoded.status.ok()) << decoded.status.ToString();
  ASSERT_TRUE(decoded.metadata.has_value());
  const FrameMetadata& m = *decoded.metadata;
  EXPECT_FALSE(m.sensor_latitude_deg.has_value());
  EXPECT_FALSE(m.sensor_longitude_deg.has_value());
  EXPECT_FALSE(m.platform_pitch_deg.has_value());
  EXPECT_FALSE(m.platform_roll_deg.has_value());
  EXPECT_FALSE(m.frame_center.has_value());
  EXPECT_FALSE(m.corners.has_value());
  const auto json = ToJson(decoded);
  EXPECT_EQ(json.at("items")[0].at("value"), "absent");
}

TEST(HostileValueTest, EgFloatNanAndInfinityAreAbsent) {
  // EG 0104 numbers are IEEE floats or doubles: NaN and infinities must not reach FrameMetadata.
  const struct {
    Eg0104Field field;
    const char* raw;
  } cases[] = {
      {Eg0104Field::kDeviceLatitude, "7f c0 00 00"},                   // float quiet NaN
      {Eg0104Field::kDeviceLongitude, "ff 80 00 00"},                  // float -infinity
      {Eg0104Field::kDeviceAltitude, "7f f0 00 00 00 00 00 00"},       // double +infinity
      {Eg0104Field::kFrameCenterLatitude, "7f f8 00 00 00 00 00 01"},  // double NaN
      {Eg0104Field::kFrameCenterLongitude, "7f 80 00 01"},             // float signalling NaN
  };
  std::vector<uint8_t> value;
  for (const auto& c : cases) {
    const UniversalKey key = Eg0104FieldKey(c.field);
    value.insert(value.end(), key.bytes.begin(), key.bytes.end());
    const std::vector<uint8_t> raw = HexBytes(c.raw);
    value.push_back(static_cast<uint8_t>(raw.size()));
    value = Concat(value, raw);
  }
  const DecodedPacket decoded = DecodePacket(MakePacket(kEg0104Key, value));
  ASSERT_TRUE(decoded.status.ok()) << decoded.status.ToString();
  ASSERT_TRUE(decoded.eg0104.has_value());
  for (const auto& item : decoded.eg0104->items) {
    EXPECT_FALSE(std::holds_alternative<double>(item.value)) << item.name;
  }
  ASSERT_TRUE(decoded.metadata.has_value());
  EXPECT_FALSE(decoded.metadata->sensor_latitude_deg.has_value());
  EXPECT_FALSE(decoded.metadata->sensor_longitude_deg.has_value());
  EXPECT_FALSE(decoded.metadata->sensor_altitude_m.has_value());
  EXPECT_FALSE(decoded.metadata->frame_center.has_value());
  EXPECT_FALSE(ToJson(decoded).dump().empty());
}

}  // namespace
}  // namespace saker::klv
