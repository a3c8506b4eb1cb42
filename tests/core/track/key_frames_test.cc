#include "core/track/key_frames.h"

#include "core/util/check.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace saker::track {
namespace {

constexpr double kWidth = 1280;
constexpr double kHeight = 720;
constexpr double kSigma = 0.5;

// Test noise from a fully specified engine and our own transforms (see homography_test.cc).
class Noise {
 public:
  explicit Noise(uint64_t seed) : engine_(seed) {}
  double Uniform(double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(engine_() >> 11) * 0x1.0p-53);
  }
  Eigen::Vector2d Gaussian2(double sigma) {
    const double u = 1.0 - Uniform(0, 1);
    const double v = Uniform(0, 1);
    const double r = sigma * std::sqrt(-2.0 * std::log(u));
    return {r * std::cos(2 * M_PI * v), r * std::sin(2 * M_PI * v)};
  }

 private:
  std::mt19937_64 engine_;
};

// A camera flying over flat ground: frame_from_ground is a slow rotation and a steady shift
// (speed_px per frame along x, a little along y), under a fixed mild perspective.
class Flight {
 public:
  explicit Flight(double speed_px) : speed_px_(speed_px) {}
  Eigen::Matrix3d FrameFromGround(int64_t n) const {
    Eigen::Matrix3d centre;
    centre << 1, 0, kWidth / 2, 0, 1, kHeight / 2, 0, 0, 1;
    Eigen::Matrix3d perspective = Eigen::Matrix3d::Identity();
    perspective(2, 0) = 1.5e-5;
    perspective(2, 1) = -2e-5;
    const double angle = 0.002 * static_cast<double>(n);
    Eigen::Matrix3d motion = Eigen::Matrix3d::Identity();
    motion.topLeftCorner<2, 2>() = Eigen::Rotation2Dd(angle).toRotationMatrix();
    const Eigen::Vector2d position(speed_px_ * static_cast<double>(n),
                                   0.1 * speed_px_ * static_cast<double>(n));
    motion.topRightCorner<2, 1>() = -motion.topLeftCorner<2, 2>() * position;
    return centre * perspective * motion;
  }
  // Truth of a sequential link: key frame `to` from key frame `from`.
  Eigen::Matrix3d ToFromFrom(int64_t to, int64_t from) const {
    const Eigen::Matrix3d h = FrameFromGround(to) * FrameFromGround(from).inverse();
    return h / h(2, 2);
  }

 private:
  double speed_px_;
};

// Ground points scattered over the strip the camera sees in `frames` frames (about
// `per_frame` of them in view at once), observed with independent noise in every frame.
class Stream {
 public:
  // The ground comes from `seed`; the observation noise too, or from noise_seed when given (so
  // Monte Carlo trials share one scene).
  Stream(const Flight& flight, int frames, int per_frame, uint64_t seed,
         std::optional<uint64_t> noise_seed = std::nullopt)
      : flight_(flight), noise_(seed) {
    const double length = 1.2 * 20 * frames + 2 * kWidth;
    const double area = length * 2 * kWidth;
    const int count = static_cast<int>(per_frame * area / (kWidth * kHeight));
    for (int i = 0; i < count; ++i) {
      ground_.emplace_back(noise_.Uniform(-kWidth, length - kWidth),
                           noise_.Uniform(-kWidth, kWidth));
    }
    if (noise_seed) noise_ = Noise(*noise_seed);
  }

  // The points in view in frame n: ground index -> observed pixel position.
  std::map<int, Eigen::Vector2d> Observe(int64_t n) {
    std::map<int, Eigen::Vector2d> seen;
    const Eigen::Matrix3d h = flight_.FrameFromGround(n);
    for (size_t i = 0; i < ground_.size(); ++i) {
      const Eigen::Vector2d p = (h * ground_[i].homogeneous()).hnormalized();
      if (p.x() < 2 || p.y() < 2 || p.x() > kWidth - 3 || p.y() > kHeight - 3) continue;
      seen[static_cast<int>(i)] = p + noise_.Gaussian2(kSigma);
    }
    return seen;
  }

 private:
  const Flight& flight_;
  Noise noise_;
  std::vector<Eigen::Vector2d> ground_;
};

