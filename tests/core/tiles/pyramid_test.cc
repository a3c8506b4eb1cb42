#include "core/tiles/pyramid.h"

#include "core/tiles/image_decode.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <map>
#include <optional>
#include <tuple>

namespace saker::tiles {
namespace {

constexpr int kWidth = 640, kHeight = 480;

// A grey test card: a horizontal ramp with a dark grid every 32 pixels.
cv::Mat TestCard(int width, int height, int offset) {
  cv::Mat grey(height, width, CV_8U);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const bool line = (x + offset) % 32 == 0 || y % 32 == 0;
      grey.at<uint8_t>(y, x) = line ? 10 : static_cast<uint8_t>(60 + (x + offset) % 160);
    }
  }
  return grey;
}

// Full-resolution frame placed at `east` metres, 0.5 m per pixel, north up (image y down).
Eigen::Matrix3d MapFromFrame(double east) {
  Eigen::Matrix3d h;
  h << 0.5, 0, east, 0, -0.5, 0, 0, 0, 1;
  return h;
}

// A key frame to draw, with an overlay mask or a sky line when given.
KeyFrameView View(const cv::Mat& grey, double scale, const Eigen::Matrix3d& map_from_frame,
                  const mission::OverlayRecord* overlay = nullptr,
                  std::optional<mission::SkyLine> sky_line = std::nullopt) {
  return {&grey, scale, map_from_frame, overlay, sky_line, nullptr, {}};
}

using Store = std::map<std::tuple<int, int, int>, std::vector<uint8_t>>;

TileSink Into(Store* store) {
  return [store](const std::vector<mission::EncodedTile>& tiles) -> Status {
    for (const mission::EncodedTile& tile : tiles)
      store->emplace(std::make_tuple(tile.level, tile.x, tile.y), tile.bytes);
    return {};
  };
}

// The level 0 pixel of `info` nearest `map` as (tile x, tile y, column, row in the tile).
std::array<int, 4> Locate(const mission::PyramidInfo& info, const Eigen::Vector2d& map) {
  const int u = static_cast<int>(std::lround((map.x() - info.map_origin.x()) / info.step_x));
  const int v = static_cast<int>(std::lround((map.y() - info.map_origin.y()) / info.step_y));
  return {u / info.tile_size, v / info.tile_size, u % info.tile_size, v % info.tile_size};
}

// The overlay mask of a line of text across the frame: full-resolution rows 40-79 (8 px cells).
mission::OverlayRecord TextLineMask() {
  mission::OverlayRecord mask;
  mask.first_frame = mask.last_frame = 0;
  mask.cell_px = 8;
  mask.cols = kWidth / 8;
  mask.rows = kHeight / 8;
  mask.cells.assign(static_cast<size_t>(mask.cols * mask.rows), 0);
  for (int y = 5; y < 10; ++y) {
    for (int x = 0; x < mask.cols; ++x) mask.cells[static_cast<size_t>(y * mask.cols + x)] = 1;
  }
  return mask;
}

