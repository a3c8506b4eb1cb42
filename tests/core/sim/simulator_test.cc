// The whole simulator against its own truth: determinism, homographies that really map the
// ground into the frames, targets where the truth says, KLV that decodes to the truth.

#include "core/sim/simulator.h"

#include "core/geo/local_tangent_plane.h"
#include "core/ingest/video_scan.h"
#include "core/klv/klv.h"
#include "core/klv/st0601.h"
#include "core/sim/truth.h"
#include "core/video/video_reader.h"
#include "tests/core/sim/sim_test_support.h"
#include "tests/testing/test_data.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <fstream>
#include <sstream>

namespace saker::sim {
namespace {

class SimulatorTest : public ::testing::Test {
 protected:
  std::filesystem::path dir_ = saker::testing::MakeTempDir("saker-sim");
};

TEST_F(SimulatorTest, SameSeedGivesIdenticalTruthAndFrames) {
  SimulationOptions a = SmallOptions(dir_ / "a.ts"), b = SmallOptions(dir_ / "b.ts"),
                    c = SmallOptions(dir_ / "c.ts");
  c.seed = 2;
  for (const auto* options : {&a, &b, &c}) {
    StatusOr<SimulationSummary> summary = Simulate(*options);
    ASSERT_TRUE(summary.ok()) << summary.status().ToString();
    EXPECT_EQ(summary->frames, 20);
  }
  std::string truth_a = ReadText(dir_ / "a.truth.json"), truth_b = ReadText(dir_ / "b.truth.json");
  // The generator records the output name; everything else must match bit for bit.
  const auto strip = [](std::string s, const std::string& name) {
    for (size_t at = s.find(name); at != std::string::npos; at = s.find(name))
      s.erase(at, name.size());
    return s;
  };
  EXPECT_EQ(strip(truth_a, "a.ts"), strip(truth_b, "b.ts"));
  EXPECT_NE(truth_a, ReadText(dir_ / "c.truth.json"));
  const std::vector<cv::Mat> fa = DecodeAll(dir_ / "a.ts"), fb = DecodeAll(dir_ / "b.ts");
  ASSERT_EQ(fa.size(), 20u);
  ASSERT_EQ(fb.size(), 20u);
  for (size_t i = 0; i < fa.size(); ++i)
    EXPECT_EQ(cv::norm(fa[i], fb[i], cv::NORM_INF), 0) << "frame " << i;
}

TEST_F(SimulatorTest, TruthHomographyMapsTheFrameOntoTheGround) {
  const SimulationOptions options = SmallOptions(dir_ / "h.ts");
  ASSERT_TRUE(Simulate(options).ok());
  StatusOr<SimulationSetup> setup = SimulationSetup::Create(options);
  ASSERT_TRUE(setup.ok());
  StatusOr<Truth> truth = ReadTruth(options.TruthPath());
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();
  ASSERT_EQ(truth->frames.size(), 20u);
  const std::vector<cv::Mat> frames = DecodeAll(options.output);
  ASSERT_EQ(frames.size(), 20u);
  for (int64_t i : {0, 9, 19}) {
    const double ncc = GroundCorrelation(*setup, *truth, i, frames[static_cast<size_t>(i)],
                                         truth->frames[static_cast<size_t>(i)].frame_from_ground);
    EXPECT_GT(ncc, 0.85) << "frame " << i;
  }
  // The check can fail: another frame's homography (1.5 m further on) does not fit.
  const double wrong =
      GroundCorrelation(*setup, *truth, 0, frames[0], truth->frames[10].frame_from_ground);
  EXPECT_LT(wrong, 0.5);
}

TEST_F(SimulatorTest, TargetImagePositionsLandOnTheDrawnTargets) {
  SimulationOptions options = SmallOptions(dir_ / "t.ts");
  options.targets.cars = 150;  // crowd the roads so the short clip sees plenty
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 200;
  options.imaging.noise_sigma = 0;
  ASSERT_TRUE(Simulate(options).ok());
  StatusOr<SimulationSetup> setup = SimulationSetup::Create(options);
  StatusOr<Truth> truth = ReadTruth(options.TruthPath());
  ASSERT_TRUE(setup.ok() && truth.ok());
  const std::vector<cv::Mat> frames = DecodeAll(options.output);
  const FrameRenderer renderer(setup->ground(), options.camera, options.imaging, options.seed);
  int checked = 0, on_target = 0, off_target = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Eigen::Matrix3d& h = truth->frames[i].frame_from_ground;
    const cv::Mat ground_only = renderer.RenderGround(h);
    cv::Mat difference;
    cv::absdiff(frames[i], ground_only, difference);
    cv::cvtColor(difference, difference, cv::COLOR_BGR2GRAY);
    for (const TargetTruth& t : truth->targets) {
      const TargetSampleTruth& s = t.samples[i];
      if (!s.visible || t.target_class == "person") continue;
      const cv::Rect inner(8, 8, options.camera.width - 16, options.camera.height - 16);
      const cv::Point at(static_cast<int>(std::lround(s.image_px.x())),
                         static_cast<int>(std::lround(s.image_px.y())));
      if (!inner.contains(at)) continue;
      ++checked;
      on_target += cv::mean(difference(cv::Rect(at.x - 1, at.y - 1, 3, 3)))[0] > 12;
      // 4 m to the side of the vehicle is road or verge, unchanged.
      const Eigen::Vector2d side =
          s.ground_m + Eigen::Vector2d(-s.velocity_mps.y(), s.velocity_mps.x()).normalized() * 4.0;
      const Eigen::Vector2d q = (h * side.homogeneous()).hnormalized();
      const cv::Point off(static_cast<int>(std::lround(q.x())),
                          static_cast<int>(std::lround(q.y())));
      if (inner.contains(off) && s.velocity_mps.norm() > 0.5) {
        off_target += cv::mean(difference(cv::Rect(off.x - 1, off.y - 1, 3, 3)))[0] > 12;
      }
    }
  }
  ASSERT_GT(checked, 15);
  EXPECT_GT(on_target, 0.9 * checked);
  EXPECT_LT(off_target, 0.3 * checked);
}

TEST_F(SimulatorTest, KlvCornersDecodeToTheTruthWithinTheNoise) {
  for (double noise : {0.0, 5.0}) {
    SimulationOptions options =
        SmallOptions(dir_ / ("k" + std::to_string(static_cast<int>(noise)) + ".ts"));
    options.metadata.position_noise_m = noise;
    options.duration_s = 4;
    ASSERT_TRUE(Simulate(options).ok());
    StatusOr<Truth> truth = ReadTruth(options.TruthPath());
    ingest::ScanOptions scan_options;
    StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(options.output.string(), scan_options);
    ASSERT_TRUE(scan.ok()) << scan.status().ToString();
    ASSERT_EQ(scan->frames.size(), truth->frames.size());
    StatusOr<geo::LocalTangentPlane> plane = geo::LocalTangentPlane::Create(options.origin);
    double sum_squared = 0, worst = 0;
    int n = 0;
    for (size_t i = 0; i < scan->frames.size(); ++i) {
      const klv::FrameMetadata* metadata = scan->MetadataOf(i);
      ASSERT_NE(metadata, nullptr) << "frame " << i;
      ASSERT_TRUE(metadata->corners.has_value());
      const Eigen::Matrix3d ground_from_frame = truth->frames[i].frame_from_ground.inverse();
      const auto image_corners = ImageCorners(options.camera);
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d truth_corner =
            (ground_from_frame * image_corners[k].homogeneous()).hnormalized();
        const Eigen::Vector2d decoded = plane->MapFromLatLon((*metadata->corners)[k].latitude_deg,
                                                             (*metadata->corners)[k].longitude_deg);
        const double e = (decoded - truth_corner).norm();
        sum_squared += e * e;
        worst = std::max(worst, e);
        ++n;
      }
    }
    const double rms_per_axis = std::sqrt(sum_squared / n / 2);
    if (noise == 0) {
      EXPECT_LT(worst, 0.05) << "corners are encoded to a few millimetres";
    } else {
      EXPECT_NEAR(rms_per_axis, noise, 0.25 * noise);
    }
  }
}

