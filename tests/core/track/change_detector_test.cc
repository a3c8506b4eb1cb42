// Change detection on synthetic frames: a textured ground seen by a camera drifting over it, with
// small dark movers drawn on top; and the blob tracker on synthetic blobs.

#include "core/track/change_detector.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <random>

namespace saker::track {
namespace {

constexpr int kWidth = 320, kHeight = 240;
const Eigen::Vector2d kCameraStep(1.5, 0.7);  // ground pixels per frame

// A smooth random texture larger than a frame (the ground, one pixel per ground unit).
cv::Mat Ground() {
  cv::Mat noise(kHeight + 200, kWidth + 400, CV_32F);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::NORMAL, 128, 120);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.0);
  return noise;
}

// A dark box on the ground: centre, half sizes.
struct Mover {
  Eigen::Vector2d centre;
  Eigen::Vector2d half;
};

// Frame n: the ground shifted by n camera steps, movers drawn (anti-aliased by supersampling),
// sensor noise, and the gain times the whole.
cv::Mat Frame(const cv::Mat& ground, int n, const std::vector<Mover>& movers, double gain,
              std::mt19937* random) {
  const Eigen::Vector2d shift = kCameraStep * n;
  cv::Mat shifted;
  cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, -shift.x(), 0, 1, -shift.y());
  cv::warpAffine(ground, shifted, m, cv::Size(kWidth, kHeight), cv::INTER_LINEAR);
  for (const Mover& mover : movers) {
    const Eigen::Vector2d c = mover.centre - shift;
    for (int y = int(c.y() - mover.half.y()) - 1; y <= int(c.y() + mover.half.y()) + 1; ++y) {
      for (int x = int(c.x() - mover.half.x()) - 1; x <= int(c.x() + mover.half.x()) + 1; ++x) {
        if (x < 0 || y < 0 || x >= kWidth || y >= kHeight) continue;
        int inside = 0;
        for (int sy = 0; sy < 4; ++sy) {
          for (int sx = 0; sx < 4; ++sx) {
            const Eigen::Vector2d p(x - 0.375 + 0.25 * sx, y - 0.375 + 0.25 * sy);
            inside += ((p - c).cwiseAbs() - mover.half).maxCoeff() <= 0;
          }
        }
        float& v = shifted.at<float>(y, x);
        v = float(v + (40.0 - v) * inside / 16.0);
      }
    }
  }
  std::normal_distribution<float> noise(0, 1.5f);
  cv::Mat out(kHeight, kWidth, CV_8U);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      out.at<uint8_t>(y, x) =
          cv::saturate_cast<uint8_t>(gain * (shifted.at<float>(y, x) + noise(*random)));
    }
  }
  return out;
}

Eigen::Matrix3d CameraMotion() {
  Eigen::Matrix3d h = Eigen::Matrix3d::Identity();
  h(0, 2) = -kCameraStep.x();
  h(1, 2) = -kCameraStep.y();
  return h;
}

ChangeOptions SmallFrameOptions() {
  ChangeOptions options;
  options.processing_width = 0;  // the frames are small already
  return options;
}

TEST(ChangeDetectorTest, StaticGroundWithGainDriftChangesNowhere) {
  const cv::Mat ground = Ground();
  std::mt19937 random(1);
  ChangeDetector detector(SmallFrameOptions());
  int compared = 0;
  for (int n = 0; n < 60; ++n) {
    const double gain = 1.0 + 0.004 * n;  // 24 % brighter by the end
    const auto& blobs =
        detector.Process(n, Frame(ground, n, {}, gain, &random),
                         n == 0 ? std::nullopt : std::optional<Eigen::Matrix3d>(CameraMotion()));
    compared += detector.frame() >= 0;
    EXPECT_TRUE(blobs.empty()) << "frame " << n << ": " << blobs.size() << " blobs";
  }
  EXPECT_EQ(compared, 60 - 2 * 12);
}

