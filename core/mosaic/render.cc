#include "core/mosaic/render.h"

#include "core/mosaic/adjustment.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/track/picture.h"
#include "core/util/statistics.h"

#include <Eigen/Geometry>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace saker::mosaic {
namespace {

cv::Point ToPoint(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector2d q = (h * p.homogeneous()).hnormalized();
  return {static_cast<int>(std::lround(q.x())), static_cast<int>(std::lround(q.y()))};
}

cv::Scalar SegmentColour(int segment) {
  static const cv::Scalar kColours[] = {{0, 200, 255}, {255, 160, 0}, {0, 220, 0},
                                        {255, 0, 200}, {0, 120, 255}, {200, 200, 0}};
  return kColours[static_cast<size_t>(segment) % 6];
}

}  // namespace

Status RenderOptions::Validate() const {
  if (max_side_px < 16 || max_side_px > 30000) {
    return InvalidArgumentError("mosaic picture: the longer side must be 16..30000 pixels");
  }
  if (!(map_units_per_px >= 0) || !std::isfinite(map_units_per_px)) {
    return InvalidArgumentError("mosaic picture: the resolution must be >= 0 map units per pixel");
  }
  if (!(ellipse_confidence >= 0 && ellipse_confidence < 1)) {
    return InvalidArgumentError("mosaic picture: the ellipse confidence must be in [0, 1)");
  }
  return Status::Ok();
}

