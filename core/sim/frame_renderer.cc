#include "core/sim/frame_renderer.h"

#include "core/sim/random.h"
#include "core/util/check.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace saker::sim {

const char* SensorLookName(SensorLook look) {
  switch (look) {
    case SensorLook::kEo:
      return "eo";
    case SensorLook::kIrWhiteHot:
      return "ir-white-hot";
    case SensorLook::kIrBlackHot:
      return "ir-black-hot";
  }
  return "eo";
}

std::optional<SensorLook> ParseSensorLook(std::string_view name) {
  for (SensorLook look : {SensorLook::kEo, SensorLook::kIrWhiteHot, SensorLook::kIrBlackHot}) {
    if (name == SensorLookName(look)) return look;
  }
  return std::nullopt;
}

bool ImagingOptions::WhiteHotAt(double time_s) const {
  const bool white_hot = look == SensorLook::kIrWhiteHot;
  const bool switched = polarity_switch_s >= 0 && time_s >= polarity_switch_s;
  return white_hot != switched;
}

Status ImagingOptions::Validate() const {
  if (!(haze >= 0 && haze <= 0.8)) return InvalidArgumentError("imaging: haze must be in [0, 0.8]");
  if (!(motion_blur_px >= 0 && motion_blur_px <= 50)) {
    return InvalidArgumentError("imaging: motion blur must be between 0 and 50 pixels");
  }
  if (!(lens_k1 >= -0.3 && lens_k1 <= 0.3)) {
    return InvalidArgumentError("imaging: lens distortion k1 must be in [-0.3, 0.3]");
  }
  if (!std::isfinite(polarity_switch_s)) {
    return InvalidArgumentError("imaging: the polarity switch time must be a number");
  }
  if (polarity_switch_s >= 0 && !infrared()) {
    return InvalidArgumentError("imaging: a polarity switch needs an infrared look");
  }
  if (!(noise_sigma >= 0 && noise_sigma <= 100)) {
    return InvalidArgumentError("imaging: noise must be between 0 and 100 grey levels");
  }
  if (!(blur_sigma_px >= 0 && blur_sigma_px <= 20)) {
    return InvalidArgumentError("imaging: blur must be between 0 and 20 pixels");
  }
  if (!(gain_drift >= 0 && gain_drift < 1)) {
    return InvalidArgumentError("imaging: gain drift must be in [0, 1)");
  }
  if (!(gain_period_s > 0)) return InvalidArgumentError("imaging: gain period must be positive");
  if (!(blank_duration_s >= 0) || !std::isfinite(blank_start_s)) {
    return InvalidArgumentError("imaging: the blank interval needs a start and a length >= 0");
  }
  return Status::Ok();
}

bool ImagingOptions::IsBlank(double time_s) const {
  return blank_start_s >= 0 && time_s >= blank_start_s && time_s < blank_start_s + blank_duration_s;
}

namespace {

// The lens model's units: pixels from the image centre, as fractions of the half diagonal.
struct LensFrame {
  Eigen::Vector2d centre;
  double half_diagonal;
};

LensFrame LensFrameOf(int width, int height) {
  return {Eigen::Vector2d(0.5 * (width - 1), 0.5 * (height - 1)),
          0.5 * std::hypot(static_cast<double>(width), static_cast<double>(height))};
}

}  // namespace

Eigen::Vector2d LensDistort(const Eigen::Vector2d& pixel, int width, int height, double k1) {
  if (k1 == 0) return pixel;
  const LensFrame lens = LensFrameOf(width, height);
  const Eigen::Vector2d u = (pixel - lens.centre) / lens.half_diagonal;
  return lens.centre + u * (1 + k1 * u.squaredNorm()) * lens.half_diagonal;
}