TEST(ChangeDetectorTest, AWalkerIsFoundWhereItIsAndNowhereElse) {
  const cv::Mat ground = Ground();
  std::mt19937 random(2);
  ChangeDetector detector(SmallFrameOptions());
  // Two pixels by three, a quarter of a pixel per frame: a walker from 400 m.
  const auto walker = [](int n) {
    return Mover{Eigen::Vector2d(250, 180) + Eigen::Vector2d(0.25, -0.1) * n,
                 Eigen::Vector2d(1.0, 1.5)};
  };
  int found = 0, frames = 0;
  for (int n = 0; n < 80; ++n) {
    const auto& blobs =
        detector.Process(n, Frame(ground, n, {walker(n)}, 1.0, &random),
                         n == 0 ? std::nullopt : std::optional<Eigen::Matrix3d>(CameraMotion()));
    if (detector.frame() < 0) continue;
    ++frames;
    const int64_t f = detector.frame();
    const Eigen::Vector2d truth = walker(int(f)).centre - kCameraStep * double(f);
    for (const ChangeBlob& blob : blobs) {
      EXPECT_LT((blob.position - truth).norm(), 1.5) << "frame " << f;
      EXPECT_LT(blob.contrast, 0) << "darker than the ground";
      found += (blob.position - truth).norm() < 1.5;
    }
    EXPECT_TRUE(detector.ChangedNear(truth, 2.0)) << "frame " << f;
    EXPECT_FALSE(detector.ChangedNear(truth + Eigen::Vector2d(20, 0), 5.0));
  }
  EXPECT_GE(found, frames * 9 / 10);
}

TEST(ChangeDetectorTest, NoGhostBehindASlowLongMover) {
  // A bar eight pixels long moving along its length at half a pixel per frame: it overlaps itself
  // over the baseline (six pixels), which would leave a ghost behind it if the frame were compared
  // with two earlier ones. (Longer than twice that, nothing of it would change: a slow car is the
  // feature tracks' to find.)
  const cv::Mat ground = Ground();
  std::mt19937 random(3);
  ChangeDetector detector(SmallFrameOptions());
  const auto bar = [](int n) {
    return Mover{Eigen::Vector2d(120, 150) + Eigen::Vector2d(0.5, 0) * n, Eigen::Vector2d(4, 2)};
  };
  int checked = 0;
  for (int n = 0; n < 70; ++n) {
    detector.Process(n, Frame(ground, n, {bar(n)}, 1.0, &random),
                     n == 0 ? std::nullopt : std::optional<Eigen::Matrix3d>(CameraMotion()));
    if (detector.frame() < 0) continue;
    const int64_t f = detector.frame();
    const Eigen::Vector2d centre = bar(int(f)).centre - kCameraStep * double(f);
    // The bar's middle changed (in neither other frame); behind it, where it was, nothing did.
    EXPECT_TRUE(detector.ChangedNear(centre, 2.0)) << "frame " << f;
    for (double behind = 5; behind <= 10; behind += 1) {
      EXPECT_FALSE(detector.ChangedNear(centre - Eigen::Vector2d(behind, 0), 0.5))
          << "ghost " << behind << " px behind, frame " << f;
    }
    ++checked;
  }
  EXPECT_GT(checked, 30);
}

TEST(ChangeDetectorTest, AChainBreakStartsAgain) {
  const cv::Mat ground = Ground();
  std::mt19937 random(4);
  ChangeDetector detector(SmallFrameOptions());
  for (int n = 0; n < 30; ++n) {
    detector.Process(n, Frame(ground, n, {}, 1.0, &random),
                     n == 0 ? std::nullopt : std::optional<Eigen::Matrix3d>(CameraMotion()));
  }
  EXPECT_EQ(detector.frame(), 30 - 1 - 12);
  detector.Process(30, Frame(ground, 30, {}, 1.0, &random), std::nullopt);
  EXPECT_EQ(detector.frame(), -1);
  EXPECT_FALSE(detector.Compared(Eigen::Vector2d(160, 120)));
  for (int n = 31; n < 55; ++n) {
    detector.Process(n, Frame(ground, n, {}, 1.0, &random), CameraMotion());
    EXPECT_EQ(detector.frame(), n < 54 ? -1 : 54 - 12) << n;
  }
  EXPECT_TRUE(detector.Compared(Eigen::Vector2d(160, 120)));
}

