#include "core/tiles/pyramid.h"

#include "core/tiles/image_decode.h"
#include "core/track/picture.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>

namespace saker::tiles {
namespace {

struct Box {
  Eigen::Vector2d lo{std::numeric_limits<double>::infinity(),
                     std::numeric_limits<double>::infinity()};
  Eigen::Vector2d hi{-std::numeric_limits<double>::infinity(),
                     -std::numeric_limits<double>::infinity()};
  bool Valid() const { return lo.allFinite() && hi.allFinite(); }
  bool Overlaps(const Box& other) const {
    return lo.x() <= other.hi.x() && other.lo.x() <= hi.x() && lo.y() <= other.hi.y() &&
           other.lo.y() <= hi.y();
  }
};

// The map box of the drawn part of a frame (DrawnPart); invalid when there is none.
Box Footprint(const std::vector<Eigen::Vector2d>& part, const Eigen::Matrix3d& map_from_frame) {
  if (part.size() < 3) return Box{};
  Box box;
  for (const Eigen::Vector2d& c : part) {
    const Eigen::Vector3d q = map_from_frame * c.homogeneous();
    if (!(q.z() > 1e-12) || !q.allFinite()) return Box{};
    box.lo = box.lo.cwiseMin(q.hnormalized());
    box.hi = box.hi.cwiseMax(q.hnormalized());
  }
  return box;
}

// Whether `part` is the whole frame (nothing cut away).
bool WholeFrame(const std::vector<Eigen::Vector2d>& part, int width, int height) {
  return part == mission::BelowSkyLine(std::nullopt, width, height);
}

class Renderer {
 public:
  Renderer(const std::vector<KeyFrameView>& frames, int width, int height,
           const mission::PyramidInfo& info, const PyramidOptions& options, const TileSink& write,
           JobContext* job)
      : frames_(frames), info_(info), options_(options), write_(write), job_(job) {
    boxes_.reserve(frames.size());
    parts_.reserve(frames.size());
    for (const KeyFrameView& frame : frames) {
      colour_ = colour_ || (frame.chroma != nullptr && !frame.chroma->empty());
      parts_.push_back(DrawnPart(frame, width, height));
      cut_.push_back(!WholeFrame(parts_.back(), width, height));
      boxes_.push_back(frame.grey && !frame.grey->empty()
                           ? Footprint(parts_.back(), frame.map_from_frame)
                           : Box{});
    }
  }

