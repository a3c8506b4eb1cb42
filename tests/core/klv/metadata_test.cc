// FrameMetadata from ST 0601: field selection, corners from full corners or
// from offsets, and the relative pointing conversion used for EG 0104.

#include "core/klv/metadata.h"

#include "core/klv/decode.h"
#include "tests/core/klv/klv_test_util.h"
#include "tests/core/klv/ts_extract.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <random>

namespace saker::klv {
namespace {

using testing::HexBytes;
using testing::MakeSt0601Packet;

// Frame centre and offset corners of the ST 0601.11 example (klvdata test
// vectors), with the absolute corners they were built from.
const char kCentreAndOffsets[] =
    "1704F101A229 180414BC082B 1A02C06E 1B02CBE9 1C02D765 1D02E2E0 1E02EE5B 1F02F9D6 "
    "20020552 210210CD";
constexpr LatLon kOffsetCorners[4] = {{-10.579637999887, 29.1273677986333},
                                      {-10.5661816260963, 29.140824172424},
                                      {-10.5527275411938, 29.1542782573265},
                                      {-10.5392711674031, 29.1677346311172}};
// Full corners 82-89 of the same example.
const char kFullCorners[] =
    "5204F0F41244 530414B679B9 5404F0F8F87E 550414B8ECD6 5604F0FDDE81 570414BB5FD8 "
    "5804F102C4BB 590414BDD2F5";

FrameMetadata MetadataOf(const std::string& hex) {
  auto set = DecodeSt0601(MakeSt0601Packet(HexBytes(hex)));
  EXPECT_TRUE(set.ok());
  return ToFrameMetadata(*set);
}

TEST(FrameMetadataTest, H264FirstPacketUsesFullCorners) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h264_klv.ts");
  std::string error;
  const auto streams = testing::ExtractTsStreams(saker::testing::ReadFileBytes(path), &error);
  ASSERT_GE(streams.size(), 2u);
  ASSERT_FALSE(streams[1].units.empty());
  const auto split = SplitKlvPackets(streams[1].units[0]);
  ASSERT_EQ(split.packets.size(), 1u);
  const DecodedPacket decoded = DecodePacket(split.packets[0]);
  ASSERT_TRUE(decoded.metadata.has_value());
  const FrameMetadata& m = *decoded.metadata;
  EXPECT_EQ(m.standard, MetadataStandard::kSt0601);
  ASSERT_TRUE(m.HasCorners());
  EXPECT_NEAR((*m.corners)[0].latitude_deg, -10.5287284, 1e-7);
  EXPECT_NEAR((*m.corners)[0].longitude_deg, 29.1615504, 1e-7);
  EXPECT_NEAR((*m.corners)[2].latitude_deg, -10.553450817499986, 1e-7);
  ASSERT_TRUE(m.frame_center.has_value());
  EXPECT_NEAR(m.frame_center->latitude_deg, -10.5423886, 1e-7);
  EXPECT_NEAR(m.frame_center->longitude_deg, 29.1578901, 1e-7);
  EXPECT_EQ(*m.ls_version, 17u);
  EXPECT_TRUE(m.checksum_ok);
  EXPECT_EQ(*m.unix_time_us, 1224807209913000u);
  EXPECT_EQ(*m.mission_id, "MISSION01");
  EXPECT_EQ(*m.platform_designation, "MQ1-B");
  EXPECT_NEAR(*m.platform_pitch_deg, -0.4315251020861441, 1e-7) << "full-range tag 90";
  EXPECT_NEAR(*m.platform_roll_deg, 3.4058139815022304, 1e-7) << "full-range tag 91";
  EXPECT_NEAR(*m.platform_heading_deg, 159.97436484321355, 1e-9);
  EXPECT_NEAR(*m.sensor_altitude_m, 14190.719462882427, 1e-6);
  EXPECT_NEAR(*m.slant_range_m, 68590.98329874477, 1e-6);
  EXPECT_NEAR(*m.sensor_rel_elevation_deg, -168.79232483394085, 1e-7);
}

TEST(FrameMetadataTest, CornersFromOffsetsWhenFullCornersAreAbsent) {
  const FrameMetadata m = MetadataOf(kCentreAndOffsets);
  ASSERT_TRUE(m.HasCorners());
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    // One LSB of the offset (1.5e-6 deg) plus one of the centre.
    EXPECT_NEAR((*m.corners)[i].latitude_deg, kOffsetCorners[i].latitude_deg, 2e-6);
    EXPECT_NEAR((*m.corners)[i].longitude_deg, kOffsetCorners[i].longitude_deg, 2e-6);
  }
  EXPECT_TRUE(m.checksum_ok);
  EXPECT_FALSE(m.ls_version.has_value());
}

