#pragma once
// Loop closure (paper: "Geometric Feature Matching", "Appearance Based Feature Matching"):
// cross-links between non-sequential key frames, where no feature track joins them.
//
// Each key frame's Harris points (its stationary points) are described by SIFT computed on the
// key frame's downscaled grey copy, with a dominant orientation estimated per point so that a
// loop coming back with another heading still matches. Then
// - geometric matching, where the predicted overlap is certain enough: a feature of `a` is
//   compared only with the features of `b` inside its projected uncertainty ellipse;
// - appearance matching, where the camera is lost: mutual nearest neighbours without geometry;
// both verified by a robust homography (track::EstimateHomography) and a sanity check
// (PlausibleHomography). AppearanceIndex, a bag of visual words, proposes the few key frames worth
// an appearance matching, so a new key frame never costs O(n) SIFT matchings.
#include "core/mosaic/link_graph.h"
#include "core/track/key_frames.h"
#include "core/track/types.h"
#include "core/util/status.h"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

namespace saker::mosaic {

struct DescribeOptions {
  // SIFT keypoint size in pixels of the downscaled image: the descriptor covers a square of
  // 4 x 1.5 x size on a side (36 px at 6, about 6 % of a 640 px key frame), the orientation a
  // Gaussian window of sigma 0.75 x size. Fixed: key frames are taken at about the same altitude.
  double keypoint_size_px = 6.0;
  // At most this many points are described; beyond it the points with the strongest gradients
  // are kept, spread over an 8 x 8 grid so the homography stays well conditioned.
  int max_features = 1000;
  // Gaussian blur (pixels of the downscaled image) before the orientation gradients; SIFT
  // itself blurs with its own base sigma of 1.6.
  double orientation_blur_sigma_px = 1.0;
  Status Validate() const;
};

struct KeyFrameFeatures {
  KeyFrameId id{};
  std::vector<Eigen::Vector2d> points;           // full-resolution pixels
  std::vector<track::FeatureTrackId> track_ids;  // same order as points
  cv::Mat descriptors;                           // CV_32F, one SIFT row per point
  size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
};

// SIFT descriptors (with a computed dominant orientation: the peak of a Gaussian-weighted
// 36-bin gradient-orientation histogram, refined by a parabola) of the key frame's Harris points,
// computed on its downscaled grey image (`scale` = full px per grey px, the grey image being
// cv::resize(full, 1 / scale)). Points closer to the border than half the descriptor square
// (3 x keypoint_size_px grey pixels) are dropped.
// Never crashes on empty images / no points (returns empty). `grey` is CV_8UC1 (a 3-channel
// image is converted). `scale` must be positive and the options valid (SAKER_CHECK).
KeyFrameFeatures DescribeKeyFrame(KeyFrameId id, const cv::Mat& grey, double scale,
                                  const std::vector<track::StationaryPoint>& points,
                                  const DescribeOptions& options);

struct MatchOptions {
  double ratio = 0.8;              // Lowe's ratio test: best / second best descriptor distance
  int min_inliers = 25;            // a proposal needs this many homography inliers (>= 5)
  double ransac_threshold_px = 3;  // full-resolution pixels; the homography's measurement sigma
                                   // is a sixth of it (homography.h), inflated a posteriori
  double confidence = 0.99;        // of the uncertainty ellipses (geometric matching)
  double point_sigma_px = 1.0;     // feature position noise added to the prediction covariance
  // A match is never accepted beyond this descriptor distance (OpenCV SIFT descriptors have an
  // L2 norm of about 512). Measured on the simulator's town (two renderings, 90 degrees and 5 %
  // zoom apart): true pairs median 58, 90 % below 200; the nearest descriptor in an unrelated view
  // median 320, 10 % below 150. Real video is noisier than renderings, hence the margin. It is the
  // only test for a geometric candidate alone in its ellipse.
  double max_descriptor_distance = 250;

  // Sanity limits of PlausibleHomography, for key frames of a downward-looking camera at about
  // the same altitude. Local scale: sqrt(det) of the Jacobian of the map, checked at the
  // corners (where its extremes are).
  double min_scale = 0.5;
  double max_scale = 2.0;
  // Largest ratio of the Jacobian's singular values (skew / anisotropic stretch) at the corners
  // and the centre.
  double max_anisotropy = 2.0;
  // Perspective: the homogeneous w of the map at the four corners must be positive (the image
  // does not cross the horizon line) and max(w) / min(w) at most this.
  double max_perspective = 1.5;
  // The image of `a` mapped into `b` must cover at least this fraction of `b`'s area.
  double min_overlap_fraction = 0.1;