TEST(ChangeDetectorTest, OptionsAreChecked) {
  ChangeOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.baseline_frames = 0;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.max_area_px = 0;
  EXPECT_FALSE(options.Validate().ok());
  BlobTrackOptions tracks;
  EXPECT_TRUE(tracks.Validate().ok());
  tracks.min_hit_fraction = 0;
  EXPECT_FALSE(tracks.Validate().ok());
}

ChangeBlob BlobAt(const Eigen::Vector2d& p) {
  ChangeBlob blob;
  blob.position = p;
  blob.box_min = p - Eigen::Vector2d(1, 1);
  blob.box_max = p + Eigen::Vector2d(1, 1);
  blob.area_px = 4;
  blob.contrast = -50;
  return blob;
}

TEST(BlobTrackerTest, ASteadyMoverIsConfirmedAndJitterIsNot) {
  BlobTracker tracker({});
  std::mt19937 random(5);
  std::normal_distribution<double> jitter(0, 0.4);
  std::uniform_real_distribution<double> anywhere(0, 300);
  for (int n = 0; n < 120; ++n) {
    std::vector<ChangeBlob> blobs;
    const Eigen::Vector2d shift = kCameraStep * n;
    // A walker at 0.2 px per frame, seen in 4 frames of 5.
    if (n % 5 != 0) {
      blobs.push_back(BlobAt(Eigen::Vector2d(100, 100) + Eigen::Vector2d(0.2, 0.1) * n - shift +
                             Eigen::Vector2d(jitter(random), jitter(random))));
    }
    // Something that flickers in place on the ground (a glint), and random noise blobs.
    blobs.push_back(
        BlobAt(Eigen::Vector2d(200, 60) - shift + Eigen::Vector2d(jitter(random), jitter(random))));
    blobs.push_back(BlobAt(Eigen::Vector2d(anywhere(random), anywhere(random))));
    tracker.AddFrame(n, blobs, CameraMotion());
  }
  tracker.FinishAll();
  const std::vector<TargetTrack> tracks = tracker.TakeFinished();
  ASSERT_EQ(tracks.size(), 1u);
  const TargetTrack& walker = tracks[0];
  EXPECT_TRUE(walker.confirmed);
  EXPECT_GE(walker.observations.size(), 90u);
  EXPECT_NEAR(walker.observations.back().velocity.x(), 0.2, 0.05);
  EXPECT_NEAR(walker.observations.back().velocity.y(), 0.1, 0.05);
  for (const TargetObservation& o : walker.observations) {
    EXPECT_TRUE(o.features.empty());
    EXPECT_EQ(o.change, ChangeEvidence::kChanged);
  }
}

TEST(SupportedByChangeTest, CountsOnlyWhereTheDetectorLooked) {
  TargetTrack track;
  for (int i = 0; i < 10; ++i) {
    TargetObservation o;
    o.frame = i;
    o.change = i < 4 ? ChangeEvidence::kNotLooked
                     : (i < 7 ? ChangeEvidence::kChanged : ChangeEvidence::kNone);
    track.observations.push_back(o);
  }
  EXPECT_TRUE(SupportedByChange(track, 0.5));  // 3 of the 6 looked at
  EXPECT_FALSE(SupportedByChange(track, 0.6));
  for (TargetObservation& o : track.observations) o.change = ChangeEvidence::kNotLooked;
  EXPECT_TRUE(SupportedByChange(track, 0.9));  // never looked: no evidence against it
}

}  // namespace
}  // namespace saker::track
