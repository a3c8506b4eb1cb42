// The simulator's real-world conditions against their truth: oblique and orbiting views, a zoom,
// burned-in overlays, infrared looks, dropped, repeated and irregular frames, a cut, and the
// options as JSON (the accuracy corpus's manifest).

#include "core/geo/local_tangent_plane.h"
#include "core/sim/frame_renderer.h"
#include "core/sim/overlay.h"
#include "core/sim/simulator.h"
#include "core/sim/truth.h"
#include "tests/core/sim/sim_test_support.h"
#include "tests/testing/test_data.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <fstream>
#include <iostream>
#include <set>

namespace saker::sim {
namespace {

class ConditionsTest : public ::testing::Test {
 protected:
  // Simulates `options` and reads back its setup, truth and frames.
  void Run(const SimulationOptions& options) {
    const StatusOr<SimulationSummary> summary = Simulate(options);
    ASSERT_TRUE(summary.ok()) << summary.status().ToString();
    summary_ = *summary;
    StatusOr<SimulationSetup> setup = SimulationSetup::Create(options);
    ASSERT_TRUE(setup.ok()) << setup.status().ToString();
    setup_.emplace(std::move(*setup));
    StatusOr<Truth> truth = ReadTruth(options.TruthPath());
    ASSERT_TRUE(truth.ok()) << truth.status().ToString();
    truth_ = std::move(*truth);
    frames_ = DecodeAll(options.output);
    ASSERT_EQ(frames_.size(), truth_.frames.size());
  }

