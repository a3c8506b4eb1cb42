#include "core/track/key_frames.h"

#include <algorithm>
#include <sstream>

namespace saker::track {
namespace {

bool ById(const StationaryPoint& a, const StationaryPoint& b) { return a.first < b.first; }

// Correspondences (source in the key frame, target in this frame) of the tracks both see; both
// lists are sorted by id.
std::vector<Correspondence> Shared(const std::vector<StationaryPoint>& key_frame,
                                   const std::vector<StationaryPoint>& frame) {
  std::vector<Correspondence> shared;
  auto k = key_frame.begin();
  auto f = frame.begin();
  while (k != key_frame.end() && f != frame.end()) {
    if (k->first < f->first) {
      ++k;
    } else if (f->first < k->first) {
      ++f;
    } else {
      shared.push_back({k->first, k->second, f->second});
      ++k;
      ++f;
    }
  }
  return shared;
}

HomographyWithCovariance Identity() { return {}; }

}  // namespace

Status KeyFrameOptions::Validate() const {
  if (!(min_shared_fraction >= 0 && min_shared_fraction < 1)) {
    std::ostringstream message;
    message << "min_shared_fraction = " << min_shared_fraction << " must be in [0, 1)";
    return InvalidArgumentError(message.str());
  }
  SAKER_RETURN_IF_ERROR(homography.Validate());
  if (min_points < homography.min_inliers) {
    std::ostringstream message;
    message << "min_points = " << min_points
            << " must be at least homography.min_inliers = " << homography.min_inliers
            << " (a direct link needs that many inliers)";
    return InvalidArgumentError(message.str());
  }
  return Status::Ok();
}

KeyFrameChain::KeyFrameChain(const KeyFrameOptions& options)
    : options_(options), since_key_frame_(Identity()) {
  const Status status = options.Validate();
  SAKER_CHECK(status.ok()) << status.ToString();
}

KeyFrameId KeyFrameChain::AddKeyFrame(int64_t frame_index,
                                      std::vector<StationaryPoint> sorted_points) {
  KeyFrame key_frame;
  key_frame.id = KeyFrameId{static_cast<int32_t>(key_frames_.size())};
  key_frame.frame_index = frame_index;
  key_frame.segment = segment_;
  key_frame.points = std::move(sorted_points);
  key_frames_.push_back(std::move(key_frame));
  since_key_frame_ = Identity();
  return key_frames_.back().id;
}

void KeyFrameChain::Break(int64_t frame_index, std::string reason, FrameOutcome* outcome) {
  breaks_.push_back({frame_index, std::move(reason)});
  in_segment_ = false;
  since_key_frame_ = Identity();
  outcome->chain_break = true;
}

void KeyFrameChain::ContinueFrom(KeyFrame last) {
  SAKER_CHECK(key_frames_.empty() && !last_frame_index_)
      << "a chain goes on from a key frame only when new";
  segment_ = 0;
  in_segment_ = true;
  last_frame_index_ = last.frame_index;
  std::sort(last.points.begin(), last.points.end(), ById);
  AddKeyFrame(last.frame_index, std::move(last.points));
}

FrameOutcome KeyFrameChain::AddFrame(int64_t frame_index,
                                     const std::vector<StationaryPoint>& stationary,
                                     const std::optional<HomographyEstimate>& from_previous) {
  SAKER_CHECK(!last_frame_index_ || frame_index > *last_frame_index_)
      << "frame " << frame_index << " after frame " << *last_frame_index_;
  last_frame_index_ = frame_index;
  std::vector<StationaryPoint> points = stationary;
  std::sort(points.begin(), points.end(), ById);
  for (size_t i = 0; i < points.size(); ++i) {
    SAKER_CHECK(points[i].second.allFinite()) << "frame " << frame_index << ": point not finite";
    SAKER_CHECK(i == 0 || points[i - 1].first != points[i].first)
        << "frame " << frame_index << ": track " << static_cast<int64_t>(points[i].first)
        << " given twice";
  }

  FrameOutcome outcome;
  if (in_segment_) {
    const KeyFrame& last = key_frames_.back();
    if (!from_previous) {
      std::ostringstream reason;
      reason << "no homography from frame " << frame_index - 1 << " to frame " << frame_index
             << " (blank or featureless frame, or a cut)";
      Break(frame_index, reason.str(), &outcome);
    } else {
      StatusOr<HomographyWithCovariance> product =
          Compose(from_previous->target_from_source, from_previous->covariance,
                  since_key_frame_.target_from_source, since_key_frame_.covariance);
      if (!product.ok()) {
        std::ostringstream reason;
        reason << "frame-to-frame homographies since key frame " << static_cast<int32_t>(last.id)
               << " (frame " << last.frame_index
               << ") compose to a degenerate homography: " << product.status().message();
        Break(frame_index, reason.str(), &outcome);
      } else {
        since_key_frame_ = *std::move(product);
        std::vector<Correspondence> shared = Shared(last.points, points);
        // A key frame without stationary points shares nothing: every following frame becomes
        // a key frame until one has points again, chained through the frame-to-frame estimates.
        const double fraction = last.points.empty() ? 0.0
                                                    : static_cast<double>(shared.size()) /
                                                          static_cast<double>(last.points.size());
        outcome.shared_fraction = fraction;
        if (fraction <= options_.min_shared_fraction) {
          SequentialLink link;
          link.from = last.id;
          if (static_cast<int>(shared.size()) >= options_.min_points) {
            StatusOr<HomographyEstimate> direct = EstimateHomography(shared, options_.homography);
            if (direct.ok()) {
              link.to_from_from = direct->target_from_source;
              link.covariance = direct->covariance;
              link.correspondences = std::move(direct->inliers);
              link.chained = false;
            } else {
              link.chained = true;
            }
          } else {
            link.chained = true;
          }
          if (link.chained) {
            link.to_from_from = since_key_frame_.target_from_source;
            link.covariance = since_key_frame_.covariance;
            link.correspondences = std::move(shared);
          }
          link.to = AddKeyFrame(frame_index, std::move(points));
          outcome.key_frame = link.to;
          outcome.link = links_.size();
          links_.push_back(std::move(link));
          return outcome;
        }
      }
    }
  }
  if (!in_segment_ && static_cast<int>(points.size()) >= options_.min_points) {
    in_segment_ = true;
    ++segment_;
    outcome.key_frame = AddKeyFrame(frame_index, std::move(points));
  }
  return outcome;
}

}  // namespace saker::track
