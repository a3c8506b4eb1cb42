#include "core/sim/camera.h"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace saker::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
double Tan(double degrees) { return std::tan(degrees * kPi / 180.0); }

Eigen::Vector2d Apply(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  return (h * p.homogeneous()).hnormalized();
}

// Pixel of a 3D ground-frame point by the textbook pinhole model, independent of FrameFromGround.
Eigen::Vector2d Project(const CameraIntrinsics& intrinsics, const CameraPose& pose,
                        const Eigen::Vector3d& world) {
  const Eigen::Vector3d camera = pose.WorldFromCamera().transpose() * (world - pose.position_m);
  EXPECT_GT(camera.z(), 0.0) << "point behind the camera";
  return (intrinsics.K() * camera).hnormalized();
}

TEST(CameraIntrinsicsTest, DefaultsGiveTwentyCentimetresAtFourHundredMetres) {
  const CameraIntrinsics intrinsics;
  ASSERT_TRUE(intrinsics.Validate().ok());
  EXPECT_NEAR(intrinsics.fx(), 640.0 / std::tan(17.75 * kPi / 180.0), 1e-9);
  EXPECT_EQ(intrinsics.fy(), intrinsics.fx());
  EXPECT_DOUBLE_EQ(intrinsics.cx(), 639.5);
  EXPECT_DOUBLE_EQ(intrinsics.cy(), 359.5);
  EXPECT_NEAR(NadirGsd(intrinsics, 400.0), 0.2, 0.001);
  EXPECT_NEAR(NadirGsd(intrinsics, 200.0), 0.5 * NadirGsd(intrinsics, 400.0), 1e-12);
  // Square pixels: the vertical field of view follows from the aspect ratio.
  EXPECT_NEAR(Tan(0.5 * intrinsics.vfov_deg()), Tan(17.75) * 720.0 / 1280.0, 1e-12);
  const Eigen::Matrix3d k = intrinsics.K();
  EXPECT_EQ(k(0, 0), intrinsics.fx());
  EXPECT_EQ(k(1, 1), intrinsics.fy());
  EXPECT_EQ(k(0, 2), 639.5);
  EXPECT_EQ(k(1, 2), 359.5);
  EXPECT_EQ(k(2, 2), 1.0);
  EXPECT_EQ(k(0, 1), 0.0);
}

TEST(CameraIntrinsicsTest, ValidateRejectsNonsense) {
  auto with = [](auto change) {
    CameraIntrinsics intrinsics;
    change(intrinsics);
    return intrinsics.Validate();
  };
  EXPECT_FALSE(with([](CameraIntrinsics& c) { c.width = 8; }).ok());
  EXPECT_FALSE(with([](CameraIntrinsics& c) { c.height = 10000; }).ok());
  EXPECT_FALSE(with([](CameraIntrinsics& c) { c.hfov_deg = 0.0; }).ok());
  EXPECT_FALSE(with([](CameraIntrinsics& c) { c.hfov_deg = 120.0; }).ok());
  EXPECT_FALSE(with([](CameraIntrinsics& c) { c.hfov_deg = NAN; }).ok());
  EXPECT_TRUE(with([](CameraIntrinsics& c) { c.width = c.height = 16; }).ok());
  const Status status = with([](CameraIntrinsics& c) { c.hfov_deg = 150.0; });
  EXPECT_NE(status.message().find("field of view 150"), std::string::npos) << status.message();
}

TEST(CameraPoseTest, WorldFromCameraIsARotation) {
  CameraPose pose;
  pose.heading_deg = 123.0;
  pose.pitch_deg = -7.0;
  pose.roll_deg = 11.0;
  const Eigen::Matrix3d r = pose.WorldFromCamera();
  EXPECT_TRUE((r.transpose() * r).isIdentity(1e-12));
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

TEST(CameraPoseTest, NadirHeadingZeroHasEastRightAndNorthUp) {
  const CameraIntrinsics intrinsics;
  const CameraPose pose;  // (0, 0, 400), level, heading north
  const Eigen::Matrix3d r = pose.WorldFromCamera();
  EXPECT_TRUE(r.col(0).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));   // image right: east
  EXPECT_TRUE(r.col(1).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));  // image down: south
  EXPECT_TRUE(r.col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));  // optical axis: down

  const Eigen::Matrix3d h = FrameFromGround(intrinsics, pose);
  const double gsd = NadirGsd(intrinsics, 400.0);
  const Eigen::Vector2d centre(intrinsics.cx(), intrinsics.cy());
  EXPECT_TRUE(Apply(h, {0, 0}).isApprox(centre, 1e-9));
  // 20 m east is 20 / gsd pixels to the right; 20 m north is as many pixels up.
  EXPECT_TRUE(Apply(h, {20, 0}).isApprox(centre + Eigen::Vector2d(20 / gsd, 0), 1e-9));
  EXPECT_TRUE(Apply(h, {0, 20}).isApprox(centre + Eigen::Vector2d(0, -20 / gsd), 1e-9));
}

