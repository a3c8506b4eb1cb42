// The feature tracker against known motion: synthetic textures moved by exact sub-pixel affine
// maps, and simulated airborne video against the simulator's ground-truth homographies.

#include "core/track/feature_tracker.h"

#include "core/sim/simulator.h"
#include "core/sim/truth.h"
#include "core/video/video_reader.h"
#include "tests/testing/test_data.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <vector>

namespace saker::track {
namespace {

// The frame rate the tests' frame counts were written for.
const FrameRate kRate(25);

// Smooth random texture (blurred noise stretched to the full grey range): corners everywhere,
// and smooth enough that cubic resampling moves it without bias.
cv::Mat Texture(cv::Size size, uint64_t seed, double blur_px = 2.0) {
  cv::Mat noise(size, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat smooth;
  cv::GaussianBlur(noise, smooth, cv::Size(0, 0), blur_px);
  cv::normalize(smooth, smooth, 0, 255, cv::NORM_MINMAX);
  return smooth;
}

// frame_from_base for a camera whose frame (size `frame`) starts at `origin` in the base image,
// has moved by `shift`, turned by `degrees` and zoomed by `zoom` about the frame centre.
Eigen::Matrix3d FrameFromBase(cv::Size frame, const Eigen::Vector2d& origin,
                              const Eigen::Vector2d& shift, double degrees, double zoom = 1) {
  const Eigen::Vector2d centre((frame.width - 1) / 2.0, (frame.height - 1) / 2.0);
  Eigen::Affine2d a = Eigen::Translation2d(centre) * Eigen::Rotation2Dd(degrees * M_PI / 180) *
                      Eigen::Scaling(zoom) * Eigen::Translation2d(-centre) *
                      Eigen::Translation2d(-origin - shift);
  return a.matrix();
}

// The view of `base` through `frame_from_base` (cubic resampling; OpenCV's pixel-centre
// convention, as the tracker's).
cv::Mat View(const cv::Mat& base, const Eigen::Matrix3d& frame_from_base, cv::Size size) {
  cv::Mat m(2, 3, CV_64F);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = frame_from_base(r, c);
  }
  cv::Mat view;
  cv::warpAffine(base, view, m, size, cv::INTER_CUBIC, cv::BORDER_REFLECT_101);
  return view;
}

Eigen::Vector2d Map(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  return (h * p.homogeneous()).hnormalized();
}

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  const auto middle = v.begin() + static_cast<ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), middle, v.end());
  return *middle;
}

// The tracker's frame-to-frame errors against the true map, with the signed errors per axis.
struct Errors {
  std::vector<double> norm, dx, dy;
  void Add(const Eigen::Vector2d& measured, const Eigen::Vector2d& truth) {
    const Eigen::Vector2d e = measured - truth;
    norm.push_back(e.norm());
    dx.push_back(e.x());
    dy.push_back(e.y());
  }
};

TrackerOptions FullResolution(int max_corners) {
  TrackerOptions options;
  options.processing_width = 0;
  options.max_corners = max_corners;
  return options;
}

TEST(TrackerOptionsTest, ValidateRejectsNonsense) {
  EXPECT_TRUE(TrackerOptions().Validate().ok());
  const auto bad = [](auto change) {
    TrackerOptions options;
    change(options);
    const Status status = options.Validate();
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find("tracker:"), std::string::npos) << status.message();
  };
  bad([](TrackerOptions& o) { o.max_corners = 0; });
  bad([](TrackerOptions& o) { o.quality = 0; });
  bad([](TrackerOptions& o) { o.min_distance_px = -1; });
  bad([](TrackerOptions& o) { o.processing_width = 10; });
  bad([](TrackerOptions& o) { o.window_px = 20; });
  bad([](TrackerOptions& o) { o.pyramid_levels = -1; });
  bad([](TrackerOptions& o) { o.max_iterations = 0; });
  bad([](TrackerOptions& o) { o.max_forward_backward_px = std::nan(""); });
  bad([](TrackerOptions& o) { o.min_correlation = 1.5; });
  bad([](TrackerOptions& o) { o.min_contrast = -1; });
  bad([](TrackerOptions& o) { o.grid_rows = 0; });
  bad([](TrackerOptions& o) { o.redetect_interval_s = -1; });
  bad([](TrackerOptions& o) { o.refill_fraction = 1.5; });
  bad([](TrackerOptions& o) { o.max_frame_gap_s = -1; });
  bad([](TrackerOptions& o) { o.max_history = 0; });
  bad([](TrackerOptions& o) { o.min_finished_length = 0; });
  TrackerOptions invalid;
  invalid.window_px = 4;
  EXPECT_THROW((FeatureTracker{invalid, kRate}), CheckError);
}