  // The tile (level, x, y), rendering and writing its subtree first; empty when nothing covers
  // it.
  StatusOr<cv::Mat> Tile(int level, int x, int y) {
    if (job_ && job_->IsCancelled()) return CancelledError("mosaic tiles: cancelled");
    const Box region = Region(level, x, y);
    std::vector<size_t> covering;
    for (size_t i = 0; i < boxes_.size(); ++i) {
      if (boxes_[i].Valid() && boxes_[i].Overlaps(region)) covering.push_back(i);
    }
    if (covering.empty()) {
      ++summary_.empty_tiles;
      return cv::Mat();
    }
    cv::Mat tile;
    if (level == 0) {
      tile = RenderLevel0(x, y, covering);
      ReportProgress();
    } else {
      const int t = info_.tile_size;
      cv::Mat quad(2 * t, 2 * t, CV_8UC4, cv::Scalar::all(0));
      bool any = false;
      for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
          SAKER_ASSIGN_OR_RETURN(cv::Mat child, Tile(level - 1, 2 * x + dx, 2 * y + dy));
          if (child.empty()) continue;
          child.copyTo(quad(cv::Rect(dx * t, dy * t, t, t)));
          any = true;
        }
      }
      if (!any) return cv::Mat();
      tile = Downsample(quad);
    }
    if (cv::countNonZero(ExtractAlpha(tile)) == 0) {
      ++summary_.empty_tiles;
      return cv::Mat();
    }
    std::vector<uint8_t> bytes;
    if (colour_ && options_.jpeg_quality > 0 && cv::countNonZero(ExtractAlpha(tile) != 255) == 0) {
      cv::Mat bgr;
      cv::cvtColor(tile, bgr, cv::COLOR_BGRA2BGR);
      if (!cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality})) {
        return IoError("mosaic tiles: JPEG encoding failed");
      }
    } else if (!cv::imencode(".png", tile, bytes,
                             {cv::IMWRITE_PNG_COMPRESSION, options_.png_compression})) {
      return IoError("mosaic tiles: PNG encoding failed");
    }
    batch_.push_back({level, x, y, std::move(bytes)});
    ++summary_.tiles_written;
    if (batch_.size() >= 64) SAKER_RETURN_IF_ERROR(Flush());
    return tile;
  }

  Status Flush() {
    if (batch_.empty()) return {};
    SAKER_RETURN_IF_ERROR(write_(batch_));
    batch_.clear();
    return {};
  }

  RenderSummary& summary() { return summary_; }

 private:
  // Map box of a tile (pixel centres of its first and last pixels, widened by half a pixel).
  Box Region(int level, int x, int y) const {
    const double f = static_cast<double>(static_cast<int64_t>(1) << level);
    const double t = info_.tile_size;
    const double u0 = (x * t - 0.5) * f, u1 = ((x + 1) * t - 0.5) * f;
    const double v0 = (y * t - 0.5) * f, v1 = ((y + 1) * t - 0.5) * f;
    const Eigen::Vector2d a =
        info_.map_origin + Eigen::Vector2d(u0 * info_.step_x, v0 * info_.step_y);
    const Eigen::Vector2d b =
        info_.map_origin + Eigen::Vector2d(u1 * info_.step_x, v1 * info_.step_y);
    Box box;
    box.lo = a.cwiseMin(b);
    box.hi = a.cwiseMax(b);
    return box;
  }

  static cv::Mat ExtractAlpha(const cv::Mat& bgra) {
    cv::Mat alpha;
    cv::extractChannel(bgra, alpha, 3);
    return alpha;
  }

  const cv::Mat& Feather(cv::Size size) {
    auto it = feathers_.find({size.width, size.height});
    if (it != feathers_.end()) return it->second;
    // Weight: distance to the border, so that overlapping frames fade into each other.
    cv::Mat inside(size, CV_8U, cv::Scalar(255)), feather;
    cv::rectangle(inside, cv::Rect(0, 0, size.width, size.height), cv::Scalar(0), 1);
    cv::distanceTransform(inside, feather, cv::DIST_L2, 3, CV_32F);
    feather += 1.0f;
    return feathers_.emplace(std::make_pair(size.width, size.height), feather).first->second;
  }

  // A key frame as it is blended: its picture and the weight of its pixels, the feather (the
  // distance to the border). On its overlay mask the weight fades to almost nothing and the
  // picture is filled from the pixels around it, so that another key frame's ground wins there
  // and where none covers the place the map shows a smooth fill rather than text or a hole.
  // Outside its drawn part (the sky, the distant ground) the weight is zero and the feather is
  // the distance to that part's edge. The picture is the grey as it is, or in colour tiles BGR.
  // Made for the last few key frames (the tiles of a region need the same ones), not all.
  struct Layer {
    const cv::Mat* picture;
    const cv::Mat* weight;
  };
  Layer LayerOf(size_t i) {
    const KeyFrameView& frame = frames_[i];
    const cv::Size size = frame.grey->size();
    const bool masked = frame.overlay != nullptr || cut_[i];
    if (!masked && !colour_) return {frame.grey, &Feather(size)};
    for (const OwnLayer& layer : layers_) {
      if (layer.frame == i) return {&layer.picture, &layer.weight};
    }
    OwnLayer layer{i, *frame.grey, Feather(size)};  // shared, never written into
    if (colour_) {
      layer.picture = track::YuvToBgr(
          *frame.grey, frame.chroma != nullptr ? *frame.chroma : cv::Mat(), frame.coding);
    }
    if (masked) Mask(i, &layer);
    constexpr size_t kKept = 8;
    if (layers_.size() >= kKept) layers_.erase(layers_.begin());
    layers_.push_back(std::move(layer));
    return {&layers_.back().picture, &layers_.back().weight};
  }

  struct OwnLayer {
    size_t frame;     // in frames_
    cv::Mat picture;  // filled on the overlay mask; the key frame's grey itself when unchanged
    cv::Mat weight;
  };

  // The weight of a key frame with an overlay mask or a part cut away, and its picture filled on
  // the mask.
  void Mask(size_t i, OwnLayer* layer) {
    const KeyFrameView& frame = frames_[i];
    const cv::Size size = frame.grey->size();
    cv::Mat excluded(size, CV_8U, cv::Scalar(0));
    if (frame.overlay != nullptr) {
      for (int v = 0; v < size.height; ++v) {
        uint8_t* row = excluded.ptr<uint8_t>(v);
        for (int u = 0; u < size.width; ++u) {
          // Grey pixel (u, v) is full-resolution ((u + 0.5) s - 0.5, (v + 0.5) s - 0.5).
          const Eigen::Vector2d full((u + 0.5) * frame.scale - 0.5, (v + 0.5) * frame.scale - 0.5);
          if (frame.overlay->Contains(full)) row[u] = 255;
        }
      }
    }
    // Outside the drawn part: the polygon in grey pixels, 1/16 pixel precision.
    cv::Mat outside(size, CV_8U, cv::Scalar(255));
    if (parts_[i].size() >= 3) {
      constexpr int kShift = 4;
      std::vector<cv::Point> polygon;
      for (const Eigen::Vector2d& p : parts_[i]) {
        const Eigen::Vector2d g = (p.array() + 0.5) / frame.scale - 0.5;
        polygon.emplace_back(static_cast<int>(std::lround(g.x() * (1 << kShift))),
                             static_cast<int>(std::lround(g.y() * (1 << kShift))));
      }
      cv::fillConvexPoly(outside, polygon, cv::Scalar(0), cv::LINE_8, kShift);
    }
    cv::Mat inside(size, CV_8U, cv::Scalar(255)), weight;
    cv::rectangle(inside, cv::Rect(0, 0, size.width, size.height), cv::Scalar(0), 1);
    inside.setTo(0, excluded);
    inside.setTo(0, outside);
    cv::distanceTransform(inside, weight, cv::DIST_L2, 3, CV_32F);
    weight += 1.0f;
    constexpr float kFillWeight = 1e-3f;
    weight.setTo(kFillWeight, excluded);
    weight.setTo(0.0f, outside);
    layer->weight = weight;
    if (frame.overlay == nullptr) return;
    // The fill: the mean of the unmasked pixels around, over a window a little wider than a
    // text line (normalised box filter), repeated where the window held none.
    const int channels = layer->picture.channels();
    cv::Mat valid, sum, count, filled;
    cv::bitwise_not(excluded, valid);
    valid.convertTo(valid, CV_32F, 1.0 / 255);
    layer->picture.convertTo(filled, CV_32F);
    for (int pass = 0, k = 31; pass < 4; ++pass, k *= 2) {
      cv::boxFilter(filled.mul(Replicate(valid, channels)), sum, CV_32F, cv::Size(k, k),
                    cv::Point(-1, -1), false);
      cv::boxFilter(valid, count, CV_32F, cv::Size(k, k), cv::Point(-1, -1), false);
      cv::Mat mean;
      cv::divide(sum, Replicate(cv::max(count, 1e-6), channels), mean);
      const cv::Mat reached = (count > 0.5) & (valid < 0.5);
      mean.copyTo(filled, reached);
      valid.setTo(1.0f, reached);
      if (cv::countNonZero(valid < 0.5) == 0) break;
    }
    cv::Mat picture;  // a buffer of its own: never written into the key frame's picture
    filled.convertTo(picture, CV_8U);
    layer->picture = picture;
  }

  // A single-channel matrix as `channels` identical channels (itself for one).
  static cv::Mat Replicate(const cv::Mat& m, int channels) {
    if (channels == 1) return m;
    cv::Mat out;
    cv::merge(std::vector<cv::Mat>(static_cast<size_t>(channels), m), out);
    return out;
  }

  cv::Mat RenderLevel0(int x, int y, const std::vector<size_t>& covering) {
    const int t = info_.tile_size;
    // Tile pixel from map: inverse of map = origin + ((x t + i) sx, (y t + j) sy).
    Eigen::Matrix3d tile_from_map;
    tile_from_map << 1 / info_.step_x, 0, -info_.map_origin.x() / info_.step_x - x * t,  //
        0, 1 / info_.step_y, -info_.map_origin.y() / info_.step_y - y * t,               //
        0, 0, 1;
    const int channels = colour_ ? 3 : 1;
    cv::Mat sum(t, t, CV_32FC(channels), cv::Scalar::all(0));
    cv::Mat weight(t, t, CV_32F, cv::Scalar(0));
    cv::Mat warped, warped_weight, product;
    for (const size_t i : covering) {
      const KeyFrameView& frame = frames_[i];
      // Grey pixel (u, v) is full-resolution ((u + 0.5) s - 0.5, (v + 0.5) s - 0.5).
      Eigen::Matrix3d full_from_grey;
      full_from_grey << frame.scale, 0, 0.5 * frame.scale - 0.5, 0, frame.scale,
          0.5 * frame.scale - 0.5, 0, 0, 1;
      cv::Mat h;
      cv::eigen2cv(Eigen::Matrix3d(tile_from_map * frame.map_from_frame * full_from_grey), h);
      const Layer layer = LayerOf(i);
      cv::warpPerspective(*layer.picture, warped, h, sum.size(), cv::INTER_LINEAR,
                          cv::BORDER_CONSTANT, cv::Scalar(0));
      cv::warpPerspective(*layer.weight, warped_weight, h, sum.size(), cv::INTER_LINEAR,
                          cv::BORDER_CONSTANT, cv::Scalar(0));
      warped.convertTo(product, CV_32F);
      product = product.mul(Replicate(warped_weight, channels));
      sum += product;
      weight += warped_weight;
    }
    cv::Mat picture;
    cv::divide(sum, Replicate(weight, channels), picture);
    const cv::Mat alpha = weight > 0;  // 255 where covered
    picture.setTo(cv::Scalar::all(0), ~alpha);
    picture.convertTo(picture, CV_8U);
    std::vector<cv::Mat> planes;
    cv::split(picture, planes);
    if (channels == 1) planes.assign(3, planes[0]);
    planes.push_back(alpha);
    cv::Mat bgra;
    cv::merge(planes, bgra);
    return bgra;
  }

  // 2t x 2t BGRA to t x t, colours averaged over covered pixels only (alpha-weighted).
  cv::Mat Downsample(const cv::Mat& quad) const {
    cv::Mat f;
    quad.convertTo(f, CV_32F, 1.0 / 255);
    std::vector<cv::Mat> channels;
    cv::split(f, channels);
    for (int c = 0; c < 3; ++c)
      channels[static_cast<size_t>(c)] = channels[static_cast<size_t>(c)].mul(channels[3]);
    cv::Mat premultiplied, small;
    cv::merge(channels, premultiplied);
    cv::resize(premultiplied, small, cv::Size(info_.tile_size, info_.tile_size), 0, 0,
               cv::INTER_AREA);
    cv::split(small, channels);
    for (int c = 0; c < 3; ++c) {
      cv::divide(channels[static_cast<size_t>(c)], channels[3], channels[static_cast<size_t>(c)]);
      channels[static_cast<size_t>(c)].setTo(0, channels[3] <= 0);
    }
    cv::merge(channels, small);
    cv::Mat out;
    small.convertTo(out, CV_8U, 255);
    return out;
  }

  void ReportProgress() {
    ++level0_done_;
    if (job_) {
      const int64_t columns = (info_.width + info_.tile_size - 1) / info_.tile_size;
      const int64_t rows = (info_.height + info_.tile_size - 1) / info_.tile_size;
      job_->ReportProgress(
          "Mosaic tiles",
          std::min(1.0, static_cast<double>(level0_done_) /
                            static_cast<double>(std::max<int64_t>(1, columns * rows))));
    }
  }

  const std::vector<KeyFrameView>& frames_;
  const mission::PyramidInfo& info_;
  const PyramidOptions& options_;
  const TileSink& write_;
  JobContext* job_;
  std::vector<Box> boxes_;
  std::vector<std::vector<Eigen::Vector2d>> parts_;  // DrawnPart of each frame
  std::vector<bool> cut_;                            // ... when it is not the whole frame
  bool colour_ = false;                              // any frame has chroma
  std::map<std::pair<int, int>, cv::Mat> feathers_;
  std::vector<OwnLayer> layers_;
  std::vector<mission::EncodedTile> batch_;
  RenderSummary summary_;
  int64_t level0_done_ = 0;
};

}  // namespace