TEST(Pyramid, PlacesAndBlendsKeyFramesAcrossLevels) {
  // Two 640 x 480 frames stored at half size (scale 2), 100 m apart (overlapping by 220 m).
  const cv::Mat a = TestCard(kWidth / 2, kHeight / 2, 0), b = TestCard(kWidth / 2, kHeight / 2, 0);
  const std::vector<KeyFrameView> frames = {View(a, 2.0, MapFromFrame(0)),
                                            View(b, 2.0, MapFromFrame(100))};
  PyramidOptions options;
  options.tile_size = 64;
  const auto info = PlanPyramid(frames, kWidth, kHeight, /*geo_referenced=*/true, options);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_DOUBLE_EQ(info->step_x, 0.5);   // the frames' own resolution
  EXPECT_DOUBLE_EQ(info->step_y, -0.5);  // north up
  EXPECT_EQ(info->width, 840);           // (100 + 319.5) / 0.5 + 1
  EXPECT_EQ(info->height, 480);
  EXPECT_EQ(info->levels, 5);  // 840 -> 420 -> 210 -> 105 -> 53 <= 64
  EXPECT_NEAR(info->map_origin.x(), 0, 1e-9);
  EXPECT_NEAR(info->map_origin.y(), 0, 1e-9);

  Store store;
  const auto summary = RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store));
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  EXPECT_EQ(summary->tiles_written, static_cast<int64_t>(store.size()));
  // Level 0: 14 x 8 tiles, all covered; the top level: a single tile.
  int level0 = 0;
  for (const auto& [key, bytes] : store) level0 += std::get<0>(key) == 0;
  EXPECT_EQ(level0, 14 * 8);
  ASSERT_EQ(store.count({4, 0, 0}), 1u);

  // A map point on frame a only (x = 20 m, y = -30 m): full-resolution pixel (40, 60), grey
  // pixel (19.75, 29.75) of the half-size card, between card values.
  const auto pixel = [&](const Eigen::Vector2d& map) {
    const auto [tx, ty, col, row] = Locate(*info, map);
    const auto tile = DecodeTile(store.at({0, tx, ty}), info->tile_size);
    EXPECT_TRUE(tile.ok());
    return tile->at<cv::Vec4b>(row, col);
  };
  const cv::Vec4b on_a = pixel({20.5, -30.5});
  EXPECT_EQ(on_a[3], 255);
  EXPECT_EQ(on_a[0], on_a[1]);       // grey
  EXPECT_NEAR(on_a[0], 60 + 20, 2);  // the ramp at grey column 20
  // In the overlap both cards agree up to the ramp's shift of 100 m = 100 grey pixels: the blend
  // lies between the two values.
  const cv::Vec4b overlap = pixel({150.5, -30.5});
  const double value_a = 60 + 150, value_b = 60 + 50;
  EXPECT_EQ(overlap[3], 255);
  EXPECT_GE(overlap[0], value_b - 2);
  EXPECT_LE(overlap[0], value_a + 2);
  // The top tile covers everything, downsampled 16x: alpha on the footprint, 0 beyond it.
  const auto top = DecodeTile(store.at({4, 0, 0}), info->tile_size);
  ASSERT_TRUE(top.ok());
  EXPECT_EQ(top->at<cv::Vec4b>(10, 20)[3], 255);
  EXPECT_EQ(top->at<cv::Vec4b>(50, 60)[3], 0);  // row 50 * 16 = 800 > 480: below the footprint
}

// A key frame's overlay mask (burned-in text) is never drawn as it is: in the overlap the other
// key frame's picture is there alone, and where no other frame covers the masked place the map
// shows a fill from the ground around it, not the text and not a hole.
TEST(Pyramid, OverlayMasksAreNotDrawn) {
  // Frame a is dark with a line of bright "text" on full-resolution rows 40-79, which its mask
  // covers; frame b is bright.
  cv::Mat a(kHeight / 2, kWidth / 2, CV_8U, cv::Scalar(40));
  a.rowRange(20, 40).setTo(250);
  const cv::Mat b(kHeight / 2, kWidth / 2, CV_8U, cv::Scalar(200));
  const mission::OverlayRecord mask = TextLineMask();
  const std::vector<KeyFrameView> frames = {View(a, 2.0, MapFromFrame(0), &mask),
                                            View(b, 2.0, MapFromFrame(100))};
  PyramidOptions options;
  options.tile_size = 64;
  const auto info = PlanPyramid(frames, kWidth, kHeight, /*geo_referenced=*/true, options);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  Store store;
  ASSERT_TRUE(RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store)).ok());
  const auto pixel = [&](const Eigen::Vector2d& map) {
    const auto [tx, ty, col, row] = Locate(*info, map);
    const auto tile = DecodeTile(store.at({0, tx, ty}), info->tile_size);
    EXPECT_TRUE(tile.ok());
    return tile->at<cv::Vec4b>(row, col);
  };
  // Full-resolution row 60 is y = -30 m. On a alone (x = 20 m): the ground around, not the text;
  // off the mask (row 200, y = -100 m): a's grey.
  EXPECT_EQ(pixel({20.5, -30.5})[3], 255);
  EXPECT_NEAR(pixel({20.5, -30.5})[0], 40, 2);
  EXPECT_EQ(pixel({20.5, -100.5})[3], 255);
  EXPECT_NEAR(pixel({20.5, -100.5})[0], 40, 1);
  // In the overlap (x = 200 m): b alone on a's mask, a blend of both elsewhere.
  EXPECT_NEAR(pixel({200.5, -30.5})[0], 200, 1);
  const cv::Vec4b blend = pixel({200.5, -100.5});
  EXPECT_GT(blend[0], 45);
  EXPECT_LT(blend[0], 195);
}