// Sub-pixel translation plus rotation, frame after frame: every frame-to-frame match lands on
// the true motion, tracks keep their ids, and ids are never given twice.
TEST(FeatureTrackerTest, FollowsSubPixelTranslationAndRotation) {
  const cv::Mat base = Texture(cv::Size(1000, 800), 1);
  const cv::Size size(640, 480);
  const Eigen::Vector2d origin(180, 160), velocity(1.37, -0.83);
  const double degrees_per_frame = 0.15;
  const auto frame_from_base = [&](int k) {
    return FrameFromBase(size, origin, velocity * k, degrees_per_frame * k);
  };
  FeatureTracker tracker(FullResolution(400), kRate);
  Errors errors;
  std::map<int64_t, Eigen::Vector2d> previous;  // id -> position in the previous frame
  std::set<int64_t> ended;
  int64_t highest_id = 0;
  const int kFrames = 25;
  for (int k = 0; k < kFrames; ++k) {
    tracker.Process(k, View(base, frame_from_base(k), size));
    ASSERT_GT(tracker.points().size(), 300u) << "frame " << k;
    if (k > 0) {
      const Eigen::Matrix3d now_from_before = frame_from_base(k) * frame_from_base(k - 1).inverse();
      EXPECT_GT(tracker.matches().size(), 0.9 * static_cast<double>(previous.size()))
          << "frame " << k;
      for (const Correspondence& m : tracker.matches()) {
        ASSERT_TRUE(previous.count(static_cast<int64_t>(m.id))) << "a match of an unknown track";
        EXPECT_EQ(previous[static_cast<int64_t>(m.id)], m.source);
        errors.Add(m.target, Map(now_from_before, m.source));
      }
    }
    std::map<int64_t, Eigen::Vector2d> now;
    int64_t last_id = 0;
    for (const TrackedPoint& p : tracker.points()) {
      const int64_t id = static_cast<int64_t>(p.id);
      EXPECT_GT(id, last_id) << "points are ordered by id";
      last_id = id;
      EXPECT_FALSE(ended.count(id)) << "id " << id << " came back";
      if (p.first_frame == k) {
        EXPECT_GT(id, highest_id) << "a new track reuses an id";
        EXPECT_FALSE(previous.count(id));
      } else {
        EXPECT_TRUE(previous.count(id));
      }
      highest_id = std::max(highest_id, id);
      now[id] = p.position;
    }
    for (const auto& [id, position] : previous) {
      if (!now.count(id)) ended.insert(id);
    }
    previous = std::move(now);
  }
  EXPECT_LT(Median(errors.norm), 0.1);
  EXPECT_LT(std::abs(Median(errors.dx)), 0.03);
  EXPECT_LT(std::abs(Median(errors.dy)), 0.03);

  // Whole histories: the start of each live track, carried to the last frame by the true motion,
  // lands on its end (the drift over up to 24 frames).
  Errors drift;
  for (const TrackedPoint& p : tracker.points()) {
    const FeatureTrack* track = tracker.History(p.id);
    ASSERT_NE(track, nullptr);
    EXPECT_EQ(track->first_frame, p.first_frame);
    EXPECT_EQ(track->history_start, p.first_frame);
    ASSERT_EQ(track->last_frame(), kFrames - 1);
    EXPECT_EQ(track->positions.back(), p.position);
    if (p.first_frame > kFrames - 10) continue;
    const Eigen::Matrix3d last_from_first =
        frame_from_base(kFrames - 1) * frame_from_base(static_cast<int>(p.first_frame)).inverse();
    drift.Add(p.position, Map(last_from_first, track->positions.front()));
  }
  ASSERT_GT(drift.norm.size(), 200u);
  EXPECT_LT(Median(drift.norm), 0.15);
  EXPECT_EQ(tracker.History(FeatureTrackId(highest_id + 1)), nullptr);
}