TEST(FrameMetadataTest, FullCornersWinOverOffsets) {
  const FrameMetadata m = MetadataOf(std::string(kCentreAndOffsets) + kFullCorners);
  ASSERT_TRUE(m.HasCorners());
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR((*m.corners)[i].latitude_deg, kOffsetCorners[i].latitude_deg, 1e-7) << i;
    EXPECT_NEAR((*m.corners)[i].longitude_deg, kOffsetCorners[i].longitude_deg, 1e-7) << i;
  }
  // Full corners that disagree with the offsets: taken as is, in order.
  const FrameMetadata full_only = MetadataOf(
      std::string(kCentreAndOffsets) +
      "5204 10000000 5304 20000000 5404 30000000 5504 40000000 5604 50000000 5704 60000000 "
      "5804 70000000 5904 7FFFFFFF");
  ASSERT_TRUE(full_only.HasCorners());
  const double lat_step = 180.0 / 4294967294.0, lon_step = 360.0 / 4294967294.0;
  EXPECT_NEAR((*full_only.corners)[0].latitude_deg, 0x10000000 * lat_step, 1e-12);
  EXPECT_NEAR((*full_only.corners)[1].longitude_deg, 0x40000000 * lon_step, 1e-12);
  EXPECT_NEAR((*full_only.corners)[3].latitude_deg, 0x70000000 * lat_step, 1e-12);
  EXPECT_DOUBLE_EQ((*full_only.corners)[3].longitude_deg, 180.0);
}

TEST(FrameMetadataTest, AbsentFullCornerFallsBackToOffsets) {
  // Corner 3 latitude carries the error indicator.
  std::string full = kFullCorners;
  full.replace(full.find("F0FDDE81"), 8, "80000000");
  const FrameMetadata m = MetadataOf(std::string(kCentreAndOffsets) + full);
  ASSERT_TRUE(m.HasCorners());
  EXPECT_NEAR((*m.corners)[2].latitude_deg, kOffsetCorners[2].latitude_deg, 2e-6);
  // Without offsets (or a centre) there are no corners at all.
  EXPECT_FALSE(MetadataOf(full).HasCorners());
  EXPECT_FALSE(MetadataOf("1A02C06E 1B02CBE9 1C02D765 1D02E2E0 1E02EE5B 1F02F9D6 20020552 210210CD")
                   .HasCorners());
  // An absent offset corner: no corners.
  std::string offsets = kCentreAndOffsets;
  offsets.replace(offsets.find("C06E"), 4, "8000");
  EXPECT_FALSE(MetadataOf(offsets).HasCorners());
}

TEST(FrameMetadataTest, PitchAndRollFallBackToShortTags) {
  const FrameMetadata m = MetadataOf("0602FD3D 070208B8 0502 71C2");
  EXPECT_NEAR(*m.platform_pitch_deg, -0.4315317239905987, 1e-12);
  EXPECT_NEAR(*m.platform_roll_deg, 3.4058656575212893, 1e-12);
  EXPECT_FALSE(m.sensor_latitude_deg.has_value());
  // Absent values stay absent.
  const FrameMetadata absent = MetadataOf("06028000 0D0480000000 0E045B5360C4");
  EXPECT_FALSE(absent.platform_pitch_deg.has_value());
  EXPECT_FALSE(absent.sensor_latitude_deg.has_value());
  EXPECT_TRUE(absent.sensor_longitude_deg.has_value());
}

TEST(FrameMetadataTest, BadChecksumIsCarriedOver) {
  auto packet = MakeSt0601Packet(HexBytes("0502 71C2"));
  packet.value.back() ^= 1;
  packet.bytes.back() ^= 1;
  const DecodedPacket decoded = DecodePacket(packet);
  ASSERT_TRUE(decoded.metadata.has_value());
  EXPECT_FALSE(decoded.metadata->checksum_ok);
  EXPECT_TRUE(decoded.metadata->platform_heading_deg.has_value()) << "still decoded";
}

TEST(RelativePointingTest, LevelPlatform) {
  RelativePointing rel = RelativeFromAbsolutePointing(90, 0, 0, 100, -30);
  EXPECT_NEAR(rel.azimuth_deg, 10, 1e-9);
  EXPECT_NEAR(rel.elevation_deg, -30, 1e-9);
  rel = RelativeFromAbsolutePointing(350, 0, 0, 10, 5);
  EXPECT_NEAR(rel.azimuth_deg, 20, 1e-9);
  rel = RelativeFromAbsolutePointing(10, 0, 0, 350, 5);
  EXPECT_NEAR(rel.azimuth_deg, 340, 1e-9) << "0..360";
}

TEST(RelativePointingTest, PitchAndRoll) {
  // Nose up 10 deg, looking along the horizon ahead: 10 deg below the nose.
  RelativePointing rel = RelativeFromAbsolutePointing(0, 10, 0, 0, 0);
  EXPECT_NEAR(rel.azimuth_deg, 0, 1e-9);
  EXPECT_NEAR(rel.elevation_deg, -10, 1e-9);
  // Right wing down 90 deg, looking straight down: out of the right wing.
  rel = RelativeFromAbsolutePointing(0, 0, 90, 0, -90);
  EXPECT_NEAR(rel.azimuth_deg, 90, 1e-6);
  EXPECT_NEAR(rel.elevation_deg, 0, 1e-6);
}

TEST(FrameMetadataJsonTest, OnlySetFields) {
  const FrameMetadata m = MetadataOf(std::string(kCentreAndOffsets) + "0302 4142");
  const auto json = FrameMetadataToJson(m);
  EXPECT_EQ(json.at("standard"), "ST 0601");
  EXPECT_EQ(json.at("mission_id"), "AB");
  EXPECT_EQ(json.at("corners").size(), 4u);
  EXPECT_TRUE(json.at("corners")[0].contains("latitude_deg"));
  EXPECT_TRUE(json.at("frame_center").contains("longitude_deg"));
  EXPECT_FALSE(json.contains("sensor_latitude_deg"));
  EXPECT_EQ(json.at("checksum_ok"), true);
  EXPECT_FALSE(json.dump().empty());
}

}  // namespace
}  // namespace saker::klv