TEST_F(SimulatorTest, MetadataRateOnlyFramesAndNone) {
  const auto packets_on = [&](SimulationOptions options) {
    EXPECT_TRUE(Simulate(options).ok());
    std::vector<int64_t> frames;
    const StatusOr<Truth> truth = ReadTruth(options.TruthPath());
    EXPECT_TRUE(truth.ok());
    if (!truth.ok()) return frames;
    for (const FrameTruth& f : truth->frames) {
      if (f.klv) frames.push_back(f.index);
    }
    return frames;
  };
  SimulationOptions every4 = SmallOptions(dir_ / "every4.ts");
  every4.metadata.every_n_frames = 4;
  EXPECT_EQ(packets_on(every4), (std::vector<int64_t>{0, 4, 8, 12, 16}));
  SimulationOptions chosen = SmallOptions(dir_ / "chosen.ts");
  chosen.metadata.only_frames = {3, 7, 500};
  EXPECT_EQ(packets_on(chosen), (std::vector<int64_t>{3, 7}));
  SimulationOptions none = SmallOptions(dir_ / "none.ts");
  none.metadata.every_n_frames = 0;
  EXPECT_TRUE(packets_on(none).empty());
  StatusOr<ingest::VideoScan> scan = ingest::ScanVideo(none.output.string(), {});
  ASSERT_TRUE(scan.ok());
  EXPECT_TRUE(scan->klv_streams.empty());
  SimulationOptions dropouts = SmallOptions(dir_ / "drop.ts");
  dropouts.duration_s = 10;
  dropouts.metadata.dropout_probability = 0.5;
  const size_t kept = packets_on(dropouts).size();
  EXPECT_GT(kept, 25u);
  EXPECT_LT(kept, 75u);
}