namespace {

constexpr int kSkyCols = 2048;  // azimuth 0..360 degrees
constexpr int kSkyRows = 256;   // elevation 0..kSkyRowsDeg
constexpr double kSkyRowsDeg = 45.0;
const cv::Vec3f kHazeBgr(206, 200, 192);   // the sky at the horizon and the distant ground
const cv::Vec3f kZenithBgr(186, 140, 96);  // the sky high up
const cv::Vec3f kCloudBgr(240, 240, 238);

// Smooth value noise with `cell`-pixel cells, periodic across the panorama's azimuth.
void AddNoiseOctave(int cell, double amplitude, Random* random, cv::Mat* sum) {
  const int grid_cols = kSkyCols / cell;
  const int grid_rows = kSkyRows / cell + 2;
  std::vector<float> grid(static_cast<size_t>(grid_rows * grid_cols));
  for (float& v : grid) v = static_cast<float>(random->Uniform(-1, 1));
  const auto at = [&](int r, int c) {
    return grid[static_cast<size_t>(r * grid_cols + (c % grid_cols))];
  };
  const auto smooth = [](double t) { return t * t * (3 - 2 * t); };
  for (int y = 0; y < kSkyRows; ++y) {
    const double v = static_cast<double>(y) / cell;
    const int r = static_cast<int>(v);
    const double fy = smooth(v - r);
    float* row = sum->ptr<float>(y);
    for (int x = 0; x < kSkyCols; ++x) {
      const double u = static_cast<double>(x) / cell;
      const int c = static_cast<int>(u);
      const double fx = smooth(u - c);
      const double top = at(r, c) + fx * (at(r, c + 1) - at(r, c));
      const double bottom = at(r + 1, c) + fx * (at(r + 1, c + 1) - at(r + 1, c));
      row[x] += static_cast<float>(amplitude * (top + fy * (bottom - top)));
    }
  }
}

// Patchy cloud cover in [0, 1] by direction (kSkyCols x kSkyRows).
cv::Mat MakeClouds(uint64_t seed) {
  Random random(seed);
  cv::Mat sum = cv::Mat::zeros(kSkyRows, kSkyCols, CV_32F);
  double amplitude = 1.0;
  for (int cell : {128, 64, 32, 16, 8}) {
    AddNoiseOctave(cell, amplitude, &random, &sum);
    amplitude *= 0.55;
  }
  cv::Mat cover;
  sum.convertTo(cover, CV_32F, 1.6, -0.15);
  cv::min(cv::max(cover, 0.0), 1.0, cover);
  return cover;
}

// The sine of the depression of every pixel's ray (negative above the horizon).
cv::Mat SinDepressionMap(const ViewGeometry& view, int width, int height) {
  cv::Mat map(height, width, CV_32F);
  const Eigen::Matrix3d& m = view.world_ray_from_pixel;
  for (int y = 0; y < height; ++y) {
    float* row = map.ptr<float>(y);
    const Eigen::Vector3d start = m * Eigen::Vector3d(0, y, 1);
    const Eigen::Vector3d step = m.col(0);
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector3d ray = start + static_cast<double>(x) * step;
      row[x] = static_cast<float>(-ray.z() / ray.norm());
    }
  }
  return map;
}

// The sine of the depression of a ray meeting the ground `heights` camera heights away.
double SinDepressionAt(double heights) { return 1.0 / std::sqrt(1.0 + heights * heights); }

}  // namespace

FrameRenderer::FrameRenderer(const GroundSource& ground, const CameraIntrinsics& camera,
                             const ImagingOptions& imaging, uint64_t seed)
    : ground_(ground), camera_(camera), imaging_(imaging), seed_(seed) {
  clouds_ = MakeClouds(HashCombine(seed, 0x534B59u));
  if (imaging_.lens_k1 != 0) {
    // For each distorted pixel, the ideal one it shows: invert r_d = r_u (1 + k1 r_u^2) by
    // fixed-point iteration (it converges for |k1| <= 0.3 within the image).
    const int w = camera_.width, h = camera_.height;
    const LensFrame lens = LensFrameOf(w, h);
    distortion_x_.create(h, w, CV_32F);
    distortion_y_.create(h, w, CV_32F);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const Eigen::Vector2d d = (Eigen::Vector2d(x, y) - lens.centre) / lens.half_diagonal;
        Eigen::Vector2d u = d;
        for (int k = 0; k < 20; ++k) u = d / (1 + imaging_.lens_k1 * u.squaredNorm());
        const Eigen::Vector2d ideal = lens.centre + u * lens.half_diagonal;
        distortion_x_.at<float>(y, x) = static_cast<float>(ideal.x());
        distortion_y_.at<float>(y, x) = static_cast<float>(ideal.y());
      }
    }
  }
}

void FrameRenderer::SetCoarserLevels(std::vector<const GroundSource*> coarser_levels) {
  coarser_levels_ = std::move(coarser_levels);
}

