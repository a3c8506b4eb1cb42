// DecodePacket / ToJson: the single entry point over all packet kinds.

#include "core/klv/decode.h"

#include "tests/core/klv/klv_test_util.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

namespace saker::klv {
namespace {

using testing::HexBytes;
using testing::MakePacket;
using testing::MakeSt0601Packet;

TEST(DecodePacketTest, St0601) {
  const DecodedPacket decoded = DecodePacket(MakeSt0601Packet(HexBytes("0502 71C2 4101 11")));
  EXPECT_EQ(decoded.kind, PacketKind::kSt0601);
  EXPECT_TRUE(decoded.status.ok());
  ASSERT_TRUE(decoded.st0601.has_value());
  EXPECT_FALSE(decoded.eg0104.has_value());
  ASSERT_TRUE(decoded.metadata.has_value());
  EXPECT_EQ(*decoded.metadata->ls_version, 17u);
  EXPECT_EQ(decoded.key, kSt0601Key);
  EXPECT_EQ(decoded.length, 11u);
  EXPECT_TRUE(decoded.raw.empty());  // the decoded items hold the bytes

  const auto json = ToJson(decoded);
  EXPECT_EQ(json.at("kind"), "st0601");
  EXPECT_EQ(json.at("key"), "060e2b34 020b0101 0e010301 01000000");
  EXPECT_EQ(json.at("status"), "ok");
  EXPECT_EQ(json.at("length"), 11);
  ASSERT_EQ(json.at("items").size(), 3u);
  EXPECT_EQ(json.at("items")[0].at("name"), "Platform Heading Angle");
  EXPECT_NEAR(json.at("items")[0].at("value").get<double>(), 159.974, 0.006);
  EXPECT_EQ(json.at("items")[0].at("raw"), "71c2");
  EXPECT_EQ(json.at("checksum").at("ok"), true);
  EXPECT_TRUE(json.contains("metadata"));
  EXPECT_FALSE(json.contains("raw")) << "decoded packets list items instead";
}

TEST(DecodePacketTest, VersionByteIsIgnored) {
  UniversalKey key = kSt0601Key;
  key.bytes[kKeyVersionByte] = 0x0A;
  EXPECT_EQ(PacketKindOf(key), PacketKind::kSt0601);
  UniversalKey eg = kEg0104Key;
  eg.bytes[kKeyVersionByte] = 0x03;
  EXPECT_EQ(PacketKindOf(eg), PacketKind::kEg0104);
}

TEST(DecodePacketTest, St0903IsListedRaw) {
  SAKER_REQUIRE_TEST_DATA(path, "jmisb/st0903_vmti_example.bin");
  const auto split = SplitKlvPackets(saker::testing::ReadFileBytes(path));
  ASSERT_EQ(split.packets.size(), 5u) << "the file holds five consecutive VMTI sets";
  EXPECT_TRUE(split.errors.empty());
  for (const auto& packet : split.packets) {
    EXPECT_EQ(DecodePacket(packet).kind, PacketKind::kSt0903);
  }
  const DecodedPacket decoded = DecodePacket(split.packets[0]);
  EXPECT_EQ(decoded.kind, PacketKind::kSt0903);
  EXPECT_TRUE(decoded.status.ok());
  EXPECT_FALSE(decoded.metadata.has_value());
  EXPECT_EQ(decoded.raw, split.packets[0].value);
  const auto json = ToJson(decoded);
  EXPECT_EQ(json.at("kind"), "st0903");
  const std::string raw = json.at("raw");
  EXPECT_EQ(raw.size(), 2 * decoded.raw.size());
  // "Example Targeting System" is in there, hex encoded.
  EXPECT_NE(raw.find(BytesToHex(HexBytes("4578616d706c6520546172676574696e67"))),
            std::string::npos);
}

TEST(DecodePacketTest, UnknownKey) {
  UniversalKey key = kSt0601Key;
  key.bytes[12] = 0x7F;
  const DecodedPacket decoded = DecodePacket(MakePacket(key, HexBytes("01 02 03")));
  EXPECT_EQ(decoded.kind, PacketKind::kUnknown);
  EXPECT_TRUE(decoded.status.ok());
  EXPECT_EQ(ToJson(decoded).at("raw"), "010203");
  EXPECT_EQ(ToJson(decoded).at("kind"), "unknown");
}

TEST(DecodePacketTest, BrokenSetIsStillListed) {
  const DecodedPacket decoded = DecodePacket(MakePacket(kSt0601Key, HexBytes("02 85 00")));
  EXPECT_EQ(decoded.kind, PacketKind::kSt0601);
  EXPECT_FALSE(decoded.status.ok());
  EXPECT_EQ(decoded.status.code(), StatusCode::kInvalidData);
  EXPECT_FALSE(decoded.st0601.has_value());
  EXPECT_FALSE(decoded.metadata.has_value());
  const auto json = ToJson(decoded);
  EXPECT_NE(json.at("status").get<std::string>(), "ok");
  EXPECT_EQ(json.at("raw"), "028500");

  const DecodedPacket eg = DecodePacket(MakePacket(kEg0104Key, HexBytes("01 02 03")));
  EXPECT_EQ(eg.kind, PacketKind::kEg0104);
  EXPECT_FALSE(eg.status.ok());
}

TEST(DecodePacketTest, TextWithInvalidUtf8DumpsToJson) {
  const DecodedPacket decoded = DecodePacket(MakeSt0601Packet(HexBytes("0304 41ff0042")));
  ASSERT_TRUE(decoded.st0601.has_value());
  EXPECT_EQ(decoded.st0601->GetString(3)->size(), 4u) << "bytes kept as sent";
  const auto json = ToJson(decoded);
  EXPECT_NO_THROW(json.dump());
  EXPECT_EQ(json.at("items")[0].at("value").get<std::string>(), std::string("A\xEF\xBF\xBD\0B", 6));
  EXPECT_EQ(json.at("metadata").at("mission_id").get<std::string>().size(), 6u);
}

TEST(DecodePacketTest, KindNames) {
  EXPECT_STREQ(PacketKindId(PacketKind::kSt0601), "st0601");
  EXPECT_STREQ(PacketKindId(PacketKind::kEg0104), "eg0104");
  EXPECT_STREQ(PacketKindId(PacketKind::kSt0903), "st0903");
  EXPECT_STREQ(PacketKindId(PacketKind::kUnknown), "unknown");
  EXPECT_STREQ(PacketKindName(PacketKind::kSt0601), "ST 0601");
  EXPECT_STREQ(PacketKindName(PacketKind::kEg0104), "EG 0104");
}

}  // namespace
}  // namespace saker::klv