// A region whose content is replaced (something moving over the ground) ends the tracks on it:
// the forward-backward and correlation checks catch what LK alone follows to a wrong place.
// A camera moving 90 px a frame (a second between frames) is beyond the pyramid's reach: without
// a prediction few tracks survive; starting the flow from the predicted motion (the low-frame-rate
// mode's previous ground motion, here off by 6 px) follows them, as accurately as a small motion.
TEST(FeatureTrackerTest, APredictedMotionFollowsShiftsBeyondThePyramidsReach) {
  const cv::Mat base = Texture(cv::Size(1200, 700), 4);
  const cv::Size size(640, 480);
  const Eigen::Vector2d origin(40, 100), step(90, 12);
  const Eigen::Matrix3d first = FrameFromBase(size, origin, {0, 0}, 0);
  const Eigen::Matrix3d second = FrameFromBase(size, origin, step, 1.0);
  const Eigen::Matrix3d now_from_before = second * first.inverse();
  // The prediction: the same motion 6 px off.
  Eigen::Matrix3d predicted = now_from_before;
  predicted(0, 2) += 5, predicted(1, 2) -= 3;
  const auto matched = [&](const Eigen::Matrix3d* prediction, double* median_error) {
    FeatureTracker tracker(FullResolution(400), kRate);
    tracker.Process(0, View(base, first, size));
    const size_t live = tracker.points().size();
    tracker.Process(1, View(base, second, size), prediction);
    std::vector<double> errors;
    for (const Correspondence& m : tracker.matches()) {
      errors.push_back((m.target - Map(now_from_before, m.source)).norm());
    }
    *median_error = Median(errors);
    return static_cast<double>(tracker.matches().size()) / static_cast<double>(live);
  };
  double error_unguided = 0, error_guided = 0;
  const double unguided = matched(nullptr, &error_unguided);
  const double guided = matched(&predicted, &error_guided);
  std::printf(
      "90 px a frame: %.0f %% of the tracks followed unguided, %.0f %% guided "
      "(median error %.3f px)\n",
      100 * unguided, 100 * guided, error_guided);
  EXPECT_LT(unguided, 0.3);
  // Most of those that stay in view (the camera moved 90 of 640 px).
  EXPECT_GT(guided, 0.6);
  EXPECT_LT(error_guided, 0.1);
}

TEST(FeatureTrackerTest, ChecksEndTracksOnAChangingRegion) {
  const cv::Mat base = Texture(cv::Size(800, 600), 2);
  const cv::Mat other = Texture(cv::Size(800, 600), 3);
  const cv::Size size(640, 480);
  const cv::Rect patch(240, 160, 160, 160);
  const auto survivors_inside = [&](double max_forward_backward_px, double min_correlation) {
    TrackerOptions options = FullResolution(400);
    options.max_forward_backward_px = max_forward_backward_px;
    options.min_correlation = min_correlation;
    FeatureTracker tracker(options, kRate);
    std::set<int64_t> inside, outside;
    int survived_inside = 0, survived_outside = 0;
    for (int k = 0; k <= 6; ++k) {
      const Eigen::Matrix3d h =
          FrameFromBase(size, Eigen::Vector2d(60, 50), Eigen::Vector2d(0.3, 0.2) * k, 0);
      cv::Mat frame = View(base, h, size);
      if (k == 6) View(other, h, size)(patch).copyTo(frame(patch));
      tracker.Process(k, frame);
      if (k == 5) {
        // Inside: the whole window on the new content; outside: the window clear of it.
        const int half = TrackerOptions().window_px / 2 + 2;
        const cv::Rect core(patch.x + half, patch.y + half, patch.width - 2 * half,
                            patch.height - 2 * half);
        const cv::Rect clear(patch.x - half, patch.y - half, patch.width + 2 * half,
                             patch.height + 2 * half);
        for (const TrackedPoint& p : tracker.points()) {
          const cv::Point2d at(p.position.x(), p.position.y());
          if (core.contains(at)) inside.insert(static_cast<int64_t>(p.id));
          if (!clear.contains(at)) outside.insert(static_cast<int64_t>(p.id));
        }
      }
    }
    for (const Correspondence& m : tracker.matches()) {
      survived_inside += static_cast<int>(inside.count(static_cast<int64_t>(m.id)));
      survived_outside += static_cast<int>(outside.count(static_cast<int64_t>(m.id)));
    }
    EXPECT_GT(inside.size(), 15u);
    EXPECT_GT(survived_outside, 0.95 * static_cast<double>(outside.size()));
    return static_cast<double>(survived_inside) / static_cast<double>(inside.size());
  };
  EXPECT_EQ(survivors_inside(0.5, 0.8), 0.0);
  // Each check alone lets a few through (so both are needed); without either (an absurd
  // tolerance), LK follows many of them into the new content.
  EXPECT_LT(survivors_inside(0.5, -1), 0.15);
  EXPECT_LT(survivors_inside(1e9, 0.8), 0.15);
  EXPECT_GT(survivors_inside(1e9, -1), 0.3);
}