std::vector<Eigen::Vector2d> DrawnPart(const KeyFrameView& frame, int width, int height) {
  std::vector<Eigen::Vector2d> part = mission::BelowSkyLine(frame.sky_line, width, height);
  // A part that reaches behind the map's plane is not drawn at all: its homography contradicts
  // the horizon the frame shows (or, without a sky line, the frame sees beyond the map's horizon,
  // and the place where its ground would end is unknown).
  const Eigen::Vector3d row = frame.map_from_frame.row(2).transpose();
  for (const Eigen::Vector2d& p : part) {
    if (!(row.dot(p.homogeneous()) > 0)) return {};
  }
  const std::optional<double> farthest = mission::FarthestMappedW(frame.map_from_frame, part);
  if (!farthest) return {};
  part = mission::ClipToHalfPlane(part, row.head<2>(), row.z() - *farthest);
  return part.size() >= 3 ? part : std::vector<Eigen::Vector2d>{};
}

Status PyramidOptions::Validate() const {
  if (tile_size < 16 || tile_size > kMaxTileSize) {
    return InvalidArgumentError("mosaic tiles: tile_size must be 16.." +
                                std::to_string(kMaxTileSize) + " pixels");
  }
  if (!(map_units_per_px >= 0) || !std::isfinite(map_units_per_px)) {
    return InvalidArgumentError("mosaic tiles: map_units_per_px must be >= 0");
  }
  if (max_side_px < tile_size || max_side_px > (1 << 22)) {
    return InvalidArgumentError("mosaic tiles: max_side_px must be tile_size..4194304");
  }
  if (png_compression < 0 || png_compression > 9) {
    return InvalidArgumentError("mosaic tiles: png_compression must be 0..9");
  }
  if (jpeg_quality < 0 || jpeg_quality > 100) {
    return InvalidArgumentError("mosaic tiles: jpeg_quality must be 0..100 (0: PNG always)");
  }
  return {};
}