  std::filesystem::path dir_ = saker::testing::MakeTempDir("saker-conditions");
  SimulationSummary summary_;
  std::optional<SimulationSetup> setup_;
  Truth truth_;
  std::vector<cv::Mat> frames_;
};

TEST_F(ConditionsTest, ObliqueViewsShowTheGroundTheTruthSays) {
  struct Case {
    const char* name;
    double off_nadir, azimuth;
    double top_to_bottom;  // ground per pixel at the top edge against the bottom edge
  };
  for (const Case& c : {Case{"forward-30", 30, 0, 1.37}, Case{"right-50", 50, 90, 1.92}}) {
    SCOPED_TRACE(c.name);
    SimulationOptions options = SmallOptions(dir_ / (std::string(c.name) + ".ts"));
    options.flight.gimbal_off_nadir_deg = c.off_nadir;
    options.flight.gimbal_azimuth_deg = c.azimuth;
    ASSERT_NO_FATAL_FAILURE(Run(options));
    for (const FrameTruth& f : truth_.frames) {
      EXPECT_DOUBLE_EQ(f.gimbal_off_nadir_deg, c.off_nadir);
      EXPECT_DOUBLE_EQ(f.gimbal_azimuth_deg, c.azimuth);
    }
    // The optical axis meets the ground off nadir: ahead, or to the right of the track.
    const FrameTruth& first = truth_.frames[0];
    const Eigen::Vector2d centre =
        (first.frame_from_ground.inverse() * Eigen::Vector3d(159.5, 89.5, 1)).hnormalized();
    const Eigen::Vector2d offset = centre - first.position_m.head<2>();
    EXPECT_NEAR(offset.norm(), 100 * std::tan(c.off_nadir * M_PI / 180), 5.0);
    for (int64_t i : {0, 19}) {
      const double ncc = GroundCorrelation(*setup_, truth_, i, frames_[static_cast<size_t>(i)],
                                           truth_.frames[static_cast<size_t>(i)].frame_from_ground);
      EXPECT_GT(ncc, 0.75) << "frame " << i;
    }
    // The check can fail: the homography of a frame 1.5 s later does not fit.
    EXPECT_LT(
        GroundCorrelation(*setup_, truth_, 0, frames_[0], truth_.frames[15].frame_from_ground),
        0.5);
    // A pixel at the top edge spans more ground than one at the bottom: the square root of the
    // area it covers, 1.37 times at 30 degrees off nadir and 1.92 at 50 with this lens (the
    // figures docs/simulator.md quotes).
    const Eigen::Matrix3d ground_from_frame = first.frame_from_ground.inverse();
    const auto ground_per_pixel = [&](double y) {
      const auto at = [&](double px, double py) {
        return Eigen::Vector2d((ground_from_frame * Eigen::Vector3d(px, py, 1)).hnormalized());
      };
      const Eigen::Vector2d dx = at(160, y) - at(159, y),
                            dy = at(159.5, y + 0.5) - at(159.5, y - 0.5);
      return std::sqrt(std::abs(dx.x() * dy.y() - dx.y() * dy.x()));
    };
    EXPECT_NEAR(ground_per_pixel(0) / ground_per_pixel(179), c.top_to_bottom, 0.05);
  }
}

// A low oblique view, as a small drone's camera looks ahead: the top of the frame shows the sky
// above the horizon, the ground fades into haze towards it, and below that the frame shows the
// ground the truth homography says. No target is drawn, or counted visible, in the haze; the KLV
// leaves out the corners that miss the ground.
TEST_F(ConditionsTest, ALowObliqueViewShowsTheSkyAboveTheHorizonAndTheGroundBelow) {
  SimulationOptions options = SmallOptions(dir_ / "horizon.ts");
  options.flight.altitude_m = 30;
  options.flight.gimbal_off_nadir_deg = 82;  // the top edge 92.3 degrees off nadir
  options.flight.gimbal_azimuth_deg = 270;   // to the left, over the town
  options.targets.cars = 40;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  EXPECT_EQ(summary_.klv_packets, static_cast<int64_t>(truth_.frames.size()));
  const CameraIntrinsics& camera = options.camera;
  for (const int64_t i : {int64_t{0}, static_cast<int64_t>(truth_.frames.size()) - 1}) {
    SCOPED_TRACE(i);
    const FrameTruth& f = truth_.frames[static_cast<size_t>(i)];
    const cv::Mat& frame = frames_[static_cast<size_t>(i)];
    const std::optional<ViewGeometry> view = ViewOfHomography(camera, f.frame_from_ground);
    ASSERT_TRUE(view.has_value());
    // The horizon's row at the centre column, and the sky a few rows above it: brighter and bluer
    // than the ground, and smooth.
    int horizon = 0;
    while (horizon < camera.height && view->SinDepression(159.5, horizon) < 0) ++horizon;
    ASSERT_GT(horizon, 3);
    ASSERT_LT(horizon, camera.height / 2);
    const cv::Mat sky = frame.rowRange(0, horizon - 2);
    const cv::Scalar sky_mean = cv::mean(sky);
    EXPECT_GT(sky_mean[0], 150);              // bright
    EXPECT_GT(sky_mean[0], sky_mean[2] + 4);  // blue over red
    // Below: the ground of the truth's homography (the renderer's own picture of it, without the
    // targets and the noise), where it is not hazed.
    FrameRenderer renderer(setup_->ground(), camera, ImagingOptions{}, options.seed);
    renderer.SetCoarserLevels(setup_->coarser_ground());
    cv::Mat valid;
    const cv::Mat expected = renderer.RenderGround(f.frame_from_ground, &valid);
    EXPECT_EQ(cv::countNonZero(valid.rowRange(0, horizon + 1)), 0);
    EXPECT_EQ(cv::countNonZero(valid.row(camera.height - 1)), camera.width);
    EXPECT_GT(Ncc(frame, expected, valid), 0.9);
    // The truth counts a target visible only in front of the camera and short of the haze.
    for (const TargetTruth& t : truth_.targets) {
      const TargetSampleTruth& sample = t.samples[static_cast<size_t>(i)];
      if (!sample.visible) continue;
      EXPECT_GT(view->depth_of_ground.dot(sample.ground_m.homogeneous()), 0);
      EXPECT_LE((sample.ground_m - view->position_m.head<2>()).norm(),
                FrameRenderer::kHazeStartHeights * view->height_m() + 1e-6);
    }
  }
  // Some targets are seen, some are too far or behind.
  int64_t visible = 0, hidden = 0;
  for (const TargetTruth& t : truth_.targets) {
    for (const TargetSampleTruth& sample : t.samples) (sample.visible ? visible : hidden) += 1;
  }
  EXPECT_GT(visible, 0);
  EXPECT_GT(hidden, 0);
}

TEST_F(ConditionsTest, TheOrbitStaresAtTheCentre) {
  SimulationOptions options = SmallOptions(dir_ / "orbit.ts");
  options.scenario = Scenario::kOrbit;
  options.flight.orbit_radius_m = 100;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  StatusOr<SimulationSetup> setup = SimulationSetup::Create(options);
  ASSERT_TRUE(setup.ok());
  // The town centre stays near the image centre (the attitude wander moves it a little), seen
  // 45 degrees off nadir, while the platform flies round it.
  const Eigen::Vector2d stare = setup->world()->town_centre;
  for (const FrameTruth& f : truth_.frames) {
    const Eigen::Vector2d at = (f.frame_from_ground * stare.homogeneous()).hnormalized();
    EXPECT_LT((at - Eigen::Vector2d(159.5, 89.5)).norm(), 15.0) << "frame " << f.index;
    EXPECT_NEAR(f.gimbal_off_nadir_deg, 45.0, 1.0);
    EXPECT_NEAR((f.position_m.head<2>() - stare).norm(), 100.0, 0.5);
  }
  EXPECT_GT(
      GroundCorrelation(*setup_, truth_, 10, frames_[10], truth_.frames[10].frame_from_ground),
      0.75);
  EXPECT_LT(GroundCorrelation(*setup_, truth_, 0, frames_[0], truth_.frames[19].frame_from_ground),
            0.5);
}

TEST_F(ConditionsTest, AZoomChangesTheScaleAsTheTruthSays) {
  SimulationOptions options = SmallOptions(dir_ / "zoom.ts");
  options.zoom.start_s = 0.5;
  options.zoom.duration_s = 1.0;
  options.zoom.to_hfov_deg = options.camera.hfov_deg / 2;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  EXPECT_DOUBLE_EQ(truth_.frames[0].hfov_deg, options.camera.hfov_deg);
  EXPECT_NEAR(truth_.frames[19].hfov_deg, options.camera.hfov_deg / 2, 1e-9);
  // Pixels per metre double (the tangent of the half angle halves, near enough at 35 degrees).
  const auto scale = [&](const FrameTruth& f) {
    return std::sqrt(std::abs(f.frame_from_ground.topLeftCorner<2, 2>().determinant()));
  };
  EXPECT_NEAR(scale(truth_.frames[19]) / scale(truth_.frames[0]), 2.05, 0.1);
  for (int64_t i : {0, 10, 19}) {
    EXPECT_GT(GroundCorrelation(*setup_, truth_, i, frames_[static_cast<size_t>(i)],
                                truth_.frames[static_cast<size_t>(i)].frame_from_ground),
              0.8)
        << "frame " << i;
  }
}

TEST(OverlayPainterTest, EveryOverlayPixelLiesInsideTheTruthBoxes) {
  for (LogoMotion logo : {LogoMotion::kStatic, LogoMotion::kRotating, LogoMotion::kPulsing}) {
    OverlayOptions options;
    options.hud_text = true;
    options.reticle = true;
    options.logo = logo;
    const OverlayPainter painter(options, 640, 360);
    ASSERT_EQ(painter.regions().size(), 4u);  // two HUD lines, reticle, logo
    cv::Mat inside(360, 640, CV_8U, cv::Scalar(0));
    for (const OverlayTruth& r : painter.regions()) {
      inside(cv::Rect(r.x, r.y, r.width, r.height)).setTo(255);
    }
    cv::Mat previous_hud, previous_logo;
    int logo_changes = 0;
    for (int k = 0; k < 40; ++k) {
      HudTelemetry telemetry;
      telemetry.utc_us = 1790000000000000 + static_cast<uint64_t>(k) * 40000;
      telemetry.frame_index = k;
      telemetry.latitude_deg = 51.15 + 1e-5 * k, telemetry.longitude_deg = -1.747 - 1e-5 * k;
      telemetry.height_m = 500 + k, telemetry.heading_deg = 359.9 - k;
      telemetry.hfov_deg = 35.5;
      cv::Mat picture(360, 640, CV_8UC3, cv::Scalar::all(128));
      painter.Paint(telemetry, 0.04 * k, &picture);
      cv::Mat changed;
      cv::cvtColor(
          cv::abs(picture - cv::Scalar::all(128)) + cv::abs(cv::Scalar::all(128) - picture),
          changed, cv::COLOR_BGR2GRAY);
      changed = changed > 0;
      ASSERT_GT(cv::countNonZero(changed), 500);
      EXPECT_EQ(cv::countNonZero(changed & ~inside), 0) << LogoMotionName(logo) << " frame " << k;
      const OverlayTruth& hud = painter.regions()[0];
      const OverlayTruth& badge = painter.regions()[3];
      const cv::Mat hud_now = picture(cv::Rect(hud.x, hud.y, hud.width, hud.height)).clone();
      const cv::Mat logo_now =
          picture(cv::Rect(badge.x, badge.y, badge.width, badge.height)).clone();
      if (k > 0) {
        // The HUD's numbers change every frame; the logo moves unless it is static.
        EXPECT_GT(cv::norm(hud_now, previous_hud, cv::NORM_L1), 0) << "frame " << k;
        logo_changes += cv::norm(logo_now, previous_logo, cv::NORM_L1) > 0;
      }
      previous_hud = hud_now;
      previous_logo = logo_now;
    }
    if (logo == LogoMotion::kStatic) {
      EXPECT_EQ(logo_changes, 0);
    } else {
      EXPECT_GE(logo_changes, 30) << LogoMotionName(logo);  // a pulse's peaks change slowly
    }
  }
}

TEST_F(ConditionsTest, OverlaysAreBurnedInWhereTheTruthSays) {
  SimulationOptions plain = SmallOptions(dir_ / "plain.ts");
  plain.imaging.noise_sigma = 0;
  SimulationOptions marked = plain;
  marked.output = dir_ / "marked.ts";
  marked.overlay.hud_text = true;
  marked.overlay.reticle = true;
  marked.overlay.logo = LogoMotion::kRotating;
  marked.overlay.opacity = 0.8;
  ASSERT_TRUE(Simulate(plain).ok());
  const std::vector<cv::Mat> clean = DecodeAll(plain.output);
  ASSERT_NO_FATAL_FAILURE(Run(marked));
  ASSERT_EQ(truth_.overlays.size(), 4u);
  EXPECT_TRUE(truth_.OnOverlay(Eigen::Vector2d(159.5, 89.5)));  // the reticle
  EXPECT_FALSE(truth_.OnOverlay(Eigen::Vector2d(80, 130)));
  cv::Mat inside(180, 320, CV_8U, cv::Scalar(0));
  for (const OverlayTruth& r : truth_.overlays) {
    inside(cv::Rect(r.x, r.y, r.width, r.height)).setTo(255);
  }
  for (size_t i : {static_cast<size_t>(0), static_cast<size_t>(19)}) {
    cv::Mat difference;
    cv::absdiff(frames_[i], clean[i], difference);
    cv::cvtColor(difference, difference, cv::COLOR_BGR2GRAY);
    // Inside the boxes the overlay shows; outside only coding noise differs.
    const double on = cv::mean(difference, inside)[0], off = cv::mean(difference, ~inside)[0];
    EXPECT_GT(on, 8.0) << "frame " << i;
    EXPECT_LT(off, on / 4) << "frame " << i;
  }
}

TEST_F(ConditionsTest, InfraredTargetsAreWarmAndThePolaritySwitches) {
  SimulationOptions options = SmallOptions(dir_ / "ir.ts");
  options.imaging.look = SensorLook::kIrWhiteHot;
  options.imaging.polarity_switch_s = 1.0;
  options.targets.cars = 300;
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 250;
  options.imaging.noise_sigma = 0;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  int hotter_before = 0, colder_after = 0, before = 0, after = 0;
  double saturation = 0;
  for (size_t i = 0; i < frames_.size(); ++i) {
    cv::Mat hsv;
    cv::cvtColor(frames_[i], hsv, cv::COLOR_BGR2HSV);
    saturation = std::max(saturation, cv::mean(hsv)[1]);
    cv::Mat grey;
    cv::cvtColor(frames_[i], grey, cv::COLOR_BGR2GRAY);
    const bool white_hot = truth_.frames[i].time_s < 1.0;
    for (const TargetTruth& t : truth_.targets) {
      const TargetSampleTruth& s = t.samples[i];
      if (!s.visible || t.target_class == "person") continue;
      const cv::Point at(static_cast<int>(std::lround(s.image_px.x())),
                         static_cast<int>(std::lround(s.image_px.y())));
      // 4 m beside a moving vehicle is road or verge.
      const Eigen::Vector2d side =
          s.ground_m + Eigen::Vector2d(-s.velocity_mps.y(), s.velocity_mps.x()).normalized() * 4.0;
      const Eigen::Vector2d q =
          (truth_.frames[i].frame_from_ground * side.homogeneous()).hnormalized();
      const cv::Point off(static_cast<int>(std::lround(q.x())),
                          static_cast<int>(std::lround(q.y())));
      const cv::Rect inner(4, 4, 632, 352);
      if (!inner.contains(at) || !inner.contains(off) || s.velocity_mps.norm() < 0.5) continue;
      const double target = grey.at<uint8_t>(at), ground = grey.at<uint8_t>(off);
      if (white_hot) {
        ++before;
        hotter_before += target > ground + 20;
      } else {
        ++after;
        colder_after += target + 20 < ground;
      }
    }
  }
  EXPECT_LT(saturation, 8.0) << "a thermal picture has no colour";
  std::cout << "vehicles compared: " << before << " white-hot, " << after << " black-hot\n";
  ASSERT_GT(before, 15);
  ASSERT_GT(after, 15);
  EXPECT_GT(hotter_before, 0.8 * before);
  EXPECT_GT(colder_after, 0.8 * after);
}

TEST_F(ConditionsTest, DroppedRepeatedAndIrregularFrames) {
  SimulationOptions options = SmallOptions(dir_ / "sampling.ts");
  options.duration_s = 6;
  options.sampling.drop_probability = 0.15;
  options.sampling.repeat_probability = 0.15;
  options.sampling.variable_rate = true;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  EXPECT_GT(summary_.dropped_frames, 2);
  EXPECT_GT(summary_.repeated_frames, 2);
  EXPECT_EQ(summary_.frames, static_cast<int64_t>(truth_.frames.size()));
  // The decoded time stamps are the truth's, on a grid of quarter frame intervals, with gaps
  // where frames were dropped and intervals of 3 to 5 quarters otherwise.
  const std::vector<double> times = DecodeTimes(options.output);
  ASSERT_EQ(times.size(), truth_.frames.size());
  std::set<long> gaps;
  for (size_t i = 0; i < times.size(); ++i) {
    EXPECT_NEAR(times[i], truth_.frames[i].time_s, 1e-3) << "frame " << i;
    if (i > 0) gaps.insert(std::lround((times[i] - times[i - 1]) / 0.025));
  }
  EXPECT_TRUE(gaps.count(3) && gaps.count(4) && gaps.count(5));
  EXPECT_GT(*gaps.rbegin(), 5) << "dropped frames leave longer gaps";
  int repeats = 0;
  for (size_t i = 1; i < frames_.size(); ++i) {
    if (!truth_.frames[i].repeated) continue;
    ++repeats;
    EXPECT_EQ(truth_.frames[i].frame_from_ground, truth_.frames[i - 1].frame_from_ground);
    EXPECT_LT(
        cv::norm(frames_[i], frames_[i - 1], cv::NORM_L1) / static_cast<double>(frames_[i].total()),
        1.0)
        << "a repeated frame shows the same picture";
  }
  EXPECT_EQ(repeats, summary_.repeated_frames);
}

TEST_F(ConditionsTest, ACutSplicesInAnotherPlace) {
  SimulationOptions options = SmallOptions(dir_ / "cut.ts");
  options.cut.at_s = 1.0;
  options.cut.jump_s = 20;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  EXPECT_EQ(truth_.CutFrames(), (std::vector<int64_t>{10}));
  const double moved = (truth_.frames[10].position_m - truth_.frames[9].position_m).norm();
  EXPECT_GT(moved, 250) << "20 s further along the flight at 15 m/s";
  EXPECT_LT((truth_.frames[11].position_m - truth_.frames[10].position_m).norm(), 3.0);
  // Both sides of the cut show the ground their truth says, and nothing relates them.
  for (int64_t i : {9, 10}) {
    EXPECT_GT(GroundCorrelation(*setup_, truth_, i, frames_[static_cast<size_t>(i)],
                                truth_.frames[static_cast<size_t>(i)].frame_from_ground),
              0.85);
  }
  EXPECT_LT(GroundCorrelation(*setup_, truth_, 10, frames_[10], truth_.frames[9].frame_from_ground),
            0.5);
  // A cut that leaves the flight too short is refused, naming the problem.
  options.cut.jump_s = 1000;
  const Status refused = Simulate(options).status();
  EXPECT_EQ(refused.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.message().find("cut"), std::string::npos) << refused.message();
}

TEST_F(ConditionsTest, LensDistortionMovesTargetsWhereTheTruthSays) {
  SimulationOptions options = SmallOptions(dir_ / "lens.ts");
  options.imaging.lens_k1 = -0.25;
  options.imaging.noise_sigma = 0;
  options.targets.cars = 300;
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 200;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  const FrameRenderer renderer(setup_->ground(), options.camera, options.imaging, options.seed);
  int checked = 0, at_truth = 0, at_pinhole = 0;
  for (size_t i = 0; i < frames_.size(); ++i) {
    const Eigen::Matrix3d& h = truth_.frames[i].frame_from_ground;
    // The same frame without targets, through the same lens.
    const cv::Mat empty =
        renderer.Render(h, {}, Eigen::Vector2d::Zero(), static_cast<int64_t>(i), 0.1 * i);
    cv::Mat difference;
    cv::absdiff(frames_[i], empty, difference);
    cv::cvtColor(difference, difference, cv::COLOR_BGR2GRAY);
    for (const TargetTruth& t : truth_.targets) {
      const TargetSampleTruth& s = t.samples[i];
      const Eigen::Vector2d pinhole = (h * s.ground_m.homogeneous()).hnormalized();
      const cv::Point a(static_cast<int>(std::lround(s.image_px.x())),
                        static_cast<int>(std::lround(s.image_px.y())));
      const cv::Point b(static_cast<int>(std::lround(pinhole.x())),
                        static_cast<int>(std::lround(pinhole.y())));
      const cv::Rect inner(4, 4, 632, 352);
      if (!s.visible || t.target_class == "person" || !inner.contains(a) || !inner.contains(b) ||
          (s.image_px - pinhole).norm() < 6)
        continue;
      ++checked;
      at_truth += cv::mean(difference(cv::Rect(a.x - 1, a.y - 1, 3, 3)))[0] > 12;
      at_pinhole += cv::mean(difference(cv::Rect(b.x - 1, b.y - 1, 3, 3)))[0] > 12;
    }
  }
  ASSERT_GT(checked, 15);
  EXPECT_GT(at_truth, 0.85 * checked);
  EXPECT_LT(at_pinhole, 0.5 * checked) << "the pinhole position is off the drawn target";
}

// Options flying over a textured orthophoto of 250 x 250 m (0.25 m per pixel) made for the test,
// with `cars` cars and `people` people and no vans.
SimulationOptions OrthophotoOptions(const std::filesystem::path& output, int cars, int people) {
  cv::Mat noise(250, 250, CV_8UC3), image;
  cv::randu(noise, cv::Scalar::all(40), cv::Scalar::all(200));
  cv::resize(noise, image, cv::Size(1000, 1000), 0, 0, cv::INTER_CUBIC);
  std::filesystem::path photo = output;
  photo.replace_extension(".png");
  EXPECT_TRUE(cv::imwrite(photo.string(), image));
  SimulationOptions options = SmallOptions(output);
  options.ground_image = photo;
  options.ground_gsd_m = 0.25;
  options.targets.cars = cars;
  options.targets.vans = 0;
  options.targets.people = people;
  return options;
}

TEST_F(ConditionsTest, TargetsMoveOverAnOrthophotoAlongGeneratedPaths) {
  SimulationOptions options = OrthophotoOptions(dir_ / "ortho-paths.ts", 12, 6);
  options.scenario = Scenario::kOrbit;
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 200;
  options.flight.orbit_radius_m = 100;
  options.ground_paths.generated = true;
  options.imaging.noise_sigma = 0;
  ASSERT_NO_FATAL_FAILURE(Run(options));
  ASSERT_EQ(truth_.targets.size(), 18u);
  int moved = 0, visible = 0, drawn = 0;
  FrameRenderer renderer(setup_->ground(), options.camera, options.imaging, options.seed);
  for (const TargetTruth& t : truth_.targets) {
    for (const TargetSampleTruth& s : t.samples) {
      EXPECT_LT(s.ground_m.cwiseAbs().maxCoeff(), 125.0) << "target " << t.id << " left the photo";
    }
    moved += (t.samples.back().ground_m - t.samples.front().ground_m).norm() > 4.0;
  }
  for (size_t i : {static_cast<size_t>(0), static_cast<size_t>(10), static_cast<size_t>(19)}) {
    const cv::Mat ground = renderer.RenderGround(truth_.frames[i].frame_from_ground);
    cv::Mat difference;
    cv::absdiff(frames_[i], ground, difference);
    cv::cvtColor(difference, difference, cv::COLOR_BGR2GRAY);
    for (const TargetTruth& t : truth_.targets) {
      const TargetSampleTruth& s = t.samples[i];
      const cv::Point at(static_cast<int>(std::lround(s.image_px.x())),
                         static_cast<int>(std::lround(s.image_px.y())));
      if (!s.visible || t.target_class == "person" || !cv::Rect(2, 2, 636, 356).contains(at))
        continue;
      ++visible;
      drawn += cv::mean(difference(cv::Rect(at.x - 1, at.y - 1, 3, 3)))[0] > 12;
    }
  }
  EXPECT_GE(moved, 10) << "vehicles drive, people walk";
  ASSERT_GE(visible, 3);
  EXPECT_GE(drawn, 0.8 * visible);
}

TEST_F(ConditionsTest, TargetsFollowTheLinesOfAGeoJsonFile) {
  SimulationOptions options = OrthophotoOptions(dir_ / "ortho-geojson.ts", 4, 3);
  options.scenario = Scenario::kStraight;
  options.flight.straight_length_m = 40;
  StatusOr<geo::LocalTangentPlane> plane = geo::LocalTangentPlane::Create(options.origin);
  ASSERT_TRUE(plane.ok());
  const auto position = [&](double east, double north) {
    const geo::Wgs84 p = plane->LatLonFromMap(Eigen::Vector2d(east, north));
    return nlohmann::json::array({p.longitude_deg, p.latitude_deg});
  };
  const nlohmann::json collection = {
      {"type", "FeatureCollection"},
      {"features",
       {{{"type", "Feature"},
         {"properties", {{"name", "high street"}}},
         {"geometry",
          {{"type", "LineString"}, {"coordinates", {position(-100, 0), position(100, 0)}}}}},
        {{"type", "Feature"},
         {"properties", {{"kind", "footpath"}}},
         {"geometry",
          {{"type", "LineString"}, {"coordinates", {position(30, 10), position(30, 60)}}}}}}}};
  options.ground_paths.geojson = dir_ / "roads.geojson";
  std::ofstream(options.ground_paths.geojson) << collection.dump();
  ASSERT_NO_FATAL_FAILURE(Run(options));
  ASSERT_EQ(truth_.targets.size(), 7u);
  for (const TargetTruth& t : truth_.targets) {
    for (const TargetSampleTruth& s : t.samples) {
      if (t.target_class == "person") {
        EXPECT_NEAR(s.ground_m.x(), 30.0, 2.5) << "person " << t.id;
      } else {
        EXPECT_LT(std::abs(s.ground_m.y()), 3.0) << "car " << t.id;
      }
    }
  }
  // Bad files are refused, naming the file and what is wrong.
  const auto refused = [&](const std::string& text) {
    const std::filesystem::path bad = dir_ / "bad.geojson";
    std::ofstream(bad) << text;
    SimulationOptions o = options;
    o.ground_paths.geojson = bad;
    o.output = dir_ / "bad.ts";
    return Simulate(o).status();
  };
  const Status one_point = refused(
      R"({"type": "FeatureCollection", "features": [{"type": "Feature", "geometry":
         {"type": "LineString", "coordinates": [[-1.747, 51.152]]}}]})");
  EXPECT_EQ(one_point.code(), StatusCode::kInvalidData);
  EXPECT_NE(one_point.message().find("bad.geojson: feature 0"), std::string::npos)
      << one_point.message();
  EXPECT_EQ(refused("not json").code(), StatusCode::kInvalidData);
  EXPECT_EQ(refused(R"({"type": "Point", "coordinates": [1, 2]})").code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(refused(R"({"type": "LineString", "coordinates": [[1, 95], [2, 3]]})").code(),
            StatusCode::kInvalidData);
  options.ground_paths.geojson = dir_ / "missing.geojson";
  EXPECT_EQ(Simulate(options).status().code(), StatusCode::kNotFound);
}