int FrameRenderer::LevelFor(double ratio) {
  // Above ~1.5 raster pixels per frame pixel, sample a reduced level of the raster to avoid
  // aliasing (the warp's bilinear kernel only filters one pixel).
  int level = 0;
  while (level < 7 && ratio / static_cast<double>(1 << level) > 1.5) ++level;
  return level;
}

void FrameRenderer::RenderRows(const Eigen::Matrix3d& frame_from_ground, int row0, int row1,
                               int level, cv::Mat* bgr_out, cv::Mat* valid,
                               const std::vector<Eigen::Vector2d>& outline) const {
  // The coarser source of this level when there is one; else the coarsest there is (or the
  // full-detail raster), reduced the rest of the way. The far rows of a view reaching the horizon
  // need up to 128 times the ground's metres per pixel.
  const size_t coarser = std::min(static_cast<size_t>(level), coarser_levels_.size());
  const GroundSource& source = coarser > 0 ? *coarser_levels_[coarser - 1] : ground_;
  const int levels = level - static_cast<int>(coarser);
  const Eigen::Matrix3d raster_from_frame =
      RasterFromGround(source.gsd_m()) * frame_from_ground.inverse();
  // The raster area under the rows: their corners (or the outline of their ground), with a margin
  // for the interpolation kernel.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  const double left = -0.5, right = camera_.width - 0.5;
  std::vector<Eigen::Vector2d> corners = outline;
  if (corners.empty()) {
    corners = {Eigen::Vector2d(left, row0 - 0.5), Eigen::Vector2d(right, row0 - 0.5),
               Eigen::Vector2d(right, row1 - 0.5), Eigen::Vector2d(left, row1 - 0.5)};
  }
  // The sign of raster_from_frame's third coordinate in front of the camera: that of the frame
  // centre's in a downward view; ViewOfHomography's depth in general.
  const std::optional<ViewGeometry> view = ViewOfHomography(camera_, frame_from_ground);
  const Eigen::Matrix3d ground_from_frame = frame_from_ground.inverse();
  for (const Eigen::Vector2d& corner : corners) {
    const Eigen::Vector3d q = raster_from_frame * corner.homogeneous();
    if (view) {
      const Eigen::Vector3d ground = ground_from_frame * corner.homogeneous();
      SAKER_CHECK(view->depth_of_ground.dot(ground / ground.z()) > 0);  // in front of the camera
    } else {
      SAKER_CHECK(q.z() > 0);  // every corner ray hits the ground in front of the camera
    }
    const Eigen::Vector2d p = q.hnormalized();
    x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
  }
  const int step = 1 << levels;
  const int margin = 3 * step;
  cv::Rect region(static_cast<int>(std::floor(x0)) - margin,
                  static_cast<int>(std::floor(y0)) - margin, 0, 0);
  region.width = static_cast<int>(std::ceil(x1)) + margin - region.x;
  region.height = static_cast<int>(std::ceil(y1)) + margin - region.y;
  region.width += (step - region.width % step) % step;
  region.height += (step - region.height % step) % step;
  SAKER_CHECK(static_cast<double>(region.width) * region.height < 400e6);
  cv::Mat bgr, mask;
  source.Render(region, &bgr, &mask);
  for (int k = 0; k < levels; ++k) {
    cv::pyrDown(bgr, bgr);
    cv::pyrDown(mask, mask);
  }
  // rows_from_level = rows_from_frame * frame_from_raster * raster_from_level; pyrDown keeps the
  // even pixels, so level pixel i sits on raster pixel region.x + step * i.
  Eigen::Matrix3d raster_from_level;
  raster_from_level << step, 0, region.x, 0, step, region.y, 0, 0, 1;
  Eigen::Matrix3d rows_from_level = raster_from_frame.inverse() * raster_from_level;
  if (row0 != 0) {
    Eigen::Matrix3d rows_from_frame = Eigen::Matrix3d::Identity();
    rows_from_frame(1, 2) = -row0;
    rows_from_level = rows_from_frame * rows_from_level;
  }
  cv::Mat m(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = rows_from_level(r, c);
  }
  const cv::Size size(camera_.width, row1 - row0);
  cv::warpPerspective(bgr, *bgr_out, m, size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                      cv::Scalar::all(0));
  if (valid != nullptr) {
    cv::warpPerspective(mask, *valid, m, size, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
  }
}

cv::Mat FrameRenderer::RenderGround(const Eigen::Matrix3d& frame_from_ground,
                                    cv::Mat* valid) const {
  const int width = camera_.width, height = camera_.height;
  // The set of rays at least a given angle below the horizon is a cone about the downward vertical,
  // whose image is convex: when the frame's corners are inside, so is the whole frame.
  const std::optional<ViewGeometry> view = ViewOfHomography(camera_, frame_from_ground);
  double least_sin = 1;
  if (view) {
    for (const Eigen::Vector2d& p : ImageCorners(camera_)) {
      least_sin = std::min(least_sin, view->SinDepression(p.x(), p.y()));
    }
  }
  if (!view || least_sin >= SinDepressionAt(kHazeStartHeights)) {
    return RenderBands(frame_from_ground, 0, {}, valid);
  }
  // A view reaching the horizon: the ground of each row out to the draw distance, then the haze
  // and the sky over it.
  const cv::Mat sin_map = SinDepressionMap(*view, width, height);
  const float far_sin = static_cast<float>(SinDepressionAt(kDrawDistanceHeights));
  std::vector<std::pair<double, double>> spans(static_cast<size_t>(height), {1.0, 0.0});
  int first_row = height;
  for (int y = height - 1; y >= 0; --y) {
    const float* row = sin_map.ptr<float>(y);
    int x0 = 0;
    while (x0 < width && row[x0] < far_sin) ++x0;
    if (x0 == width) continue;
    int x1 = width - 1;
    while (row[x1] < far_sin) --x1;
    spans[static_cast<size_t>(y)] = {x0, x1};
    first_row = y;
  }
  cv::Mat frame;
  if (first_row < height) {
    frame = RenderBands(frame_from_ground, first_row, spans, valid);
  } else {
    frame = cv::Mat::zeros(height, width, CV_8UC3);
    if (valid != nullptr) *valid = cv::Mat::zeros(height, width, CV_8U);
  }
  DrawSkyAndHaze(*view, &frame, valid);
  return frame;
}

cv::Mat FrameRenderer::RenderBands(const Eigen::Matrix3d& frame_from_ground, int first_row,
                                   const std::vector<std::pair<double, double>>& spans,
                                   cv::Mat* valid) const {
  const int width = camera_.width, height = camera_.height;
  const Eigen::Matrix3d raster_from_frame =
      RasterFromGround(ground_.gsd_m()) * frame_from_ground.inverse();
  // Raster pixels per frame pixel at a frame point: the square root of the Jacobian determinant
  // of raster_from_frame there, det(M) / w^3 for a homography M with w the point's third
  // coordinate.
  const double det = std::abs(raster_from_frame.determinant());
  const auto isotropic_ratio_at = [&](double x, double y) {
    const double w = (raster_from_frame * Eigen::Vector3d(x, y, 1)).z();
    return std::sqrt(det / std::abs(w * w * w));
  };
  // Near the horizon a pixel is foreshortened many times more along the view than across it: the
  // larger singular value of the Jacobian there, or the warp aliases (moire on striped fields).
  const auto stretched_ratio_at = [&](double x, double y) {
    const Eigen::Matrix3d& m = raster_from_frame;
    const Eigen::Vector3d q = m * Eigen::Vector3d(x, y, 1);
    const double u = q.x() / q.z(), v = q.y() / q.z();
    Eigen::Matrix2d j;
    j << m(0, 0) - u * m(2, 0), m(0, 1) - u * m(2, 1), m(1, 0) - v * m(2, 0), m(1, 1) - v * m(2, 1);
    j /= q.z();
    const double a = j.squaredNorm() / 2, d = j.determinant();
    return std::sqrt(a + std::sqrt(std::max(a * a - d * d, 0.0)));
  };
  // Views whose rows end at the horizon use the stretched one; others keep the isotropic one
  // (their pictures, and the corpus measured on them, stay as they were).
  const auto ratio_at = [&](double x, double y) {
    return spans.empty() ? isotropic_ratio_at(x, y) : stretched_ratio_at(x, y);
  };
  // The columns of row r that show ground (an empty span: none).
  const auto span_of = [&](int r) {
    return spans.empty() ? std::pair<double, double>(-0.5, width - 0.5)
                         : spans[static_cast<size_t>(r)];
  };
  cv::Mat frame;
  if (spans.empty()) {
    std::vector<Eigen::Vector2d> quad;
    for (const Eigen::Vector2d& corner : ImageCorners(camera_)) quad.push_back(corner);
    double least = 1e300, most = 0;
    for (const Eigen::Vector2d& p : quad) {
      least = std::min(least, ratio_at(p.x(), p.y()));
      most = std::max(most, ratio_at(p.x(), p.y()));
    }
    if (most < 1.5 * least) {
      // One scale (nadir views): one level for the whole frame, from the area it covers.
      std::vector<cv::Point2f> raster_quad;
      for (const Eigen::Vector2d& p : quad) {
        const Eigen::Vector2d q = (raster_from_frame * p.homogeneous()).hnormalized();
        raster_quad.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
      }
      const double ratio = std::sqrt(cv::contourArea(raster_quad) /
                                     (static_cast<double>(width) * static_cast<double>(height)));
      RenderRows(frame_from_ground, 0, height, LevelFor(ratio), &frame, valid);
      if (valid != nullptr) cv::threshold(*valid, *valid, 254, 255, cv::THRESH_BINARY);
      return frame;
    }
  }
  // Bands of rows needing the same level (the coarser of the row's two ends), merged until each
  // is at least two blending widths high.
  constexpr int kBlendRows = 8;
  std::vector<std::pair<int, int>> bands;  // (first row, level)
  for (int r = first_row; r < height; ++r) {
    const auto [x0, x1] = span_of(r);
    const int level = x0 <= x1 ? LevelFor(std::max(ratio_at(x0, r), ratio_at(x1, r)))
                               : (bands.empty() ? 0 : bands.back().second);
    if (bands.empty() || bands.back().second != level) bands.emplace_back(r, level);
  }
  for (size_t i = 1; i < bands.size();) {
    const int end = i + 1 < bands.size() ? bands[i + 1].first : height;
    if (bands[i].first - bands[i - 1].first < 2 * kBlendRows ||
        end - bands[i].first < 2 * kBlendRows) {
      bands.erase(bands.begin() + static_cast<ptrdiff_t>(i));  // the band above takes its rows
    } else {
      ++i;
    }
  }
  cv::Mat sum = cv::Mat::zeros(height, width, CV_32FC3);
  cv::Mat sum_valid = cv::Mat::zeros(height, width, CV_32F);
  for (size_t i = 0; i < bands.size(); ++i) {
    const int top = bands[i].first;
    const int bottom = i + 1 < bands.size() ? bands[i + 1].first : height;
    const int row0 = i == 0 ? top : top - kBlendRows;
    const int row1 = i + 1 == bands.size() ? height : bottom + kBlendRows;
    // The ground of these rows, sampled every few rows (it is convex, and the sampled rows'
    // pixel edges bound it up to a fraction of a pixel, within the warp's margin).
    std::vector<Eigen::Vector2d> outline;
    if (!spans.empty()) {
      for (int r = row0; r < row1; r = (r + 4 < row1 || r == row1 - 1) ? r + 4 : row1 - 1) {
        const auto [x0, x1] = span_of(r);
        if (x0 > x1) continue;
        for (const double y : {r - 0.5, r + 0.5}) {
          outline.emplace_back(x0 - 0.5, y);
          outline.emplace_back(x1 + 0.5, y);
        }
      }
    }
    cv::Mat band, band_valid;
    RenderRows(frame_from_ground, row0, row1, bands[i].second, &band,
               valid != nullptr ? &band_valid : nullptr, outline);
    band.convertTo(band, CV_32FC3);
    if (valid != nullptr) band_valid.convertTo(band_valid, CV_32F);
    for (int r = row0; r < row1; ++r) {
      // Weights ramp over the 2 kBlendRows rows about each boundary and add up to one.
      double w = 1;
      if (i > 0 && r < top + kBlendRows) w = (r - (top - kBlendRows) + 0.5) / (2 * kBlendRows);
      if (i + 1 < bands.size() && r >= bottom - kBlendRows)
        w = std::min(w, (bottom + kBlendRows - r - 0.5) / (2 * kBlendRows));
      // sum.row(r) += w * band row, in place (the row headers allocate nothing).
      cv::Mat sum_row = sum.row(r);
      cv::scaleAdd(band.row(r - row0), w, sum_row, sum_row);
      if (valid != nullptr) {
        cv::Mat valid_row = sum_valid.row(r);
        cv::scaleAdd(band_valid.row(r - row0), w, valid_row, valid_row);
      }
    }
  }
  sum.convertTo(frame, CV_8UC3);
  if (valid != nullptr) {
    sum_valid.convertTo(*valid, CV_8U);
    cv::threshold(*valid, *valid, 253, 255, cv::THRESH_BINARY);
  }
  return frame;
}

void FrameRenderer::DrawSkyAndHaze(const ViewGeometry& view, cv::Mat* frame, cv::Mat* valid) const {
  const int width = frame->cols, height = frame->rows;
  const double far_heights = kDrawDistanceHeights, haze_heights = kHazeStartHeights;
  const double haze_sin = SinDepressionAt(haze_heights), far_sin = SinDepressionAt(far_heights);
  const Eigen::Matrix3d& m = view.world_ray_from_pixel;
  constexpr double kDegPerRad = 180.0 / M_PI;
  for (int y = 0; y < height; ++y) {
    cv::Vec3b* row = frame->ptr<cv::Vec3b>(y);
    uint8_t* valid_row = valid != nullptr ? valid->ptr<uint8_t>(y) : nullptr;
    const Eigen::Vector3d start = m * Eigen::Vector3d(0, y, 1);
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector3d ray = start + static_cast<double>(x) * m.col(0);
      const double sin_dep = -ray.z() / ray.norm();
      if (sin_dep >= haze_sin) continue;
      // How much haze: none at haze_heights away, all of it at far_heights and beyond.
      double haze = 1;
      if (sin_dep > far_sin) {
        const double heights = std::sqrt(1 - sin_dep * sin_dep) / sin_dep;
        haze = (heights - haze_heights) / (far_heights - haze_heights);
      }
      cv::Vec3f backdrop = kHazeBgr;
      if (sin_dep < 0) {
        // The sky: bluer with elevation, and the clouds of this direction, fading in over the
        // first degrees above the horizon.
        const double elevation = -std::asin(sin_dep) * kDegPerRad;
        const double blue = std::pow(std::min(elevation / 25.0, 1.0), 0.6);
        backdrop = kHazeBgr + static_cast<float>(blue) * (kZenithBgr - kHazeBgr);
        double azimuth = std::atan2(ray.x(), ray.y()) * kDegPerRad;
        if (azimuth < 0) azimuth += 360;
        const double u = azimuth / 360.0 * kSkyCols;
        const double v = std::min(elevation / kSkyRowsDeg, 1.0) * (kSkyRows - 1);
        const int c = std::min(static_cast<int>(u), kSkyCols - 1);
        const int r = std::min(static_cast<int>(v), kSkyRows - 2);
        const double fu = u - c, fv = v - r;
        const int c1 = (c + 1) % kSkyCols;
        const double cover =
            (1 - fv) * ((1 - fu) * clouds_.at<float>(r, c) + fu * clouds_.at<float>(r, c1)) +
            fv * ((1 - fu) * clouds_.at<float>(r + 1, c) + fu * clouds_.at<float>(r + 1, c1));
        const double fade = std::min(elevation / 3.0, 1.0);
        backdrop += static_cast<float>(cover * fade) * (kCloudBgr - backdrop);
      }
      const cv::Vec3f ground(row[x][0], row[x][1], row[x][2]);
      const cv::Vec3f out = ground + static_cast<float>(haze) * (backdrop - ground);
      row[x] = cv::Vec3b(cv::saturate_cast<uint8_t>(out[0]), cv::saturate_cast<uint8_t>(out[1]),
                         cv::saturate_cast<uint8_t>(out[2]));
      if (valid_row != nullptr) valid_row[x] = 0;
    }
  }
}