StatusOr<mission::PyramidInfo> PlanPyramid(const std::vector<KeyFrameView>& frames, int width,
                                           int height, bool geo_referenced,
                                           const PyramidOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  if (width < 2 || height < 2) return InvalidArgumentError("mosaic tiles: no frame size");
  Box extent;
  std::vector<double> resolutions;
  for (const KeyFrameView& frame : frames) {
    const std::vector<Eigen::Vector2d> part = DrawnPart(frame, width, height);
    const Box box = Footprint(part, frame.map_from_frame);
    if (!box.Valid() || !frame.grey || frame.grey->empty()) continue;
    extent.lo = extent.lo.cwiseMin(box.lo);
    extent.hi = extent.hi.cwiseMax(box.hi);
    // Map units per full-resolution pixel at the centre of the drawn part (the image centre
    // when the whole frame is drawn).
    Eigen::Vector2d centre(0, 0);
    for (const Eigen::Vector2d& p : part) centre += p;
    centre /= static_cast<double>(part.size());
    const Eigen::Vector3d q = frame.map_from_frame * centre.homogeneous();
    const Eigen::Matrix<double, 2, 3> d =
        (Eigen::Matrix<double, 2, 3>() << 1 / q.z(), 0, -q.x() / (q.z() * q.z()), 0, 1 / q.z(),
         -q.y() / (q.z() * q.z()))
            .finished();
    const Eigen::Matrix2d jacobian = d * frame.map_from_frame.leftCols<2>();
    resolutions.push_back(std::sqrt(std::abs(jacobian.determinant())));
  }
  if (!extent.Valid() || resolutions.empty()) {
    return InvalidDataError("mosaic tiles: no key frame has a finite footprint on the map");
  }
  double units =
      options.map_units_per_px > 0 ? options.map_units_per_px : Median(std::move(resolutions));
  if (!(units > 0) || !std::isfinite(units)) {
    return InvalidDataError("mosaic tiles: degenerate key frame homographies");
  }
  const Eigen::Vector2d size = extent.hi - extent.lo;
  units = std::max(units, size.maxCoeff() / (options.max_side_px - 1));
  mission::PyramidInfo info;
  info.tile_size = options.tile_size;
  info.width = static_cast<int>(std::ceil(size.x() / units)) + 1;
  info.height = static_cast<int>(std::ceil(size.y() / units)) + 1;
  info.step_x = units;
  if (geo_referenced) {  // north up: rows go south
    info.map_origin = {extent.lo.x(), extent.hi.y()};
    info.step_y = -units;
  } else {
    info.map_origin = extent.lo;
    info.step_y = units;
  }
  info.levels = 1;
  while ((static_cast<int64_t>(options.tile_size) << (info.levels - 1)) <
         std::max(info.width, info.height)) {
    ++info.levels;
  }
  return info;
}