// The frame-to-frame estimate a tracker would give: the points seen in both frames.
std::optional<HomographyEstimate> FrameToFrame(const std::map<int, Eigen::Vector2d>& previous,
                                               const std::map<int, Eigen::Vector2d>& current) {
  std::vector<Correspondence> correspondences;
  for (const auto& [index, p] : current) {
    const auto it = previous.find(index);
    if (it != previous.end()) correspondences.push_back({FeatureTrackId{index}, it->second, p});
  }
  HomographyOptions options;
  options.measurement_sigma_px = kSigma;
  StatusOr<HomographyEstimate> estimate = EstimateHomography(correspondences, options);
  if (!estimate.ok()) return std::nullopt;
  return *std::move(estimate);
}

// Track ids for the observed points: the ground index, or (renew_every > 0) a fresh id for
// every point each renew_every frames, as if the tracker lost and re-found them all at once.
std::vector<StationaryPoint> Tracks(const std::map<int, Eigen::Vector2d>& seen, int64_t n,
                                    int renew_every) {
  std::vector<StationaryPoint> tracks;
  for (const auto& [index, p] : seen) {
    int64_t id = index;
    if (renew_every > 0) id = int64_t{index} * 1000 + n / renew_every;
    tracks.push_back({FeatureTrackId{id}, p});
  }
  return tracks;
}

// Squared Mahalanobis distance of each image corner's transfer error under the link's
// covariance; the largest of the four.
double WorstCornerChi2(const Eigen::Matrix3d& estimate, const HomographyCovariance& cov,
                       const Eigen::Matrix3d& truth) {
  double worst = 0;
  for (const Eigen::Vector2d& corner :
       {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(kWidth - 0.5, -0.5),
        Eigen::Vector2d(kWidth - 0.5, kHeight - 0.5), Eigen::Vector2d(-0.5, kHeight - 0.5)}) {
    const Eigen::Vector2d error = Transfer(estimate, corner) - Transfer(truth, corner);
    const Eigen::Matrix2d c = TransferCovariance(estimate, cov, corner);
    worst = std::max(worst, error.dot(c.ldlt().solve(error)));
  }
  return worst;
}

double WorstCornerError(const Eigen::Matrix3d& estimate, const Eigen::Matrix3d& truth) {
  double worst = 0;
  for (const Eigen::Vector2d& corner :
       {Eigen::Vector2d(-0.5, -0.5), Eigen::Vector2d(kWidth - 0.5, -0.5),
        Eigen::Vector2d(kWidth - 0.5, kHeight - 0.5), Eigen::Vector2d(-0.5, kHeight - 0.5)}) {
    worst = std::max(worst, (Transfer(estimate, corner) - Transfer(truth, corner)).norm());
  }
  return worst;
}

std::set<FeatureTrackId> Ids(const std::vector<StationaryPoint>& points) {
  std::set<FeatureTrackId> ids;
  for (const auto& p : points) ids.insert(p.first);
  return ids;
}