bool FrameRenderer::Shows(const Eigen::Matrix3d& frame_from_ground,
                          const Eigen::Vector2d& ground_m) const {
  const std::optional<ViewGeometry> view = ViewOfHomography(camera_, frame_from_ground);
  if (!view) return true;
  if (!(view->depth_of_ground.dot(ground_m.homogeneous()) > 0)) return false;
  return (ground_m - view->position_m.head<2>()).norm() <= kHazeStartHeights * view->height_m();
}

// Thermal ground seen white-hot, from the visible ground: dark surfaces (asphalt, roofs) soak up
// the sun and glow, vegetation and pale surfaces stay cool, all within a narrow band of grey
// levels (a thermal scene has far less contrast than a visible one). Black stays black (no data).
cv::Mat FrameRenderer::ThermalGround(const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::Mat thermal;
  grey.convertTo(thermal, CV_8U, -0.35, 150.0 + 0.35 * 128.0);
  thermal.setTo(0, grey == 0);
  cv::Mat out;
  cv::cvtColor(thermal, out, cv::COLOR_GRAY2BGR);
  return out;
}

std::vector<Target> FrameRenderer::ThermalTargets(const std::vector<Target>& targets) {
  // Running engines and bodies are warm: vehicles bright with cool (sky-reflecting) glass, people
  // a little less bright.
  std::vector<Target> warm = targets;
  for (Target& t : warm) {
    t.look.body_bgr = cv::Scalar::all(220);
    t.clothes_bgr = cv::Scalar::all(205);
  }
  return warm;
}

