#include "core/render/activity_map.h"

#include "core/activity/density.h"
#include "core/util/durable_file.h"

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace saker::render {
namespace {

const cv::Scalar kBackground(48, 40, 36);  // no-data: dark blue-grey, not black
constexpr int kShift = 4;                  // sub-pixel bits for drawing
constexpr double kOne = 1 << kShift;

cv::Scalar Bgr(const activity::Rgb& c) {
  return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)};
}

cv::Point Fixed(const Eigen::Vector2d& p) {
  return {static_cast<int>(std::lround(p.x() * kOne)), static_cast<int>(std::lround(p.y() * kOne))};
}

// Alpha-blends a BGRA tile onto the canvas at (x, y), clipped.
void Blend(const cv::Mat& tile, cv::Mat* canvas, int x, int y) {
  const cv::Rect target =
      cv::Rect(x, y, tile.cols, tile.rows) & cv::Rect(0, 0, canvas->cols, canvas->rows);
  for (int r = target.y; r < target.y + target.height; ++r) {
    const cv::Vec4b* source = tile.ptr<cv::Vec4b>(r - y);
    cv::Vec3b* out = canvas->ptr<cv::Vec3b>(r);
    for (int c = target.x; c < target.x + target.width; ++c) {
      const cv::Vec4b& s = source[c - x];
      const int a = s[3];
      for (int k = 0; k < 3; ++k)
        out[c][k] = static_cast<uint8_t>((s[k] * a + out[c][k] * (255 - a)) / 255);
    }
  }
}

// A "nice" length (1, 2 or 5 times a power of ten) at most `at_most`.
double NiceLength(double at_most) {
  const double power = std::pow(10.0, std::floor(std::log10(at_most)));
  for (const double m : {5.0, 2.0, 1.0}) {
    if (m * power <= at_most) return m * power;
  }
  return power;
}

void Text(cv::Mat* image, const std::string& text, cv::Point at, double scale,
          const cv::Scalar& colour, int thickness = 1) {
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

cv::Size TextSize(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline);
}

// A translucent white panel behind overlays, so they read on any mosaic.
void Panel(cv::Mat* image, cv::Rect box) {
  box &= cv::Rect(0, 0, image->cols, image->rows);
  if (box.empty()) return;
  cv::Mat region = (*image)(box);
  cv::Mat white(region.size(), region.type(), cv::Scalar(255, 255, 255));
  cv::addWeighted(region, 0.2, white, 0.8, 0, region);
  cv::rectangle(*image, box, cv::Scalar(90, 90, 90), 1);
}

void DrawLegend(const activity::Legend& legend, double ui, cv::Mat* image) {
  const double text_scale = 0.5 * ui;
  const int pad = static_cast<int>(10 * ui), line = static_cast<int>(22 * ui);
  const int width =
      std::max(static_cast<int>(190 * ui), TextSize(legend.title, text_scale).width + 2 * pad);
  const int rows = legend.continuous ? 3 : static_cast<int>(legend.entries.size()) + 1;
  const cv::Rect box(image->cols - width - pad, pad, width, rows * line + 2 * pad);
  Panel(image, box);
  const cv::Scalar ink(30, 30, 30);
  Text(image, legend.title, {box.x + pad, box.y + pad + static_cast<int>(14 * ui)}, text_scale,
       ink);
  if (legend.continuous) {
    // A ramp through the entries' colours, labels under their positions.
    const int x0 = box.x + pad, x1 = box.x + width - pad;
    const int y0 = box.y + pad + line, y1 = y0 + static_cast<int>(14 * ui);
    for (int x = x0; x <= x1; ++x) {
      const double p = static_cast<double>(x - x0) / std::max(1, x1 - x0);
      size_t i = 0;
      while (i + 2 < legend.entries.size() && legend.entries[i + 1].position < p) ++i;
      const auto& a = legend.entries[i];
      const auto& b = legend.entries[std::min(i + 1, legend.entries.size() - 1)];
      const double f = b.position > a.position
                           ? std::clamp((p - a.position) / (b.position - a.position), 0.0, 1.0)
                           : 0;
      const cv::Scalar colour = Bgr(a.colour) * (1 - f) + Bgr(b.colour) * f;
      cv::line(*image, {x, y0}, {x, y1}, colour, 1);
    }
    cv::rectangle(*image, {x0, y0}, {x1, y1}, cv::Scalar(90, 90, 90), 1);
    for (const auto& entry : legend.entries) {
      const int x = x0 + static_cast<int>(entry.position * (x1 - x0));
      const cv::Size size = TextSize(entry.label, 0.42 * ui);
      const int left = std::clamp(x - size.width / 2, box.x + 2, box.x + width - size.width - 2);
      cv::line(*image, {x, y1}, {x, y1 + static_cast<int>(4 * ui)}, ink, 1);
      Text(image, entry.label, {left, y1 + static_cast<int>(18 * ui)}, 0.42 * ui, ink);
    }
  } else {
    for (size_t i = 0; i < legend.entries.size(); ++i) {
      const int y = box.y + pad + line * static_cast<int>(i + 1);
      cv::line(*image, {box.x + pad, y + static_cast<int>(8 * ui)},
               {box.x + pad + static_cast<int>(28 * ui), y + static_cast<int>(8 * ui)},
               Bgr(legend.entries[i].colour), std::max(2, static_cast<int>(4 * ui)), cv::LINE_AA);
      Text(image, legend.entries[i].label,
           {box.x + pad + static_cast<int>(38 * ui), y + static_cast<int>(13 * ui)}, 0.45 * ui,
           ink);
    }
  }
}