TEST(CameraPoseTest, HeadingTurnsTheImageClockwise) {
  const CameraIntrinsics intrinsics;
  CameraPose pose;
  pose.position_m = {100, -50, 400};
  const Eigen::Vector2d centre(intrinsics.cx(), intrinsics.cy());
  const double step = 20 / NadirGsd(intrinsics, 400.0);

  pose.heading_deg = 90;  // nose east: image up is east, image right is south
  Eigen::Matrix3d h = FrameFromGround(intrinsics, pose);
  EXPECT_TRUE(Apply(h, {120, -50}).isApprox(centre + Eigen::Vector2d(0, -step), 1e-9));
  EXPECT_TRUE(Apply(h, {100, -70}).isApprox(centre + Eigen::Vector2d(step, 0), 1e-9));

  pose.heading_deg = 180;  // nose south: image up is south, image right is west
  h = FrameFromGround(intrinsics, pose);
  EXPECT_TRUE(Apply(h, {100, -70}).isApprox(centre + Eigen::Vector2d(0, -step), 1e-9));
  EXPECT_TRUE(Apply(h, {80, -50}).isApprox(centre + Eigen::Vector2d(step, 0), 1e-9));
}

TEST(CameraPoseTest, HomographyAgreesWithPinholeProjection) {
  CameraIntrinsics intrinsics;
  intrinsics.width = 640;
  intrinsics.height = 480;
  intrinsics.hfov_deg = 50;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    CameraPose pose;
    pose.position_m = {500 * unit(random), 500 * unit(random), 300 + 200 * unit(random)};
    pose.heading_deg = 180 * unit(random);
    pose.pitch_deg = 15 * unit(random);
    pose.roll_deg = 15 * unit(random);
    const Eigen::Matrix3d h = FrameFromGround(intrinsics, pose);
    EXPECT_NEAR(h(2, 2), 1.0, 1e-12);
    for (int i = 0; i < 5; ++i) {
      // Points around the nadir, all in front of the camera for these attitudes.
      const Eigen::Vector3d ground(pose.position_m.x() + 100 * unit(random),
                                   pose.position_m.y() + 100 * unit(random), 0.0);
      const Eigen::Vector2d expected = Project(intrinsics, pose, ground);
      EXPECT_LT((Apply(h, ground.head<2>()) - expected).norm(), 1e-6) << "trial " << trial;
    }
  }
}