cv::Mat FrameRenderer::Render(const Eigen::Matrix3d& frame_from_ground,
                              const std::vector<Target>& targets,
                              const Eigen::Vector2d& shadow_per_m, int64_t frame_index,
                              double time_s, cv::Mat* valid) const {
  cv::Mat frame;
  Random random(HashCombine(seed_, static_cast<uint64_t>(frame_index) * 0x9E37u + 17));
  if (imaging_.IsBlank(time_s)) {
    // Cloud: bright, almost featureless, slowly varying.
    cv::Mat small(9, 16, CV_8UC3);
    for (int r = 0; r < small.rows; ++r) {
      for (int c = 0; c < small.cols; ++c) {
        const uint8_t v = static_cast<uint8_t>(random.Uniform(215, 240));
        small.at<cv::Vec3b>(r, c) = cv::Vec3b(v, v, static_cast<uint8_t>(v - 3));
      }
    }
    cv::resize(small, frame, cv::Size(camera_.width, camera_.height), 0, 0, cv::INTER_CUBIC);
    if (valid != nullptr) *valid = cv::Mat::zeros(frame.size(), CV_8U);
  } else {
    std::vector<Target> shown;
    for (const Target& t : targets) {
      if (Shows(frame_from_ground, t.position)) shown.push_back(t);
    }
    if (imaging_.infrared()) {
      frame = ThermalGround(RenderGround(frame_from_ground, valid));
      DrawTargets(ThermalTargets(shown), Eigen::Vector2d::Zero(), frame_from_ground, &frame);
    } else {
      frame = RenderGround(frame_from_ground, valid);
      DrawTargets(shown, shadow_per_m, frame_from_ground, &frame);
    }
  }
  if (!distortion_x_.empty()) {
    cv::Mat distorted;
    cv::remap(frame, distorted, distortion_x_, distortion_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar::all(0));
    frame = distorted;
    if (valid != nullptr) {
      cv::remap(*valid, distorted, distortion_x_, distortion_y_, cv::INTER_NEAREST,
                cv::BORDER_CONSTANT, cv::Scalar(0));
      *valid = distorted;
    }
  }
  if (imaging_.blur_sigma_px > 0) {
    cv::GaussianBlur(frame, frame, cv::Size(), imaging_.blur_sigma_px);
  }
  if (imaging_.motion_blur_px > 0) {
    // A box smear along the image's vertical axis: the ground's motion in a forward flight.
    const int length = std::max(1, static_cast<int>(std::lround(imaging_.motion_blur_px)));
    cv::blur(frame, frame, cv::Size(1, length));
  }
  if (imaging_.haze > 0) {
    frame.convertTo(frame, -1, 1.0 - imaging_.haze, 205.0 * imaging_.haze);
  }
  if (imaging_.infrared() && !imaging_.WhiteHotAt(time_s)) {
    cv::bitwise_not(frame, frame);  // black-hot
  }
  if (imaging_.gain_drift > 0) {
    const double gain =
        1.0 + imaging_.gain_drift * std::sin(2 * M_PI * time_s / imaging_.gain_period_s);
    frame.convertTo(frame, -1, gain);
  }
  if (imaging_.noise_sigma > 0) {
    cv::Mat noise(frame.size(), CV_16SC3);
    cv::RNG rng(random.Next());
    rng.fill(noise, cv::RNG::NORMAL, 0.0, imaging_.noise_sigma);
    cv::Mat widened;
    frame.convertTo(widened, CV_16SC3);
    widened += noise;
    widened.convertTo(frame, CV_8UC3);
  }
  return frame;
}

}  // namespace saker::sim