// The density of the tracks' observations (the heat map) blended over the picture: each cell's
// colour, bilinearly interpolated from the cell centres, with its opacity.
void DrawDensity(const std::vector<mission::ActivityTrack>& tracks, bool geo_referenced,
                 const Eigen::Matrix3d& image_from_map, cv::Mat* image) {
  std::vector<const mission::ActivityTrack*> all;
  for (const mission::ActivityTrack& t : tracks) all.push_back(&t);
  const activity::DensityGrid grid = activity::CountObservations(all, geo_referenced);
  if (grid.cols == 0) return;
  // Premultiplied BGRA of the cells, so that interpolation does not darken the edges.
  cv::Mat cells(grid.rows, grid.cols, CV_32FC4, cv::Scalar::all(0));
  for (int r = 0; r < grid.rows; ++r) {
    for (int c = 0; c < grid.cols; ++c) {
      const double p = activity::DensityPosition(grid.At(c, r), grid.max);
      const float a = activity::DensityAlpha(p) / 255.0f;
      const activity::Rgb rgb = activity::DensityRamp(p);
      cells.at<cv::Vec4f>(r, c) = cv::Vec4f(rgb.b * a, rgb.g * a, rgb.r * a, a);
    }
  }
  // Picture from cell (centres at integers): map = origin + (cell index + 0.5) * cell.
  Eigen::Matrix3d map_from_cell;
  map_from_cell << grid.cell, 0, grid.origin.x() + 0.5 * grid.cell, 0, grid.cell,
      grid.origin.y() + 0.5 * grid.cell, 0, 0, 1;
  const Eigen::Matrix3d image_from_cell = image_from_map * map_from_cell;
  cv::Mat affine(2, 3, CV_64F);
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 3; ++j) affine.at<double>(i, j) = image_from_cell(i, j);
  }
  cv::Mat warped;
  cv::warpAffine(cells, warped, affine, image->size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                 cv::Scalar::all(0));
  for (int v = 0; v < image->rows; ++v) {
    cv::Vec3b* row = image->ptr<cv::Vec3b>(v);
    const cv::Vec4f* heat = warped.ptr<cv::Vec4f>(v);
    for (int u = 0; u < image->cols; ++u) {
      const float a = heat[u][3];
      if (a <= 0) continue;
      for (int k = 0; k < 3; ++k) {
        row[u][k] = cv::saturate_cast<uint8_t>(heat[u][k] + (1 - a) * row[u][k]);
      }
    }
  }
}

void DrawScaleBar(double metres_per_px, double ui, cv::Mat* image) {
  const double metres = NiceLength(0.2 * image->cols * metres_per_px);
  const int length = static_cast<int>(std::lround(metres / metres_per_px));
  const std::string label = metres >= 1000 ? std::to_string(static_cast<int>(metres / 1000)) + " km"
                                           : std::to_string(static_cast<int>(metres)) + " m";
  const int pad = static_cast<int>(10 * ui);
  const cv::Rect box(pad, image->rows - static_cast<int>(46 * ui) - pad, length + 2 * pad,
                     static_cast<int>(46 * ui));
  Panel(image, box);
  const int y = box.y + static_cast<int>(32 * ui), x0 = box.x + pad;
  const cv::Scalar ink(30, 30, 30);
  cv::rectangle(*image, {x0, y}, {x0 + length / 2, y + static_cast<int>(6 * ui)}, ink, cv::FILLED);
  cv::rectangle(*image, {x0, y}, {x0 + length, y + static_cast<int>(6 * ui)}, ink, 1);
  Text(image, label, {x0, y - static_cast<int>(8 * ui)}, 0.5 * ui, ink);
}