TEST(SimulationOptionsJsonTest, RoundTripsAndRefusesUnknownKeys) {
  SimulationOptions options;
  options.scenario = Scenario::kOrbit;
  options.fps = 2;
  options.flight.orbit_radius_m = 600;
  options.overlay.logo = LogoMotion::kPulsing;
  options.imaging.look = SensorLook::kIrBlackHot;
  options.sampling.variable_rate = true;
  options.cut.at_s = 12;
  SimulationOptions copy;
  ASSERT_TRUE(ApplyOptionsJson(options.ToJson(), &copy).ok());
  EXPECT_EQ(copy.ToJson(), options.ToJson());

  SimulationOptions partial;
  ASSERT_TRUE(
      ApplyOptionsJson({{"flight", {{"gimbal_off_nadir_deg", 30}}}, {"seed", 7}}, &partial).ok());
  EXPECT_EQ(partial.flight.gimbal_off_nadir_deg, 30);
  EXPECT_EQ(partial.seed, 7u);
  EXPECT_EQ(partial.flight.altitude_m, SimulationOptions().flight.altitude_m);

  for (const nlohmann::json& bad :
       {nlohmann::json{{"flight", {{"gimbal_of_nadir_deg", 30}}}}, nlohmann::json{{"fsp", 2}},
        nlohmann::json{{"fps", "fast"}}, nlohmann::json{{"imaging", {{"look", "sonar"}}}},
        nlohmann::json{{"seed", -1}}, nlohmann::json{{"overlay", {{"reticle", 1}}}}}) {
    SimulationOptions target;
    const Status status = ApplyOptionsJson(bad, &target);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << bad.dump();
    EXPECT_EQ(target.ToJson(), SimulationOptions().ToJson()) << "left unchanged: " << bad.dump();
  }
  const Status unknown = ApplyOptionsJson({{"flight", {{"gimbal_of_nadir_deg", 30}}}}, &options);
  EXPECT_NE(unknown.message().find("flight.gimbal_of_nadir_deg"), std::string::npos)
      << unknown.message();
}

}  // namespace
}  // namespace saker::sim