namespace {

// The picture's frame: its map units per pixel and image_from_map, chosen from the key frames'
// footprints; `size` is the picture's size in pixels.
StatusOr<MosaicImage> PictureFrame(const LinkGraph& graph, const RenderOptions& options,
                                   cv::Size* size) {
  const auto corners = track::ImageCorners(graph.image_width, graph.image_height);
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  std::vector<double> resolutions;
  for (const Node& node : graph.nodes) {
    for (const Eigen::Vector2d& c : corners) {
      const Eigen::Vector3d q = node.map_from_frame * c.homogeneous();
      if (!(q.z() > 1e-12)) continue;  // a corner beyond the horizon: not drawable
      x0 = std::min(x0, q.x() / q.z()), x1 = std::max(x1, q.x() / q.z());
      y0 = std::min(y0, q.y() / q.z()), y1 = std::max(y1, q.y() / q.z());
    }
    const Eigen::Matrix2d a = track::TransferPointJacobian(
        node.map_from_frame, {graph.image_width / 2.0, graph.image_height / 2.0});
    resolutions.push_back(std::sqrt(std::abs(a.determinant())));
  }
  if (!(std::isfinite(x0) && std::isfinite(x1) && std::isfinite(y0) && std::isfinite(y1)) ||
      resolutions.empty()) {
    return InvalidDataError("mosaic picture: the key frames' extent is not finite");
  }
  double units =
      options.map_units_per_px > 0 ? options.map_units_per_px : Median(std::move(resolutions));
  if (!(units > 0)) return InvalidDataError("mosaic picture: degenerate key frame homographies");
  units = std::max(units, std::max(x1 - x0, y1 - y0) / options.max_side_px);
  size->width = std::max(1, static_cast<int>(std::ceil((x1 - x0) / units)) + 1);
  size->height = std::max(1, static_cast<int>(std::ceil((y1 - y0) / units)) + 1);

  MosaicImage out;
  out.map_units_per_px = units;
  // Map -> picture: scale, and for a geo-referenced map flip north up.
  if (graph.geo_referenced) {
    out.image_from_map << 1 / units, 0, -x0 / units, 0, -1 / units, y1 / units, 0, 0, 1;
  } else {
    out.image_from_map << 1 / units, 0, -x0 / units, 0, 1 / units, -y0 / units, 0, 0, 1;
  }
  return out;
}

// Blends the key frames that have an image into out->bgr (of `size`), each weighted by its
// distance to the image border so that overlapping frames fade into each other.
Status BlendKeyFrames(const LinkGraph& graph, const std::vector<track::KeyFrameImage>& images,
                      cv::Size size, MosaicImage* out) {
  std::map<int, const track::KeyFrameImage*> by_id;
  bool colour = false;  // any key frame in colour: all drawn in colour, grey ones as grey
  for (const track::KeyFrameImage& image : images) {
    if (image.grey.empty()) continue;
    by_id[static_cast<int>(image.id)] = &image;
    colour = colour || track::IsColour(image);
  }
  const int channels = colour ? 3 : 1;
  const auto replicate = [channels](const cv::Mat& m) {
    if (channels == 1) return m;
    cv::Mat copies;
    cv::merge(std::vector<cv::Mat>(static_cast<size_t>(channels), m), copies);
    return copies;
  };
  cv::Mat sum(size, CV_32FC(channels), cv::Scalar::all(0));
  cv::Mat weight(size, CV_32F, cv::Scalar(0));
  cv::Mat warped, warped_weight, feather;
  cv::Size feather_size;
  int drawn = 0;
  for (const Node& node : graph.nodes) {
    const auto it = by_id.find(static_cast<int>(node.id));
    if (it == by_id.end()) continue;
    const track::KeyFrameImage& image = *it->second;
    if (image.grey.size() != feather_size) {
      cv::Mat inside(image.grey.size(), CV_8U, cv::Scalar(255));
      cv::rectangle(inside, cv::Rect(0, 0, inside.cols, inside.rows), cv::Scalar(0), 1);
      cv::distanceTransform(inside, feather, cv::DIST_L2, 3, CV_32F);
      feather += 1.0f;
      feather_size = image.grey.size();
    }
    // Grey pixel (u, v) is full-resolution ((u + 0.5) s - 0.5, (v + 0.5) s - 0.5).
    Eigen::Matrix3d full_from_grey;
    full_from_grey << image.scale, 0, 0.5 * image.scale - 0.5, 0, image.scale,
        0.5 * image.scale - 0.5, 0, 0, 1;
    const Eigen::Matrix3d picture_from_grey =
        out->image_from_map * node.map_from_frame * full_from_grey;
    cv::Mat h;
    cv::eigen2cv(picture_from_grey, h);
    cv::Mat picture;
    (colour ? track::KeyFrameBgr(image) : image.grey).convertTo(picture, CV_32F);
    cv::warpPerspective(picture.mul(replicate(feather)), warped, h, sum.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar::all(0));
    cv::warpPerspective(feather, warped_weight, h, sum.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar(0));
    sum += warped;
    weight += warped_weight;
    ++drawn;
  }
  if (drawn == 0) return InvalidDataError("mosaic picture: no key frame has an image to draw");
  cv::Mat picture;
  cv::divide(sum, replicate(weight), picture);
  picture.convertTo(picture, CV_8U);
  if (colour) {
    out->bgr = picture;
  } else {
    cv::cvtColor(picture, out->bgr, cv::COLOR_GRAY2BGR);
  }
  // No-data stays a neutral dark blue-grey, not black, so the footprint reads as such.
  out->bgr.setTo(cv::Scalar(48, 40, 36), weight <= 0);
  return Status::Ok();
}

// Draws what `options` asks for over the picture: links, key frame outlines, and the uncertainty
// ellipses of the key frames' corners (in map units, through the picture's similarity).
void DrawGraph(const LinkGraph& graph, const std::vector<track::HomographyCovariance>& covariances,
               const RenderOptions& options, MosaicImage* out) {
  const auto corners = track::ImageCorners(graph.image_width, graph.image_height);
  const Eigen::Vector2d centre((graph.image_width - 1) / 2.0, (graph.image_height - 1) / 2.0);
  if (options.links) {
    for (const Link& link : graph.links) {
      const Node& a = graph.nodes[static_cast<size_t>(link.from)];
      const Node& b = graph.nodes[static_cast<size_t>(link.to)];
      const cv::Scalar colour =
          link.kind == LinkKind::kSequential ? cv::Scalar(255, 255, 255) : cv::Scalar(0, 0, 255);
      cv::line(out->bgr, ToPoint(out->image_from_map * a.map_from_frame, centre),
               ToPoint(out->image_from_map * b.map_from_frame, centre), colour,
               link.kind == LinkKind::kSequential ? 1 : 2, cv::LINE_AA);
    }
  }
  if (options.outlines) {
    for (const Node& node : graph.nodes) {
      std::vector<cv::Point> outline;
      for (const Eigen::Vector2d& c : corners) {
        outline.push_back(ToPoint(out->image_from_map * node.map_from_frame, c));
      }
      cv::polylines(out->bgr, outline, true, SegmentColour(node.segment), 1, cv::LINE_AA);
    }
  }
  if (options.ellipse_confidence > 0 && covariances.size() == graph.nodes.size()) {
    for (size_t i = 0; i < graph.nodes.size(); ++i) {
      const Node& node = graph.nodes[i];
      for (const Eigen::Vector2d& c : corners) {
        const Eigen::Matrix2d cov =
            track::TransferCovariance(node.map_from_frame, covariances[i], c);
        const track::Ellipse e = track::ConfidenceEllipse(track::Transfer(node.map_from_frame, c),
                                                          cov, options.ellipse_confidence);
        std::vector<cv::Point> polygon;
        for (const Eigen::Vector2d& p : track::EllipsePolygon(e, 48)) {
          polygon.push_back(ToPoint(out->image_from_map, p));
        }
        cv::polylines(out->bgr, polygon, true, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
      }
    }
  }
}

}  // namespace

StatusOr<MosaicImage> RenderMosaic(const LinkGraph& graph,
                                   const std::vector<track::KeyFrameImage>& images,
                                   const RenderOptions& options,
                                   const std::vector<track::HomographyCovariance>& covariances) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  SAKER_RETURN_IF_ERROR(graph.Validate());
  cv::Size size;
  SAKER_ASSIGN_OR_RETURN(MosaicImage out, PictureFrame(graph, options, &size));
  SAKER_RETURN_IF_ERROR(BlendKeyFrames(graph, images, size, &out));
  DrawGraph(graph, covariances, options, &out);
  return out;
}

}  // namespace saker::mosaic