TEST(KeyFrameChainTest, KeyFramesExactlyWhenSharedFractionDropsTo30Percent) {
  const Flight flight(16);
  Stream stream(flight, 200, 200, 1);
  KeyFrameChain chain(KeyFrameOptions{});
  std::map<int, Eigen::Vector2d> previous;
  std::set<FeatureTrackId> last_key_ids;
  for (int64_t n = 0; n < 200; ++n) {
    const std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
    const std::vector<StationaryPoint> tracks = Tracks(seen, n, 0);
    const std::optional<HomographyEstimate> from_previous =
        n == 0 ? std::nullopt : FrameToFrame(previous, seen);
    ASSERT_TRUE(n == 0 || from_previous) << "frame " << n;
    const FrameOutcome outcome = chain.AddFrame(n, tracks, from_previous);

    // The rule, recomputed from the stream: shared with the last key frame / its count.
    bool expect_key = n == 0;
    if (n > 0) {
      int shared = 0;
      for (const auto& [id, p] : tracks) shared += last_key_ids.count(id) ? 1 : 0;
      const double fraction = static_cast<double>(shared) / last_key_ids.size();
      ASSERT_TRUE(outcome.shared_fraction.has_value());
      EXPECT_DOUBLE_EQ(*outcome.shared_fraction, fraction);
      expect_key = fraction <= 0.3;
    }
    EXPECT_EQ(outcome.key_frame.has_value(), expect_key) << "frame " << n;
    EXPECT_FALSE(outcome.chain_break);
    if (outcome.key_frame) last_key_ids = Ids(tracks);
    previous = seen;
  }

  // 16 px a frame across and 1.6 px down: 30 % of the area left after about 45 frames.
  std::cout << "  key frames at";
  for (const KeyFrame& key : chain.key_frames()) std::cout << " " << key.frame_index;
  std::cout << "\n";
  ASSERT_EQ(chain.key_frames().size(), 5u);
  ASSERT_EQ(chain.links().size(), 4u);
  EXPECT_TRUE(chain.breaks().empty());
  for (size_t k = 0; k < chain.key_frames().size(); ++k) {
    const KeyFrame& key = chain.key_frames()[k];
    EXPECT_EQ(key.id, KeyFrameId{static_cast<int32_t>(k)});
    EXPECT_EQ(key.segment, 0);
    EXPECT_TRUE(std::is_sorted(key.points.begin(), key.points.end(),
                               [](const auto& a, const auto& b) { return a.first < b.first; }));
  }
  for (const SequentialLink& link : chain.links()) {
    const KeyFrame& from = chain.key_frames()[static_cast<size_t>(link.from)];
    const KeyFrame& to = chain.key_frames()[static_cast<size_t>(link.to)];
    EXPECT_EQ(static_cast<int32_t>(link.to), static_cast<int32_t>(link.from) + 1);
    EXPECT_FALSE(link.chained) << "about 60 tracks span consecutive key frames";
    EXPECT_GE(link.correspondences.size(), 20u);
    const Eigen::Matrix3d truth = flight.ToFromFrom(to.frame_index, from.frame_index);
    // Within the 99.9 % ellipse of the link's own covariance at every corner. The corners far
    // from the 30 % overlap are extrapolated (several pixels of error, and of predicted sd);
    // where the shared tracks are, the link is good to a fraction of a pixel.
    EXPECT_LT(WorstCornerChi2(link.to_from_from, link.covariance, truth), 13.8);
    double sum_squares = 0;
    for (const Correspondence& c : link.correspondences) {
      const double error =
          (Transfer(link.to_from_from, c.source) - Transfer(truth, c.source)).norm();
      EXPECT_LT(error, 1.0);
      sum_squares += error * error;
    }
    EXPECT_LT(std::sqrt(sum_squares / link.correspondences.size()), 0.5);
  }
}

TEST(KeyFrameChainTest, ChainedLinksWhenNoTrackSpansTwoKeyFrames) {
  const Flight flight(16);
  Stream stream(flight, 40, 150, 2);
  KeyFrameChain chain(KeyFrameOptions{});
  std::map<int, Eigen::Vector2d> previous;
  // The frame-to-frame estimates since the last key frame, composed here independently.
  HomographyWithCovariance expected;
  for (int64_t n = 0; n < 40; ++n) {
    const std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
    const std::optional<HomographyEstimate> from_previous =
        n == 0 ? std::nullopt : FrameToFrame(previous, seen);
    if (n > 0) {
      ASSERT_TRUE(from_previous);
      const auto composed = Compose(from_previous->target_from_source, from_previous->covariance,
                                    expected.target_from_source, expected.covariance);
      ASSERT_TRUE(composed.ok());
      expected = *composed;
    }
    // Every track is renewed each 6 frames: frame 6k shares nothing with frame 6k - 6.
    const FrameOutcome outcome = chain.AddFrame(n, Tracks(seen, n, 6), from_previous);
    EXPECT_EQ(outcome.key_frame.has_value(), n % 6 == 0) << "frame " << n;
    if (outcome.link) {
      const SequentialLink& link = chain.links()[*outcome.link];
      EXPECT_TRUE(link.chained);
      EXPECT_TRUE(link.correspondences.empty());
      EXPECT_TRUE(link.to_from_from.isApprox(expected.target_from_source, 1e-12));
      EXPECT_TRUE(link.covariance.isApprox(expected.covariance, 1e-9));
      const Eigen::Matrix3d truth = flight.ToFromFrom(n, n - 6);
      EXPECT_LT(WorstCornerChi2(link.to_from_from, link.covariance, truth), 13.8);
      EXPECT_LT(WorstCornerError(link.to_from_from, truth), 1.5);
      // Six frame-to-frame steps are less certain than one.
      EXPECT_GT(link.covariance(2, 2), 3 * from_previous->covariance(2, 2));
    }
    if (outcome.key_frame) expected = HomographyWithCovariance{};
    previous = seen;
  }
  EXPECT_EQ(chain.key_frames().size(), 7u);
  EXPECT_EQ(chain.links().size(), 6u);
}