// Colour key frames give colour tiles: JPEG where a tile is covered throughout, PNG (with its
// alpha) at the edges; a grey key frame among them is drawn grey; an overlay mask is filled with
// the colour around it. A grey mission's tiles stay PNG.
TEST(Pyramid, ColourKeyFramesGiveColourTiles) {
  // Frame a: BT.709 limited-range red (Y 63, Cb 102, Cr 240), a line of green "text" on
  // full-resolution rows 40-79 under its overlay mask. Frame b: mid grey luma, no chroma.
  const cv::Mat luma(kHeight / 2, kWidth / 2, CV_8U, cv::Scalar(63));
  const cv::Mat mid_grey(kHeight / 2, kWidth / 2, CV_8U, cv::Scalar(126));
  cv::Mat red((kHeight / 2 + 1) / 2, (kWidth / 2 + 1) / 2, CV_8UC2, cv::Scalar(102, 240));
  red.rowRange(10, 20).setTo(cv::Scalar(42, 26));  // green text (chroma rows 10-19)
  const mission::OverlayRecord mask = TextLineMask();
  const YuvCoding coding{YuvMatrix::kBt709, false};
  KeyFrameView a = View(luma, 2.0, MapFromFrame(0), &mask);
  a.chroma = &red;
  a.coding = coding;
  KeyFrameView b = View(mid_grey, 2.0, MapFromFrame(400));
  b.coding = coding;
  const std::vector<KeyFrameView> frames = {a, b};
  PyramidOptions options;
  options.tile_size = 64;
  const auto info = PlanPyramid(frames, kWidth, kHeight, /*geo_referenced=*/true, options);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  Store store;
  ASSERT_TRUE(RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store)).ok());
  int jpeg = 0, png = 0;
  for (const auto& [key, bytes] : store) {
    const auto tile = DecodeTile(bytes, info->tile_size);
    ASSERT_TRUE(tile.ok()) << tile.status().ToString();
    if (!IsJpeg(bytes)) {
      ++png;
      continue;
    }
    ++jpeg;
    cv::Mat alpha;
    cv::extractChannel(*tile, alpha, 3);
    EXPECT_EQ(cv::countNonZero(alpha != 255), 0) << "a JPEG tile is covered throughout";
  }
  EXPECT_GT(jpeg, 0);
  EXPECT_GT(png, 0);  // the footprints' edges
  const auto pixel = [&](const Eigen::Vector2d& map) {
    const auto [tx, ty, col, row] = Locate(*info, map);
    const auto tile = DecodeTile(store.at({0, tx, ty}), info->tile_size);
    EXPECT_TRUE(tile.ok());
    return tile->at<cv::Vec4b>(row, col);
  };
  const cv::Vec4b on_a = pixel({100.5, -150.5});
  EXPECT_NEAR(on_a[2], 255, 6);  // 709 red from its coded values
  EXPECT_NEAR(on_a[1], 0, 6);
  EXPECT_NEAR(on_a[0], 0, 6);
  const cv::Vec4b on_b = pixel({600.5, -150.5});
  EXPECT_NEAR(on_b[0], 128, 3);  // luma 126 of 16..235 is 128 of 0..255
  EXPECT_NEAR(on_b[1], 128, 3);
  EXPECT_NEAR(on_b[2], 128, 3);
  // On a's mask (row 60 is y = -30 m): the red around it, not the green text.
  const cv::Vec4b on_mask = pixel({100.5, -30.5});
  EXPECT_GT(on_mask[2], on_mask[1] + 150);

  // The same two frames without chroma: every tile PNG.
  a.chroma = nullptr;
  Store grey;
  ASSERT_TRUE(RenderPyramid({a, b}, kWidth, kHeight, *info, options, Into(&grey)).ok());
  EXPECT_EQ(grey.size(), store.size());
  for (const auto& [key, bytes] : grey) EXPECT_FALSE(IsJpeg(bytes));
}