// Half the image goes blank (a cloud: flat grey with sensor noise) and comes back: the tracks
// there end, no corners are made up on the noise, and the cells are refilled once texture returns.
TEST(FeatureTrackerTest, RedetectsWhereTracksRanOut) {
  const cv::Mat texture = Texture(cv::Size(640, 480), 4);
  cv::Mat half_flat = texture.clone();
  cv::Mat cloud(480, 320, CV_8UC1);
  cv::RNG(5).fill(cloud, cv::RNG::NORMAL, 128, 1.5);
  cloud.copyTo(half_flat(cv::Rect(0, 0, 320, 480)));
  TrackerOptions options = FullResolution(300);
  options.redetect_interval_s = 3 / kRate.fps();  // 3 frames
  FeatureTracker tracker(options, kRate);
  const auto count_left = [&](int64_t born_from) {
    int n = 0;
    for (const TrackedPoint& p : tracker.points()) {
      n += p.position.x() < 290 && p.first_frame >= born_from;
    }
    return n;
  };
  for (int k = 0; k < 20; ++k) {
    tracker.Process(k, k >= 5 && k < 10 ? half_flat : texture);
    if (k == 4) {
      EXPECT_GT(count_left(0), 100);
    }
    if (k >= 5 && k < 10) {
      EXPECT_EQ(count_left(0), 0) << "frame " << k;
    }
    if (k >= 10 + 3) {
      EXPECT_GT(count_left(10), 100) << "frame " << k;
      EXPECT_GT(tracker.points().size(), 0.8 * options.max_corners) << "frame " << k;
    }
  }
}

// A long pan: corners leave on one side, new ground enters on the other; the count stays near
// max_corners, histories stay within max_history, and lost tracks come out of TakeFinished once.
TEST(FeatureTrackerTest, KeepsTheCountUpOverALongPanWithBoundedHistories) {
  const cv::Mat base = Texture(cv::Size(1700, 560), 5);
  const cv::Size size(640, 480);
  TrackerOptions options = FullResolution(400);
  options.max_history = 20;
  FeatureTracker tracker(options, kRate);
  std::set<int64_t> finished_ids;
  size_t fewest = options.max_corners;
  const int kFrames = 150;
  for (int k = 0; k < kFrames; ++k) {
    const Eigen::Matrix3d h =
        FrameFromBase(size, Eigen::Vector2d(20, 40), Eigen::Vector2d(6.6, 0.25) * k, 0);
    tracker.Process(k, View(base, h, size));
    if (k >= 2) fewest = std::min(fewest, tracker.points().size());
    for (const TrackedPoint& p : tracker.points()) {
      const FeatureTrack* track = tracker.History(p.id);
      ASSERT_NE(track, nullptr);
      ASSERT_LE(track->positions.size(), 25u);
      ASSERT_GE(track->positions.size(),
                std::min<size_t>(20, static_cast<size_t>(k - p.first_frame + 1)));
      ASSERT_EQ(track->last_frame(), k);
      ASSERT_EQ(*track->PositionAt(k), p.position);
      ASSERT_EQ(track->PositionAt(track->history_start - 1), nullptr);
    }
    for (FeatureTrack& t : tracker.TakeFinished()) {
      EXPECT_TRUE(finished_ids.insert(static_cast<int64_t>(t.id)).second) << "handed out twice";
      EXPECT_EQ(tracker.History(t.id), nullptr);
      EXPECT_LT(t.last_frame(), k);
      EXPECT_GE(t.last_frame() - t.first_frame + 1, options.min_finished_length);
      EXPECT_LE(t.positions.size(), 25u);
      EXPECT_GE(t.history_start, t.first_frame);
    }
  }
  EXPECT_GT(fewest, 0.85 * options.max_corners);
  // 150 frames * 6.6 px over a 640 px wide view: the ground was replaced about 1.5 times.
  EXPECT_GT(finished_ids.size(), 400u);
}