// The chained covariance assumes independent frame-to-frame estimates. Monte Carlo over 200
// noise draws of one 6-frame chain: with each estimate made from its own observations, the
// prediction is right; when consecutive estimates share frame n's measured positions (a real
// tracker), their errors partly cancel and the prediction is conservative.
TEST(KeyFrameChainTest, ChainedCovarianceAgainstMonteCarlo) {
  const Flight flight(16);
  for (bool shared_measurements : {false, true}) {
    SCOPED_TRACE(shared_measurements ? "shared measurements" : "independent measurements");
    std::vector<HomographyParameters> samples;
    HomographyCovariance predicted = HomographyCovariance::Zero();
    const int trials = 200;
    for (int t = 0; t < trials; ++t) {
      Stream stream(flight, 7, 150, 9, 1000 + t);
      KeyFrameChain chain(KeyFrameOptions{});
      std::map<int, Eigen::Vector2d> previous;
      for (int64_t n = 0; n <= 6; ++n) {
        const std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
        std::optional<HomographyEstimate> from_previous;
        if (n > 0) {
          from_previous =
              FrameToFrame(shared_measurements ? previous : stream.Observe(n - 1), seen);
        }
        chain.AddFrame(n, Tracks(seen, n, 6), from_previous);
        previous = seen;
      }
      ASSERT_EQ(chain.links().size(), 1u);
      ASSERT_TRUE(chain.links()[0].chained);
      samples.push_back(ParametersFromHomography(chain.links()[0].to_from_from));
      predicted += chain.links()[0].covariance / trials;
    }
    HomographyParameters mean = HomographyParameters::Zero();
    for (const auto& s : samples) mean += s / trials;
    HomographyCovariance empirical = HomographyCovariance::Zero();
    for (const auto& s : samples) empirical += (s - mean) * (s - mean).transpose() / (trials - 1);
    std::cout << "  chained, " << (shared_measurements ? "shared" : "independent")
              << " measurements: empirical / predicted variance";
    for (int k = 0; k < 8; ++k) {
      const double ratio = empirical(k, k) / predicted(k, k);
      std::cout << " " << ratio;
      // 200 samples: 10 % relative sd on a variance.
      if (shared_measurements) {
        EXPECT_LT(ratio, 0.8) << "parameter " << k;
      } else {
        EXPECT_NEAR(ratio, 1.0, 0.3) << "parameter " << k;
      }
    }
    std::cout << "\n";
  }
}

// Few tracks shared (below min_points) also chains, even though some tracks span the link.
TEST(KeyFrameChainTest, ChainedLinkWhenTooFewSharedTracks) {
  const Flight flight(16);
  Stream stream(flight, 80, 40, 3);
  KeyFrameOptions options;
  options.homography.min_inliers = 10;
  options.min_points = 15;
  KeyFrameChain chain(options);
  std::map<int, Eigen::Vector2d> previous;
  for (int64_t n = 0; n < 80; ++n) {
    const std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
    chain.AddFrame(n, Tracks(seen, n, 0), n == 0 ? std::nullopt : FrameToFrame(previous, seen));
    previous = seen;
  }
  ASSERT_GE(chain.links().size(), 1u);
  for (const SequentialLink& link : chain.links()) {
    // About 30 % of 40 points: fewer than 15.
    EXPECT_TRUE(link.chained);
    EXPECT_LT(link.correspondences.size(), 15u);
    EXPECT_GT(link.correspondences.size(), 0u);
    for (const Correspondence& c : link.correspondences) {
      const KeyFrame& from = chain.key_frames()[static_cast<size_t>(link.from)];
      const auto it = std::lower_bound(
          from.points.begin(), from.points.end(), c.id,
          [](const StationaryPoint& p, FeatureTrackId id) { return p.first < id; });
      ASSERT_NE(it, from.points.end());
      EXPECT_EQ(it->second, c.source);
    }
  }
}