  Status Validate() const;
};

// Geometric matching. `b_from_a_predicted` maps a's pixels into b's; `covariance_in_b(p)` is the
// 2x2 pixel covariance in b of the prediction at a's point p. Each feature of a is compared only
// with features of b inside its ellipse at options.confidence (Mahalanobis gate on the
// prediction covariance plus point_sigma_px^2 for the point in b and the same propagated from
// a); the best descriptor is taken when it passes the ratio test among those candidates and
// max_descriptor_distance (alone in its ellipse, only the latter); a feature of b claimed by
// several of a keeps the closest. Then track::EstimateHomography on the matches (source in a,
// target in b). Returns a Link {from = a.id, to = b.id, kind = kGeometric, to_from_from,
// covariance, correspondences = inliers (ids: a's track ids)} when there are >= min_inliers
// inliers and PlausibleHomography holds; nullopt otherwise. `width` x `height`: full-resolution
// image size. The options must be valid (SAKER_CHECK).
std::optional<Link> MatchGeometric(
    const KeyFrameFeatures& a, const KeyFrameFeatures& b, const Eigen::Matrix3d& b_from_a_predicted,
    const std::function<Eigen::Matrix2d(const Eigen::Vector2d&)>& covariance_in_b, int width,
    int height, const MatchOptions& options);

// Appearance matching: mutual nearest neighbours (brute force, L2) passing the ratio test and
// max_descriptor_distance, no geometry; then the same robust estimate and checks;
// kind = kAppearance.
std::optional<Link> MatchAppearance(const KeyFrameFeatures& a, const KeyFrameFeatures& b, int width,
                                    int height, const MatchOptions& options);

// Sane homography between two key frames of width x height taken at about the same altitude:
// finite, orientation preserving, local scale within [min_scale, max_scale] over the image,
// anisotropy and perspective within limits, and the frames overlap by at least
// min_overlap_fraction.
bool PlausibleHomography(const Eigen::Matrix3d& b_from_a, int width, int height,
                         const MatchOptions& options);

struct AppearanceIndexOptions {
  int words = 256;              // vocabulary size (k-means centres)
  int training_key_frames = 8;  // the vocabulary is trained once this many frames were added
  uint64_t seed = 1;            // of k-means++ seeding, so training is deterministic
  int kmeans_iterations = 10;   // Lloyd iterations of the training
  // Training uses at most this many descriptors, taken evenly from the training frames.
  int max_training_descriptors = 20000;
  Status Validate() const;
};

// Bag of visual words with an inverted file. Each frame is a histogram of the words of its
// descriptors, normalised to sum 1 (term frequency); the similarity of two frames is the
// histogram intersection weighted by the inverse document frequency,
//   s(q, f) = sum over words w of idf(w) min(tf_q(w), tf_f(w)),  idf(w) = log(1 + N / n(w)),
// with N frames indexed and n(w) of them holding w (the smoothed idf stays positive when a word is
// everywhere, which a small vocabulary makes common). It needs no per-frame norm, so adding frames
// never rescales the ones already indexed. Query quantises the query's descriptors (one pass over
// the vocabulary) and then reads only the posting lists of the query's words.
//
// The vocabulary is trained once, by k-means (k-means++ seeding from `seed`, deterministic) on the
// descriptors of the first `training_key_frames` frames added, as soon as they hold at least
// `words` descriptors; the frames added before are indexed then. Before training, Query returns
// the frames added so far, newest first, with similarity 0 (there are at most a handful).
class AppearanceIndex {
 public:
  // The options must be valid (SAKER_CHECK).
  explicit AppearanceIndex(const AppearanceIndexOptions& options);
  void Add(const KeyFrameFeatures& features);
  // The best `count` key frames added earlier, by similarity (highest first, ties by id), skipping
  // the query's own id and those for which skip(id) is true. After training only frames sharing
  // a word with the query are returned.
  std::vector<std::pair<KeyFrameId, double>> Query(
      const KeyFrameFeatures& features, int count,
      const std::function<bool(KeyFrameId)>& skip = {}) const;
  size_t size() const { return ids_.size(); }
  bool trained() const { return !vocabulary_.empty(); }

 private:
  struct Posting {
    uint32_t frame;  // index into ids_
    float tf;
  };
  bool Train();  // false when the pending descriptors cannot train a vocabulary
  void Index(uint32_t frame, const cv::Mat& descriptors);
  // Term frequencies of the descriptors' words: (word, tf) sorted by word.
  std::vector<std::pair<int, float>> Histogram(const cv::Mat& descriptors) const;

  AppearanceIndexOptions options_;
  std::vector<KeyFrameId> ids_;                 // in the order added
  std::vector<cv::Mat> pending_;                // descriptors of the frames added before training
  cv::Mat vocabulary_;                          // words x 128, CV_32F; empty until trained
  std::vector<std::vector<Posting>> postings_;  // per word
};

}  // namespace saker::mosaic