TEST(Pyramid, TilesNoFrameCoversAreNotWritten) {
  // Two frames far apart on a diagonal: the tiles between them stay empty.
  const cv::Mat a = TestCard(kWidth, kHeight, 0);
  Eigen::Matrix3d far = MapFromFrame(2000);
  far(1, 2) = -2000;
  const std::vector<KeyFrameView> frames = {View(a, 1.0, MapFromFrame(0)), View(a, 1.0, far)};
  PyramidOptions options;
  options.tile_size = 128;
  const auto info = PlanPyramid(frames, kWidth, kHeight, true, options);
  ASSERT_TRUE(info.ok());
  Store store;
  const auto summary = RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store));
  ASSERT_TRUE(summary.ok());
  int level0 = 0;
  for (const auto& [key, bytes] : store) level0 += std::get<0>(key) == 0;
  // Each frame covers 640 x 480 px: 6 x 5 tiles of 128 at most (depending on alignment).
  EXPECT_LE(level0, 2 * 6 * 5);
  EXPECT_GE(level0, 2 * 5 * 4);
  EXPECT_GT(summary->empty_tiles, 0);
}

TEST(Pyramid, CancelAndErrors) {
  const cv::Mat a = TestCard(kWidth, kHeight, 0);
  const std::vector<KeyFrameView> frames = {View(a, 1.0, MapFromFrame(0))};
  PyramidOptions options;
  const auto info = PlanPyramid(frames, kWidth, kHeight, false, options);
  ASSERT_TRUE(info.ok());
  EXPECT_GT(info->step_y, 0);  // not geo-referenced: the image's orientation

  JobContext job;
  job.RequestCancel();
  Store store;
  const auto cancelled = RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store), &job);
  ASSERT_FALSE(cancelled.ok());
  EXPECT_EQ(cancelled.status().code(), StatusCode::kCancelled);

  // A failing sink stops the render with its error.
  const auto failed =
      RenderPyramid(frames, kWidth, kHeight, *info, options,
                    [](const std::vector<mission::EncodedTile>&) { return IoError("disk full"); });
  ASSERT_FALSE(failed.ok());
  EXPECT_NE(failed.status().message().find("disk full"), std::string::npos);

  // Nothing drawable: the whole frame behind the map's plane, or above its sky line.
  Eigen::Matrix3d behind = Eigen::Matrix3d::Identity();
  behind(2, 2) = -1;
  EXPECT_FALSE(PlanPyramid({View(a, 1.0, behind)}, kWidth, kHeight, false, options).ok());
  EXPECT_FALSE(PlanPyramid({View(a, 1.0, MapFromFrame(0), nullptr, mission::SkyLine{kHeight, 0})},
                           kWidth, kHeight, false, options)
                   .ok());
  EXPECT_FALSE(DecodeTile({1, 2, 3}, options.tile_size).ok());
  options.tile_size = 3;
  EXPECT_FALSE(options.Validate().ok());
}