TEST(KeyFrameChainTest, FailedEstimateBreaksTheChainAndACutStartsANewSegment) {
  const Flight flight(16);
  Stream stream(flight, 100, 200, 4);
  KeyFrameChain chain(KeyFrameOptions{});
  std::map<int, Eigen::Vector2d> previous;
  for (int64_t n = 0; n < 100; ++n) {
    const std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
    std::optional<HomographyEstimate> from_previous =
        n == 0 ? std::nullopt : FrameToFrame(previous, seen);
    if (n == 30) from_previous.reset();  // a cut: the tracker could not relate 30 to 29
    const FrameOutcome outcome = chain.AddFrame(n, Tracks(seen, n, 0), from_previous);
    EXPECT_EQ(outcome.chain_break, n == 30) << "frame " << n;
    if (n == 30) {
      // Frame 30 has plenty of points: it starts segment 1 at once.
      ASSERT_TRUE(outcome.key_frame.has_value());
      EXPECT_FALSE(outcome.link.has_value());
      EXPECT_FALSE(outcome.shared_fraction.has_value());
      EXPECT_EQ(chain.key_frames().back().segment, 1);
    }
    previous = seen;
  }
  ASSERT_EQ(chain.breaks().size(), 1u);
  EXPECT_EQ(chain.breaks()[0].frame_index, 30);
  EXPECT_NE(chain.breaks()[0].reason.find("frame 29 to frame 30"), std::string::npos)
      << chain.breaks()[0].reason;
  // Segment 0 ends at frame 29, before its 30 % point: one key frame (0). Segment 1 starts at
  // 30 and reaches its 30 % point near frame 86. Links only inside segments.
  ASSERT_EQ(chain.key_frames().size(), 3u);
  EXPECT_EQ(chain.key_frames()[0].frame_index, 0);
  EXPECT_EQ(chain.key_frames()[1].frame_index, 30);
  EXPECT_EQ(chain.key_frames()[2].segment, 1);
  for (const SequentialLink& link : chain.links()) {
    EXPECT_EQ(chain.key_frames()[static_cast<size_t>(link.from)].segment,
              chain.key_frames()[static_cast<size_t>(link.to)].segment);
  }
  ASSERT_EQ(chain.links().size(), 1u);
  EXPECT_EQ(chain.links()[0].from, KeyFrameId{1});
}

TEST(KeyFrameChainTest, BlankFramesWaitForEnoughPoints) {
  const Flight flight(16);
  Stream stream(flight, 40, 200, 5);
  KeyFrameChain chain(KeyFrameOptions{});
  std::map<int, Eigen::Vector2d> previous;
  for (int64_t n = 0; n < 40; ++n) {
    std::map<int, Eigen::Vector2d> seen = stream.Observe(n);
    // Frames 0-1 and 20-21 are blank (no points, so nothing to estimate from or to).
    const bool blank = n <= 1 || n == 20 || n == 21;
    if (blank) seen.clear();
    std::optional<HomographyEstimate> from_previous;
    if (!blank && !previous.empty()) from_previous = FrameToFrame(previous, seen);
    const FrameOutcome outcome = chain.AddFrame(n, Tracks(seen, n, 0), from_previous);
    EXPECT_EQ(outcome.chain_break, n == 20) << "frame " << n;
    EXPECT_EQ(outcome.key_frame.has_value(), n == 2 || n == 22) << "frame " << n;
    EXPECT_EQ(chain.in_segment(), !(n <= 1 || n == 20 || n == 21)) << "frame " << n;
    previous = seen;
  }
  ASSERT_EQ(chain.breaks().size(), 1u);
  ASSERT_EQ(chain.key_frames().size(), 2u);
  EXPECT_EQ(chain.key_frames()[0].segment, 0);
  EXPECT_EQ(chain.key_frames()[1].segment, 1);
  EXPECT_TRUE(chain.links().empty());
}

TEST(KeyFrameChainTest, OptionsAndMisuse) {
  EXPECT_TRUE(KeyFrameOptions{}.Validate().ok());
  KeyFrameOptions bad;
  bad.min_shared_fraction = 1.0;
  EXPECT_EQ(bad.Validate().code(), StatusCode::kInvalidArgument);
  bad = KeyFrameOptions{};
  bad.min_points = 10;  // fewer than the 15 inliers a direct link needs
  EXPECT_EQ(bad.Validate().code(), StatusCode::kInvalidArgument);
  bad = KeyFrameOptions{};
  bad.homography.measurement_sigma_px = -1;
  EXPECT_FALSE(bad.Validate().ok());
  EXPECT_THROW(KeyFrameChain{bad}, CheckError);

  KeyFrameChain chain(KeyFrameOptions{});
  chain.AddFrame(5, {}, std::nullopt);
  EXPECT_THROW(chain.AddFrame(5, {}, std::nullopt), CheckError);
  EXPECT_THROW(
      chain.AddFrame(6, {{FeatureTrackId{1}, {1, 2}}, {FeatureTrackId{1}, {3, 4}}}, std::nullopt),
      CheckError);
  EXPECT_TRUE(chain.key_frames().empty());
}

}  // namespace
}  // namespace saker::track