StatusOr<RenderSummary> RenderPyramid(const std::vector<KeyFrameView>& frames, int width,
                                      int height, const mission::PyramidInfo& info,
                                      const PyramidOptions& options, const TileSink& write,
                                      JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  if (info.levels < 1 || info.levels > 24 || info.tile_size != options.tile_size ||
      !(std::abs(info.step_x) > 0) || !(std::abs(info.step_y) > 0)) {
    return InvalidArgumentError("mosaic tiles: the pyramid does not match the options");
  }
  const Stopwatch begin;
  Renderer renderer(frames, width, height, info, options, write, job);
  SAKER_RETURN_IF_ERROR(renderer.Tile(info.levels - 1, 0, 0).status());
  SAKER_RETURN_IF_ERROR(renderer.Flush());
  if (job) job->ReportProgress("Mosaic tiles", 1.0);
  RenderSummary summary = renderer.summary();
  summary.time_s = begin.ElapsedSeconds();
  return summary;
}

StatusOr<cv::Mat> DecodeTile(const std::vector<uint8_t>& bytes, int tile_size) {
  if (bytes.empty()) return InvalidDataError("mosaic tile: no bytes");
  if (tile_size < 1 || tile_size > kMaxTileSize) {
    return InvalidDataError("mosaic tile: the pyramid's tile size " + std::to_string(tile_size) +
                            " is outside 1.." + std::to_string(kMaxTileSize));
  }
  const ImageLimits limits{tile_size, tile_size, static_cast<int64_t>(tile_size) * tile_size};
  const bool jpeg = IsJpeg(bytes);
  StatusOr<cv::Mat> tile = jpeg ? DecodeJpeg(bytes, cv::IMREAD_COLOR, limits)
                                : DecodePng(bytes, cv::IMREAD_UNCHANGED, limits);
  if (!tile.ok()) return Status(tile.status().code(), "mosaic tile: " + tile.status().message());
  if (jpeg && tile->type() == CV_8UC3) cv::cvtColor(*tile, *tile, cv::COLOR_BGR2BGRA);
  if (tile->type() != CV_8UC4 || tile->cols != tile_size || tile->rows != tile_size) {
    return InvalidDataError("mosaic tile: not a " + std::to_string(tile_size) + "x" +
                            std::to_string(tile_size) +
                            (jpeg ? " colour JPEG image" : " BGRA PNG image"));
  }
  return tile;
}

}  // namespace saker::tiles