void DrawNorthArrow(double ui, cv::Mat* image) {
  const int pad = static_cast<int>(10 * ui), size = static_cast<int>(52 * ui);
  const cv::Rect box(pad, pad, static_cast<int>(40 * ui), size + static_cast<int>(20 * ui));
  Panel(image, box);
  const int cx = box.x + box.width / 2, top = box.y + static_cast<int>(24 * ui),
            bottom = box.y + box.height - static_cast<int>(6 * ui);
  const std::vector<cv::Point> left = {
      {cx, top}, {cx - static_cast<int>(9 * ui), bottom}, {cx, bottom - static_cast<int>(10 * ui)}};
  const std::vector<cv::Point> right = {
      {cx, top}, {cx + static_cast<int>(9 * ui), bottom}, {cx, bottom - static_cast<int>(10 * ui)}};
  cv::fillConvexPoly(*image, left, cv::Scalar(30, 30, 30), cv::LINE_AA);
  cv::polylines(*image, right, true, cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  const cv::Size n = TextSize("N", 0.55 * ui, 2);
  Text(image, "N", {cx - n.width / 2, box.y + static_cast<int>(19 * ui)}, 0.55 * ui,
       cv::Scalar(30, 30, 30), 2);
}

}  // namespace

Status ActivityMapOptions::Validate() const {
  if (max_side_px < 64 || max_side_px > 30000) {
    return InvalidArgumentError("activity map: the longer side must be 64..30000 pixels");
  }
  if (!(line_width > 0 && line_width <= 50)) {
    return InvalidArgumentError("activity map: the line width must be in (0, 50] pixels");
  }
  if (start_s && end_s && *end_s < *start_s) {
    return InvalidArgumentError("activity map: the time window ends before it starts");
  }
  return {};
}