TEST(CameraPoseTest, FootprintIsTheGroundOfTheImageCorners) {
  const CameraIntrinsics intrinsics;
  const auto corners = ImageCorners(intrinsics);
  EXPECT_EQ(corners[0], Eigen::Vector2d(-0.5, -0.5));
  EXPECT_EQ(corners[1], Eigen::Vector2d(1279.5, -0.5));
  EXPECT_EQ(corners[2], Eigen::Vector2d(1279.5, 719.5));
  EXPECT_EQ(corners[3], Eigen::Vector2d(-0.5, 719.5));

  // Nadir, heading north: a 256 x 144 m rectangle centred under the camera, corner 1 north-west.
  CameraPose pose;
  pose.position_m = {1000, 2000, 400};
  auto footprint = GroundFootprint(intrinsics, pose);
  ASSERT_TRUE(footprint.has_value());
  const double half_w = 0.5 * 1280 * NadirGsd(intrinsics, 400);
  const double half_h = 0.5 * 720 * NadirGsd(intrinsics, 400);
  EXPECT_TRUE((*footprint)[0].isApprox(Eigen::Vector2d(1000 - half_w, 2000 + half_h), 1e-12));
  EXPECT_TRUE((*footprint)[1].isApprox(Eigen::Vector2d(1000 + half_w, 2000 + half_h), 1e-12));
  EXPECT_TRUE((*footprint)[2].isApprox(Eigen::Vector2d(1000 + half_w, 2000 - half_h), 1e-12));
  EXPECT_TRUE((*footprint)[3].isApprox(Eigen::Vector2d(1000 - half_w, 2000 - half_h), 1e-12));

  // Any attitude: the homography takes each footprint corner back to its image corner, and the
  // ground centre to the principal point.
  pose.heading_deg = 250;
  pose.pitch_deg = 12;
  pose.roll_deg = -9;
  footprint = GroundFootprint(intrinsics, pose);
  ASSERT_TRUE(footprint.has_value());
  const Eigen::Matrix3d h = FrameFromGround(intrinsics, pose);
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT((Apply(h, (*footprint)[i]) - corners[i]).norm(), 1e-6) << "corner " << i + 1;
  }
  const auto centre = GroundCentre(intrinsics, pose);
  ASSERT_TRUE(centre.has_value());
  EXPECT_LT((Apply(h, *centre) - Eigen::Vector2d(intrinsics.cx(), intrinsics.cy())).norm(), 1e-6);
  const auto pixel = GroundPointOfPixel(intrinsics, pose, {100, 600});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_LT((Apply(h, *pixel) - Eigen::Vector2d(100, 600)).norm(), 1e-6);
}

TEST(CameraPoseTest, PitchUpMovesTheFootprintForwardAndRollRightMovesItLeft) {
  const CameraIntrinsics intrinsics;
  CameraPose pose;
  pose.position_m = {0, 0, 400};
  pose.pitch_deg = 10;
  EXPECT_TRUE(GroundCentre(intrinsics, pose)->isApprox(Eigen::Vector2d(0, 400 * Tan(10)), 1e-12));
  pose.heading_deg = 90;  // forward is east
  EXPECT_TRUE(GroundCentre(intrinsics, pose)->isApprox(Eigen::Vector2d(400 * Tan(10), 0), 1e-12));

  pose.pitch_deg = 0;
  pose.roll_deg = 10;  // nose east, right wing (south) down: looks north, the pilot's left
  EXPECT_TRUE(GroundCentre(intrinsics, pose)->isApprox(Eigen::Vector2d(0, 400 * Tan(10)), 1e-12));
  pose.heading_deg = 0;  // nose north: left is west
  EXPECT_TRUE(GroundCentre(intrinsics, pose)->isApprox(Eigen::Vector2d(-400 * Tan(10), 0), 1e-12));

  // Order of rotations: yaw, then pitch, then roll (the roll axis is the pitched nose), so the
  // roll offset is stretched by 1 / cos(pitch) and the pitch offset is not.
  pose.pitch_deg = 10;
  pose.roll_deg = 5;
  const double cos_pitch = std::cos(10 * kPi / 180);
  EXPECT_TRUE(GroundCentre(intrinsics, pose)
                  ->isApprox(Eigen::Vector2d(-400 * Tan(5) / cos_pitch, 400 * Tan(10)), 1e-12));
}

TEST(CameraPoseTest, RaysAtOrAboveTheHorizonHaveNoGroundPoint) {
  const CameraIntrinsics intrinsics;  // vertical field of view about 20.5 degrees
  CameraPose pose;
  pose.pitch_deg = 80;  // optical axis 10 degrees below the horizon, top edge just above it
  EXPECT_FALSE(GroundFootprint(intrinsics, pose).has_value());
  const auto centre = GroundCentre(intrinsics, pose);
  ASSERT_TRUE(centre.has_value());
  EXPECT_NEAR(centre->y(), 400 / Tan(10), 1e-9);
  EXPECT_FALSE(GroundPointOfPixel(intrinsics, pose, {639.5, -0.5}).has_value());
  EXPECT_TRUE(GroundPointOfPixel(intrinsics, pose, {639.5, 719.5}).has_value());

  pose.pitch_deg = 89;  // axis 1 degree below the horizon: too shallow to trust
  EXPECT_FALSE(GroundCentre(intrinsics, pose).has_value());
  pose.pitch_deg = 120;  // looking up and backwards
  EXPECT_FALSE(GroundCentre(intrinsics, pose).has_value());
  pose.pitch_deg = 0;
  pose.roll_deg = -95;
  EXPECT_FALSE(GroundFootprint(intrinsics, pose).has_value());

  pose = CameraPose();
  pose.position_m.z() = 0;  // on the ground
  EXPECT_FALSE(GroundFootprint(intrinsics, pose).has_value());
  pose.position_m.z() = -10;
  EXPECT_FALSE(GroundCentre(intrinsics, pose).has_value());
}