TEST_F(SimulatorTest, BlankIntervalHidesTheGround) {
  SimulationOptions options = SmallOptions(dir_ / "blank.ts");
  options.imaging.blank_start_s = 0.5;
  options.imaging.blank_duration_s = 1.0;
  options.imaging.noise_sigma = 0;  // so "featureless" is measurable
  ASSERT_TRUE(Simulate(options).ok());
  StatusOr<Truth> truth = ReadTruth(options.TruthPath());
  const std::vector<cv::Mat> frames = DecodeAll(options.output);
  ASSERT_EQ(frames.size(), 20u);
  for (size_t i = 0; i < frames.size(); ++i) {
    const bool blank = i >= 5 && i < 15;
    EXPECT_EQ(truth->frames[i].blank, blank) << i;
    cv::Mat grey, edges;
    cv::cvtColor(frames[i], grey, cv::COLOR_BGR2GRAY);
    cv::Laplacian(grey, edges, CV_32F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(edges, mean, stddev);
    if (blank) {
      EXPECT_LT(stddev[0], 3) << "frame " << i;
    } else {
      EXPECT_GT(stddev[0], 6) << "frame " << i;
    }
    if (blank) {
      for (const TargetTruth& t : truth->targets) EXPECT_FALSE(t.samples[i].visible);
    }
  }
}

TEST_F(SimulatorTest, CancelLeavesNoFiles) {
  SimulationOptions options = SmallOptions(dir_ / "cancelled.ts");
  JobContext job([&](const std::string&, double fraction) {
    if (fraction > 0.3) job.RequestCancel();
  });
  StatusOr<SimulationSummary> summary = Simulate(options, &job);
  ASSERT_FALSE(summary.ok());
  EXPECT_EQ(summary.status().code(), StatusCode::kCancelled);
  EXPECT_TRUE(std::filesystem::is_empty(dir_)) << "partial output left behind";
}

TEST_F(SimulatorTest, ClearErrors) {
  SimulationOptions options = SmallOptions(dir_ / "no" / "such" / "dir" / "x.ts");
  StatusOr<SimulationSummary> summary = Simulate(options);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("no/such/dir"), std::string::npos)
      << summary.status().message();
  options = SmallOptions(dir_ / "long.ts");
  options.duration_s = 3600;
  summary = Simulate(options);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("lasts"), std::string::npos)
      << summary.status().message();
  options = SmallOptions(dir_ / "odd.ts");
  options.camera.width = 321;
  EXPECT_FALSE(Simulate(options).ok());
  options = SmallOptions(dir_ / "ortho.ts");
  options.ground_image = dir_ / "missing.png";
  options.ground_gsd_m = 0.3;
  options.scenario = Scenario::kStraight;
  summary = Simulate(options);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("missing.png"), std::string::npos)
      << summary.status().message();
}