// A low oblique view's sky: nothing above the sky line is drawn, the ground below it is.
TEST(Pyramid, TheSkyAboveTheSkyLineIsNotDrawn) {
  const cv::Mat a = TestCard(kWidth, kHeight, 0);
  const mission::SkyLine sky{200, 0.1};  // from row 200 at the left to row 264 at the right
  const std::vector<KeyFrameView> frames = {View(a, 1.0, MapFromFrame(0), nullptr, sky)};
  const std::vector<Eigen::Vector2d> part = DrawnPart(frames[0], kWidth, kHeight);
  ASSERT_EQ(part.size(), 4u);
  for (const Eigen::Vector2d& p : part) EXPECT_FALSE(sky.Masks(p + Eigen::Vector2d(0, 1e-9)));
  PyramidOptions options;
  options.tile_size = 64;
  const auto info = PlanPyramid(frames, kWidth, kHeight, true, options);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  // The map covers the ground below the line only: 280 rows at most of 480.
  EXPECT_LE(std::abs(info->height * info->step_y), 0.5 * 281 + 1);
  Store store;
  ASSERT_TRUE(RenderPyramid(frames, kWidth, kHeight, *info, options, Into(&store)).ok());
  const auto alpha_at = [&](const Eigen::Vector2d& pixel) -> int {
    const Eigen::Vector2d map = (MapFromFrame(0) * pixel.homogeneous()).hnormalized();
    const auto [tx, ty, col, row] = Locate(*info, map);
    const auto it = store.find({0, tx, ty});
    if (it == store.end()) return 0;
    const auto tile = DecodeTile(it->second, info->tile_size);
    if (!tile.ok()) return -1;
    return tile->at<cv::Vec4b>(row, col)[3];
  };
  EXPECT_EQ(alpha_at({100, 400}), 255);  // ground
  EXPECT_EQ(alpha_at({600, 300}), 255);  // ground, just below the line there (row 260)
  EXPECT_EQ(alpha_at({600, 240}), 0);    // sky, right of the frame
}

// Towards the horizon the ground is drawn only as far as its scale stays within kMaxScaleSpread
// of the nearest ground's: a frame whose rows fade into the distance keeps its nearer part.
TEST(Pyramid, GroundFarBeyondTheNearestIsLeftOut) {
  const cv::Mat a = TestCard(kWidth, kHeight, 0);
  Eigen::Matrix3d oblique = Eigen::Matrix3d::Identity();
  oblique(2, 1) = 1.0 / 400;  // w = 1 + y / 400: 1 at the top row, 2.2 at the bottom
  const std::vector<Eigen::Vector2d> part = DrawnPart(View(a, 1.0, oblique), kWidth, kHeight);
  ASSERT_EQ(part.size(), 4u);
  // w >= 2.2 * 8^(-2/3) = 0.55 everywhere: nothing cut.
  for (const Eigen::Vector2d& p : part) EXPECT_TRUE(p.y() == 0 || p.y() == kHeight - 1);
  oblique(2, 2) = 0.05;  // w = 0.05 + y / 400: the top row 25 times farther than the bottom one
  const std::vector<Eigen::Vector2d> near = DrawnPart(View(a, 1.0, oblique), kWidth, kHeight);
  ASSERT_EQ(near.size(), 4u);
  // The nearest ground has w = 1.2475 (the bottom row); kept: w >= 1.2475 / 4, y >= 104.75.
  double top = kHeight;
  for (const Eigen::Vector2d& p : near) top = std::min(top, p.y());
  EXPECT_NEAR(top, 400 * (1.2475 / 4 - 0.05), 1e-6);
  // A frame that reaches beyond the map's horizon (the top rows behind its plane) is not drawn,
  // unless its sky line cuts that part away.
  Eigen::Matrix3d beyond = oblique;
  beyond(2, 2) = -0.3;  // behind the plane above row 120
  EXPECT_TRUE(DrawnPart(View(a, 1.0, beyond), kWidth, kHeight).empty());
  EXPECT_EQ(
      DrawnPart(View(a, 1.0, beyond, nullptr, mission::SkyLine{150, 0}), kWidth, kHeight).size(),
      4u);
  PyramidOptions options;
  EXPECT_TRUE(PlanPyramid({View(a, 1.0, oblique)}, kWidth, kHeight, false, options).ok());
}

}  // namespace
}  // namespace saker::tiles
