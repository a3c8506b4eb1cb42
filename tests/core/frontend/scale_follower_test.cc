// The ground's scale of each frame from the KLV corners carried before it.

#include "core/frontend/scale_follower.h"

#include <gtest/gtest.h>

#include <cmath>

namespace saker::frontend {
namespace {

constexpr int kWidth = 641, kHeight = 481;

// A trusted ST 0601 packet at `byte_pos` whose corners make a north-up nadir footprint of
// kWidth x kHeight pixels at `metres_per_pixel`, at 45 degrees north (111 131.75 m a degree of
// latitude, 78 846.84 m of longitude).
ingest::MetadataPacket Packet(int64_t byte_pos, double metres_per_pixel, bool trusted = true) {
  const double e = (kWidth - 1) * metres_per_pixel / 2, n = (kHeight - 1) * metres_per_pixel / 2;
  const double east[4] = {-e, e, e, -e}, north[4] = {n, n, -n, -n};
  klv::FrameMetadata metadata;
  std::array<klv::LatLon, 4> corners;
  for (size_t i = 0; i < 4; ++i) {
    corners[i].latitude_deg = 45 + north[i] / 111131.75;
    corners[i].longitude_deg = 7 + east[i] / 78846.84;
  }
  metadata.corners = corners;
  ingest::MetadataPacket packet;
  packet.byte_pos = byte_pos;
  packet.decoded.metadata = metadata;
  packet.trusted = trusted;
  return packet;
}

double ScaleOf(const std::optional<track::GroundScale>& scale) {
  return scale ? scale->MetresPerPixel(Eigen::Vector2d(320, 240)) : -1;
}

TEST(ScaleFollowerTest, AFrameTakesThePacketCarriedBeforeIt) {
  ScaleFollower follower(25);
  EXPECT_FALSE(follower.ForFrame(50, kWidth, kHeight).has_value()) << "no packet yet";
  follower.AddPacket(Packet(100, 0.5));
  // Demuxed before the frame at 250 reaches the front end (the decoder's delay), carried after.
  follower.AddPacket(Packet(300, 1.0));
  EXPECT_NEAR(ScaleOf(follower.ForFrame(200, kWidth, kHeight)), 0.5, 1e-3);
  EXPECT_NEAR(ScaleOf(follower.ForFrame(250, kWidth, kHeight)), 0.5, 1e-3);
  EXPECT_NEAR(ScaleOf(follower.ForFrame(350, kWidth, kHeight)), 1.0, 1e-3);
  // A frame at a position unknown takes every packet so far.
  follower.AddPacket(Packet(400, 0.25));
  EXPECT_NEAR(ScaleOf(follower.ForFrame(-1, kWidth, kHeight)), 0.25, 1e-3);
  // Decoded at half the size: the same ground, pixels twice as large.
  EXPECT_NEAR(ScaleOf(follower.ForFrame(-1, 321, 241)), 0.5, 2e-3);
}

// A footprint across the antimeridian is whole: its corners are put on the tangent plane through
// Earth-centred coordinates.
TEST(ScaleFollowerTest, AFootprintAcrossTheAntimeridianHasItsScale) {
  ScaleFollower follower(25);
  ingest::MetadataPacket packet = Packet(100, 0.5);
  for (klv::LatLon& c : *packet.decoded.metadata->corners) {
    c.longitude_deg += 173;  // 7 + 173: the view's centre on the antimeridian
    if (c.longitude_deg > 180) c.longitude_deg -= 360;
  }
  follower.AddPacket(packet);
  EXPECT_NEAR(ScaleOf(follower.ForFrame(200, kWidth, kHeight)), 0.5, 1e-3);
}

TEST(ScaleFollowerTest, UntrustedCornerlessAndDegeneratePacketsArePassedOver) {
  ScaleFollower follower(25);
  follower.AddPacket(Packet(100, 0.5));
  follower.AddPacket(Packet(200, 2.0, /*trusted=*/false));
  ingest::MetadataPacket no_corners = Packet(300, 2.0);
  no_corners.decoded.metadata->corners.reset();
  follower.AddPacket(no_corners);
  ingest::MetadataPacket crossed = Packet(400, 2.0);
  std::swap((*crossed.decoded.metadata->corners)[2], (*crossed.decoded.metadata->corners)[3]);
  follower.AddPacket(crossed);
  ingest::MetadataPacket not_finite = Packet(500, 2.0);
  (*not_finite.decoded.metadata->corners)[1].latitude_deg = std::nan("");
  follower.AddPacket(not_finite);
  ingest::MetadataPacket undecoded = Packet(600, 2.0);
  undecoded.decoded.metadata.reset();
  follower.AddPacket(undecoded);
  EXPECT_NEAR(ScaleOf(follower.ForFrame(700, kWidth, kHeight)), 0.5, 1e-3);
}

// A damaged file's metadata with no picture after it is not all held: the follower keeps 1024
// packets waiting, and the latest of them still gives the next frame its scale.
TEST(ScaleFollowerTest, PacketsWithNoPictureAfterThemAreNotAllHeld) {
  ScaleFollower follower(25);
  EXPECT_FALSE(follower.ForFrame(10, kWidth, kHeight).has_value());
  for (int i = 0; i < 100000; ++i) follower.AddPacket(Packet(100 + i, i % 2 == 0 ? 0.5 : 1.0));
  EXPECT_EQ(follower.waiting(), 1024u);
  EXPECT_NEAR(ScaleOf(follower.ForFrame(1000000, kWidth, kHeight)), 1.0, 1e-3);
  EXPECT_EQ(follower.waiting(), 0u);
}

TEST(ScaleFollowerTest, CornersThatStopComingAreForgotten) {
  ScaleFollower follower(10, /*stale_s=*/2);
  follower.AddPacket(Packet(100, 0.5));
  for (int n = 1; n <= 20; ++n) {
    EXPECT_TRUE(follower.ForFrame(100 + 10 * n, kWidth, kHeight).has_value()) << "frame " << n;
  }
  EXPECT_FALSE(follower.ForFrame(400, kWidth, kHeight).has_value()) << "2 s without corners";
  follower.AddPacket(Packet(500, 1.0));
  EXPECT_NEAR(ScaleOf(follower.ForFrame(600, kWidth, kHeight)), 1.0, 1e-3);
}

}  // namespace
}  // namespace saker::frontend