TEST_F(SimulatorTest, OrthophotoGround) {
  SAKER_REQUIRE_TEST_DATA(ortho, "imagery/odm_aukerman_orthomosaic.png");
  SimulationOptions options = SmallOptions(dir_ / "ortho.ts");
  options.ground_image = ortho;
  options.ground_gsd_m = 0.3;
  options.ground_nodata_bgr = cv::Vec3b(255, 255, 255);
  options.scenario = Scenario::kStraight;
  options.flight.straight_length_m = 60;
  options.flight.altitude_m = 150;
  ASSERT_TRUE(Simulate(options).ok());
  StatusOr<SimulationSetup> setup = SimulationSetup::Create(options);
  StatusOr<Truth> truth = ReadTruth(options.TruthPath());
  ASSERT_TRUE(setup.ok() && truth.ok());
  EXPECT_TRUE(truth->targets.empty());
  const std::vector<cv::Mat> frames = DecodeAll(options.output);
  ASSERT_FALSE(frames.empty());
  EXPECT_GT(GroundCorrelation(*setup, *truth, 0, frames[0], truth->frames[0].frame_from_ground),
            0.85);
}

}  // namespace
}  // namespace saker::sim

namespace saker::sim {
namespace {

// The KLV of one frame, decoded again with Saker's own decoder.
klv::St0601Set FrameKlv(const CameraIntrinsics& camera, const CameraPose& pose,
                        double ground_height_m) {
  StatusOr<geo::LocalTangentPlane> plane =
      geo::LocalTangentPlane::Create({51.15, -1.75, ground_height_m});
  EXPECT_TRUE(plane.ok());
  const auto footprint = GroundFootprint(camera, pose);
  const auto centre = GroundCentre(camera, pose);
  EXPECT_TRUE(footprint && centre);
  StatusOr<std::vector<uint8_t>> bytes = EncodeFrameKlv(
      *plane, 1790000000000000, camera, pose, pose.position_m, *centre, *footprint, "TEST");
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  if (!bytes.ok()) return {};
  const std::vector<klv::KlvPacket> packets = klv::SplitKlvPackets(*bytes).packets;
  EXPECT_EQ(packets.size(), 1u);
  StatusOr<klv::St0601Set> set = klv::DecodeSt0601(packets.at(0));
  EXPECT_TRUE(set.ok() && set->checksum_ok);
  return set.ok() ? *set : klv::St0601Set{};
}

TEST(EncodeFrameKlvTest, HeightsAndWidthOfAnOrdinaryFrame) {
  CameraPose pose;
  pose.position_m = {10, 20, 400};
  const klv::St0601Set set = FrameKlv(CameraIntrinsics(), pose, 100);
  EXPECT_NEAR(*set.GetDouble(75), 500, 0.5);  // sensor above the ellipsoid
  EXPECT_NEAR(*set.GetDouble(78), 100, 0.5);  // frame centre above the ellipsoid
  EXPECT_NEAR(*set.GetDouble(15), 500, 0.5);
  EXPECT_NEAR(*set.GetDouble(22), 1280 * NadirGsd(CameraIntrinsics(), 400), 0.5);
  EXPECT_TRUE(set.Find(26) != nullptr);
}

TEST(EncodeFrameKlvTest, WideFootprintsLeaveOutWhatDoesNotFit) {
  // 14 km wide: beyond target width's 10 km and the offset corners' 0.075 degrees.
  CameraIntrinsics camera;
  camera.width = 64, camera.height = 48, camera.hfov_deg = 100;
  CameraPose pose;
  pose.position_m = {0, 0, 6000};
  const klv::St0601Set set = FrameKlv(camera, pose, 100);
  EXPECT_EQ(set.Find(22), nullptr);
  EXPECT_EQ(set.Find(26), nullptr);
  EXPECT_TRUE(set.Find(82) != nullptr);
}

TEST(EncodeFrameKlvTest, HeightsOutsideTheKlvRangeAreRefusedUpFront) {
  SimulationOptions options = SmallOptions("/tmp/unused.ts");
  options.origin.height_m = 18900;
  const Status status = options.Validate();
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("19000"), std::string::npos) << status.message();
}

}  // namespace
}  // namespace saker::sim