// Tracking on a shrunk copy is as accurate frame to frame as tracking at full resolution, at an
// integer and a fractional scale.
TEST(FeatureTrackerTest, ProcessingWidthKeepsFrameToFrameAccuracy) {
  const cv::Mat base = Texture(cv::Size(1600, 1000), 6);
  const cv::Size size(1280, 720);
  const auto frame_from_base = [&](int k) {
    return FrameFromBase(size, Eigen::Vector2d(150, 130), Eigen::Vector2d(2.3, 1.1) * k, 0.1 * k);
  };
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 10; ++k) frames.push_back(View(base, frame_from_base(k), size));
  for (int width : {0, 960, 640}) {
    TrackerOptions options;
    options.processing_width = width;
    options.max_corners = 500;
    FeatureTracker tracker(options, kRate);
    Errors errors;
    for (int k = 0; k < static_cast<int>(frames.size()); ++k) {
      tracker.Process(k, frames[static_cast<size_t>(k)]);
      const Eigen::Matrix3d now_from_before = frame_from_base(k) * frame_from_base(k - 1).inverse();
      for (const Correspondence& m : tracker.matches()) {
        errors.Add(m.target, Map(now_from_before, m.source));
      }
    }
    ASSERT_GT(errors.norm.size(), 4000u) << "width " << width;
    EXPECT_LT(Median(errors.norm), 0.15) << "width " << width;
  }
}

// Round bright blobs on a dark ground, drawn exactly (no resampling) centred on `centres`.
cv::Mat Blobs(cv::Size size, const std::vector<Eigen::Vector2d>& centres, double sigma) {
  cv::Mat image(size, CV_32F, cv::Scalar(40));
  const int reach = static_cast<int>(std::ceil(4 * sigma));
  const double k = -1 / (2 * sigma * sigma);
  for (const Eigen::Vector2d& c : centres) {
    const int cx = static_cast<int>(std::lround(c.x())), cy = static_cast<int>(std::lround(c.y()));
    for (int y = std::max(0, cy - reach); y <= std::min(size.height - 1, cy + reach); ++y) {
      float* row = image.ptr<float>(y);
      const double dy2 = (y - c.y()) * (y - c.y());
      for (int x = std::max(0, cx - reach); x <= std::min(size.width - 1, cx + reach); ++x) {
        row[x] += static_cast<float>(180 * std::exp(k * ((x - c.x()) * (x - c.x()) + dy2)));
      }
    }
  }
  cv::Mat grey;
  image.convertTo(grey, CV_8U);
  return grey;
}

// Positions are absolute full-resolution pixels whatever the processing width: the half-pixel of
// the pixel-centre convention is taken care of. (A constant shift of every position cancels out
// of frame-to-frame motion, so only content at a known place can show it.) Symmetric blobs are
// centred on processing-pixel centres, where the corner detector must find them; their true
// full-resolution centres are known exactly while they move by sub-pixel steps.
TEST(FeatureTrackerTest, ProcessingWidthKeepsPositionsAbsolute) {
  const cv::Size size(960, 540);
  for (int width : {0, 720, 480}) {
    const double scale = width == 0 ? 1.0 : static_cast<double>(size.width) / width;
    // A blob every 16 processing pixels, on processing-pixel centres (i + 0.5) * scale - 0.5.
    const auto centre = [&](int i, int j) {
      return Eigen::Vector2d((24 + 16 * i + 0.5) * scale - 0.5, (24 + 16 * j + 0.5) * scale - 0.5);
    };
    const int columns = static_cast<int>((size.width - 80) / (16 * scale)),
              rows = static_cast<int>((size.height - 80) / (16 * scale));
    std::vector<Eigen::Vector2d> grid;
    for (int j = 0; j < rows; ++j) {
      for (int i = 0; i < columns; ++i) grid.push_back(centre(i, j));
    }
    TrackerOptions options;
    options.processing_width = width;
    options.quality = 0.1;  // the blobs, not the faint saddles between them
    options.max_corners = 2000;
    FeatureTracker tracker(options, kRate);
    Errors errors;
    size_t found = 0;
    for (int k = 0; k < 6; ++k) {
      const Eigen::Vector2d shift = Eigen::Vector2d(0.37, -0.21) * k;
      std::vector<Eigen::Vector2d> centres = grid;
      for (Eigen::Vector2d& c : centres) c += shift;
      tracker.Process(k, Blobs(size, centres, 1.5 * scale));
      for (const TrackedPoint& p : tracker.points()) {
        // The blob this track was detected on: the lattice point nearest to its start.
        const Eigen::Vector2d start = tracker.History(p.id)->positions.front();
        const int i = static_cast<int>(std::lround(((start.x() + 0.5) / scale - 24.5) / 16));
        const int j = static_cast<int>(std::lround(((start.y() + 0.5) / scale - 24.5) / 16));
        if (i < 0 || i >= columns || j < 0 || j >= rows) continue;
        if ((centre(i, j) - start).norm() > 1.5 * scale) continue;
        errors.Add(p.position, centre(i, j) + shift);
        found += k == 0;
      }
    }
    EXPECT_GT(found, 0.8 * static_cast<double>(grid.size())) << "width " << width;
    EXPECT_LT(Median(errors.norm), 0.05) << "width " << width;
  }
}