StatusOr<ActivityMap> RenderActivityMap(const mission::Mission& mission, const TileReader& tiles,
                                        const ActivityMapOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  std::vector<mission::ActivityTrack> shown_copy;
  for (const mission::ActivityTrack& track : mission.tracks) {
    if (options.start_s && track.end_s < *options.start_s) continue;
    if (options.end_s && track.start_s > *options.end_s) continue;
    shown_copy.push_back(track);
  }
  ActivityMap out;
  double metres_per_px = 0;
  if (mission.pyramid) {
    const mission::PyramidInfo& info = *mission.pyramid;
    int level = 0;
    while (level + 1 < info.levels &&
           (std::max(info.width, info.height) >> level) > options.max_side_px) {
      ++level;
    }
    const double f = static_cast<double>(static_cast<int64_t>(1) << level);
    const int width = static_cast<int>(std::ceil(info.width / f)),
              height = static_cast<int>(std::ceil(info.height / f));
    out.bgr = cv::Mat(height, width, CV_8UC3, kBackground);
    const int t = info.tile_size;
    for (int ty = 0; ty * t < height; ++ty) {
      for (int tx = 0; tx * t < width; ++tx) {
        SAKER_ASSIGN_OR_RETURN(const cv::Mat tile, tiles(level, tx, ty));
        if (tile.empty()) continue;
        if (tile.type() != CV_8UC4) return InvalidDataError("activity map: a tile is not BGRA");
        Blend(tile, &out.bgr, tx * t, ty * t);
      }
    }
    out.level = level;
    // Level-l pixel (centre) from level-0 pixel u0: (u0 - (f - 1) / 2) / f.
    Eigen::Matrix3d level_from_level0;
    level_from_level0 << 1 / f, 0, -(f - 1) / (2 * f), 0, 1 / f, -(f - 1) / (2 * f), 0, 0, 1;
    Eigen::Matrix3d level0_from_map;
    level0_from_map << 1 / info.step_x, 0, -info.map_origin.x() / info.step_x, 0, 1 / info.step_y,
        -info.map_origin.y() / info.step_y, 0, 0, 1;
    out.image_from_map = level_from_level0 * level0_from_map;
    metres_per_px = std::abs(info.step_x) * f;
  } else {
    if (shown_copy.empty()) {
      return InvalidDataError("activity map: the mission has neither a mosaic nor tracks to draw");
    }
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d hi = -lo;
    for (const auto& track : shown_copy) {
      for (const auto& p : track.points) lo = lo.cwiseMin(p.map), hi = hi.cwiseMax(p.map);
    }
    const double extent = std::max((hi - lo).maxCoeff(), 1.0);
    const double side = std::min(options.max_side_px, 2048);
    const double scale = 0.9 * side / extent;
    const int width = static_cast<int>(std::ceil((hi.x() - lo.x()) * scale + 0.1 * side));
    const int height = static_cast<int>(std::ceil((hi.y() - lo.y()) * scale + 0.1 * side));
    out.bgr = cv::Mat(std::max(height, 64), std::max(width, 64), CV_8UC3, kBackground);
    const double flip = mission.map.geo_referenced ? -1 : 1;
    out.image_from_map << scale, 0, 0.05 * side - lo.x() * scale,  //
        0, flip * scale, flip > 0 ? 0.05 * side - lo.y() * scale : 0.05 * side + hi.y() * scale, 0,
        0, 1;
    metres_per_px = 1 / scale;
  }
  // Overlays scale with the picture, so they stay readable on large exports.
  const double ui = std::clamp(std::min(out.bgr.cols, out.bgr.rows) / 700.0, 0.8, 3.0);

  const activity::TrackColouring colouring(options.colour_by, shown_copy,
                                           mission.map.geo_referenced);
  const bool density = options.colour_by == activity::ColourMode::kDensity;
  if (density) DrawDensity(shown_copy, mission.map.geo_referenced, out.image_from_map, &out.bgr);
  const int width_px = std::max(1, static_cast<int>(std::lround(options.line_width * ui)));
  for (const mission::ActivityTrack& track : shown_copy) {
    if (track.points.empty()) continue;  // a mission may hold a track without points: no line
    if (density) {  // the heat map is the picture; the tracks are counted, not drawn
      ++out.tracks;
      continue;
    }
    std::vector<cv::Point> line;
    for (const mission::TrackPoint& p : track.points) {
      line.push_back(Fixed((out.image_from_map * p.map.homogeneous()).hnormalized()));
    }
    const cv::Scalar colour = Bgr(colouring.ColourOf(track));
    // A dark casing under the colour keeps thin lines visible on bright ground.
    cv::polylines(out.bgr, line, false, cv::Scalar(20, 20, 20), width_px + 2, cv::LINE_AA, kShift);
    cv::polylines(out.bgr, line, false, colour, width_px, cv::LINE_AA, kShift);
    // The direction of travel: an arrow head at the end, along the last ~12 pixels of the path.
    const Eigen::Vector2d end(line.back().x / kOne, line.back().y / kOne);
    for (size_t i = line.size(); i-- > 0;) {
      const Eigen::Vector2d p(line[i].x / kOne, line[i].y / kOne);
      if ((end - p).norm() >= 12 * ui) {
        const Eigen::Vector2d d = (end - p).normalized();
        const Eigen::Vector2d n(-d.y(), d.x());
        const double s = 5 * ui + width_px;
        const std::vector<cv::Point> head = {Fixed(end + d * s * 0.6),
                                             Fixed(end - d * s + n * s * 0.6),
                                             Fixed(end - d * s - n * s * 0.6)};
        cv::fillConvexPoly(out.bgr, head, colour, cv::LINE_AA, kShift);
        cv::polylines(out.bgr, head, true, cv::Scalar(20, 20, 20), 1, cv::LINE_AA, kShift);
        break;
      }
    }
    ++out.tracks;
  }
  if (options.legend) DrawLegend(colouring.legend(), ui, &out.bgr);
  if (mission.map.geo_referenced && metres_per_px > 0) {
    DrawScaleBar(metres_per_px, ui, &out.bgr);
    DrawNorthArrow(ui, &out.bgr);
  }
  return out;
}

Status WritePicture(const cv::Mat& bgr, const std::string& path) {
  // The temporary keeps the extension: imwrite picks the format by it.
  return ReplaceFile(path, [&](const std::string& temporary) -> Status {
    bool written = false;
    try {
      written = cv::imwrite(temporary, bgr);
    } catch (const cv::Exception&) {
      written = false;
    }
    if (!written) {
      return IoError(
          "cannot write " + path +
          " (the folder must exist and be writable; the name must end in .png, .jpg or .tif)");
    }
    return Status::Ok();
  });
}

}  // namespace saker::render