// The renderer recovers the camera from the ground homography alone (for the sky and the haze):
// its position, and the depression of every pixel's ray, whatever the matrix's scale and sign.
TEST(CameraPoseTest, ViewOfHomographyRecoversTheCameraAndItsRays) {
  const CameraIntrinsics intrinsics;
  CameraPose pose;
  pose.position_m = Eigen::Vector3d(120, -40, 150);
  pose.heading_deg = 37;
  pose.roll_deg = 3;
  pose.gimbal_off_nadir_deg = 82;  // the top of the frame above the horizon
  const Eigen::Matrix3d h = FrameFromGround(intrinsics, pose);
  for (const double scale : {1.0, -3.7, 1e-3}) {
    SCOPED_TRACE(scale);
    const std::optional<ViewGeometry> view = ViewOfHomography(intrinsics, scale * h);
    ASSERT_TRUE(view.has_value());
    EXPECT_LT((view->position_m - pose.position_m).norm(), 1e-6);
    for (const Eigen::Vector2d& pixel :
         {Eigen::Vector2d(0, 0), Eigen::Vector2d(640, 360), Eigen::Vector2d(1279, 719)}) {
      const Eigen::Vector3d ray =
          pose.WorldFromCamera() * Eigen::Vector3d((pixel.x() - intrinsics.cx()) / intrinsics.fx(),
                                                   (pixel.y() - intrinsics.cy()) / intrinsics.fy(),
                                                   1);
      EXPECT_NEAR(view->SinDepression(pixel.x(), pixel.y()), -ray.normalized().z(), 1e-9);
    }
    EXPECT_LT(view->SinDepression(640, 0), 0);  // above the horizon
    const std::optional<Eigen::Vector2d> below = GroundCentre(intrinsics, pose);
    ASSERT_TRUE(below.has_value());
    EXPECT_GT(view->depth_of_ground.dot(below->homogeneous()), 0);  // in front, whatever the sign
  }
  // A matrix that is no camera's.
  EXPECT_FALSE(ViewOfHomography(intrinsics, Eigen::Matrix3d::Zero()).has_value());
}

// What a view reaching the horizon sees, to size the simulated world: its border's rays cut at
// the draw distance; nothing when the camera sees no ground at all.
TEST(CameraPoseTest, TheVisibleGroundOfAViewReachingTheHorizonEndsAtTheDrawDistance) {
  const CameraIntrinsics intrinsics;
  CameraPose pose;
  pose.position_m = Eigen::Vector3d(0, 0, 100);
  pose.gimbal_off_nadir_deg = 85;  // looking north, the horizon in the upper part of the frame
  const std::vector<Eigen::Vector2d> outline = VisibleGroundOutline(intrinsics, pose, 8);
  ASSERT_FALSE(outline.empty());
  double nearest = 1e300, farthest = 0;
  for (const Eigen::Vector2d& p : outline) {
    nearest = std::min(nearest, p.norm());
    farthest = std::max(farthest, p.norm());
    EXPECT_GT(p.y(), 0);  // ahead
  }
  EXPECT_NEAR(farthest, 800, 1e-6);
  // The bottom edge, 85 - 10.3 degrees off nadir (the lens's half vertical field of view).
  EXPECT_NEAR(nearest, 100 * Tan(85 - intrinsics.vfov_deg() / 2), 1.0);
  pose.gimbal_off_nadir_deg = 0;
  pose.pitch_deg = 130;  // looking up and back: sky only
  EXPECT_TRUE(VisibleGroundOutline(intrinsics, pose, 8).empty());
}

}  // namespace
}  // namespace saker::sim