// Frames skipped by the caller get interpolated positions; a long jump, a size change or Reset
// end every track; ids keep increasing; frame indices must increase.
TEST(FeatureTrackerTest, GapsJumpsResetAndIds) {
  const cv::Mat base = Texture(cv::Size(600, 500), 7);
  const cv::Size size(400, 300);
  const Eigen::Vector2d velocity(1.2, 0.5);
  const auto frame = [&](int k) {
    return View(base, FrameFromBase(size, Eigen::Vector2d(50, 50), velocity * k, 0), size);
  };
  TrackerOptions options = FullResolution(200);
  options.max_frame_gap_s = 3 / kRate.fps();  // 3 frames
  FeatureTracker tracker(options, kRate);
  EXPECT_EQ(tracker.last_frame(), -1);
  tracker.Process(0, frame(0));
  tracker.Process(1, frame(1));
  tracker.Process(4, frame(4));  // frames 2 and 3 skipped
  EXPECT_EQ(tracker.last_frame(), 4);
  ASSERT_FALSE(tracker.matches().empty());
  for (const Correspondence& m : tracker.matches()) {
    EXPECT_LT((m.target - m.source + 3 * velocity).norm(), 0.3);
    const FeatureTrack* track = tracker.History(m.id);
    ASSERT_NE(track, nullptr);
    ASSERT_EQ(track->positions.size(), 5u);
    EXPECT_EQ(track->first_frame, 0);
    const Eigen::Vector2d* at3 = track->PositionAt(3);
    ASSERT_NE(at3, nullptr);
    EXPECT_LT((*at3 - (m.source + (m.target - m.source) * (2.0 / 3.0))).norm(), 1e-9)
        << "linear interpolation";
    EXPECT_LT((*at3 - (m.target + velocity)).norm(), 0.1);
  }
  EXPECT_THROW(tracker.Process(4, frame(4)), CheckError);
  EXPECT_THROW(tracker.Process(5, cv::Mat(size, CV_8UC3)), CheckError);

  int64_t highest = 0;
  for (const TrackedPoint& p : tracker.points())
    highest = std::max(highest, static_cast<int64_t>(p.id));
  const size_t live = tracker.points().size();
  tracker.TakeFinished();
  tracker.Process(8, frame(8));  // 3 skipped: still followed
  EXPECT_FALSE(tracker.matches().empty());
  tracker.Process(12, frame(12));  // 3 skipped again
  EXPECT_FALSE(tracker.matches().empty());
  tracker.Process(17, frame(17));  // 4 skipped: every track ends, fresh corners
  EXPECT_TRUE(tracker.matches().empty());
  std::set<int64_t> ended;
  for (const FeatureTrack& t : tracker.TakeFinished()) ended.insert(static_cast<int64_t>(t.id));
  EXPECT_GE(ended.size(), live / 2);
  for (const TrackedPoint& p : tracker.points()) {
    EXPECT_GT(static_cast<int64_t>(p.id), highest);
    EXPECT_EQ(p.first_frame, 17);
  }
  for (const TrackedPoint& p : tracker.points())
    highest = std::max(highest, static_cast<int64_t>(p.id));

  // A new image size is a new video: everything ends.
  tracker.Process(18, frame(18));
  tracker.Process(19, View(base, Eigen::Matrix3d::Identity(), cv::Size(320, 240)));
  EXPECT_TRUE(tracker.matches().empty());
  EXPECT_FALSE(tracker.TakeFinished().empty());

  // Reset: every live track is finished, any index may follow, ids go on increasing.
  const size_t before_reset = tracker.points().size();
  tracker.Process(20, View(base, Eigen::Matrix3d::Identity(), cv::Size(320, 240)));
  tracker.TakeFinished();
  for (const TrackedPoint& p : tracker.points())
    highest = std::max(highest, static_cast<int64_t>(p.id));
  tracker.Reset();
  EXPECT_TRUE(tracker.points().empty());
  EXPECT_EQ(tracker.last_frame(), -1);
  EXPECT_GE(tracker.TakeFinished().size(), before_reset / 2);
  EXPECT_TRUE(tracker.TakeFinished().empty()) << "handed out once";
  tracker.Process(0, frame(0));
  EXPECT_TRUE(tracker.matches().empty());
  ASSERT_FALSE(tracker.points().empty());
  for (const TrackedPoint& p : tracker.points()) EXPECT_GT(static_cast<int64_t>(p.id), highest);

  // A frame too small to track is survived.
  tracker.Process(1, cv::Mat(8, 8, CV_8UC1, cv::Scalar(100)));
  EXPECT_TRUE(tracker.points().empty());
  tracker.Process(2, frame(2));
  EXPECT_FALSE(tracker.points().empty());

  // Lost tracks are not collected when nobody wants them.
  options.keep_finished = false;
  FeatureTracker quiet(options, kRate);
  quiet.Process(0, frame(0));
  quiet.Reset();
  EXPECT_TRUE(quiet.TakeFinished().empty());
}

// Simulated airborne video (H.264, sensor noise, moving cars, shadows) against the simulator's
// truth: ground points move by H_now * H_before^-1 from frame to frame.
TEST(FeatureTrackerTest, FollowsTheGroundInSimulatedVideo) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-tracker");
  sim::SimulationOptions options;
  options.output = dir / "sim.ts";
  options.camera.width = 640;
  options.camera.height = 360;
  options.flight.altitude_m = 200;  // 0.2 m per pixel, like the default 1280x720 at 400 m
  options.fps = 10;
  options.duration_s = 2;
  options.crf = 18;
  options.targets.cars = 150;  // so that some cars are in view
  const StatusOr<sim::SimulationSummary> summary = sim::Simulate(options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  const StatusOr<sim::Truth> truth = sim::ReadTruth(options.TruthPath());
  ASSERT_TRUE(truth.ok()) << truth.status().ToString();

  video::ReaderOptions reader_options;
  reader_options.want_bgr = false;
  reader_options.want_grey = true;
  StatusOr<std::unique_ptr<video::VideoReader>> reader =
      video::VideoReader::Open(options.output.string(), reader_options);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  std::vector<cv::Mat> frames;
  video::Frame frame;
  while (true) {
    StatusOr<bool> more = (*reader)->ReadNext(&frame, nullptr);
    ASSERT_TRUE(more.ok()) << more.status().ToString();
    if (!*more) break;
    frames.push_back(frame.grey.clone());
  }
  ASSERT_EQ(frames.size(), truth->frames.size());

  // A car is about 4.5 m (23 px) long: keep 30 px away from every target centre and its shadow.
  const auto near_target = [&](size_t frame_index, const Eigen::Vector2d& p) {
    for (const sim::TargetTruth& t : truth->targets) {
      if ((t.samples[frame_index].image_px - p).norm() < 30) return true;
    }
    return false;
  };
  for (int width : {0, 320}) {
    TrackerOptions tracker_options;
    tracker_options.processing_width = width;
    tracker_options.min_distance_px = 8;
    FeatureTracker tracker(tracker_options, kRate);
    Errors errors;
    int excluded = 0;
    for (size_t i = 0; i < frames.size(); ++i) {
      tracker.Process(static_cast<int64_t>(i), frames[i]);
      if (i == 0) continue;
      EXPECT_GT(tracker.matches().size(), 300u) << "frame " << i;
      const Eigen::Matrix3d now_from_before =
          truth->frames[i].frame_from_ground * truth->frames[i - 1].frame_from_ground.inverse();
      for (const Correspondence& m : tracker.matches()) {
        if (near_target(i, m.target) || near_target(i - 1, m.source)) {
          ++excluded;
          continue;
        }
        errors.Add(m.target, Map(now_from_before, m.source));
      }
    }
    EXPECT_GT(excluded, 0) << "no target in view: the scene is not what the test means";
    ASSERT_GT(errors.norm.size(), 3000u);
    EXPECT_LT(Median(errors.norm), 0.3) << "width " << width;
  }
}

}  // namespace
}  // namespace saker::track
