#include "core/sim/ground_image.h"

#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

// The test target does not get GDAL's include directory (saker_sim keeps GDAL private), so reach
// the headers through their folder; their own quoted includes resolve beside them.
#include <gdal.h>
#include <ogr_srs_api.h>

#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace saker::sim {
namespace {

namespace fs = std::filesystem;

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// The colour written at image pixel (x, y) of the synthetic images: unique per pixel.
cv::Vec3b Colour(int x, int y) {
  return cv::Vec3b(static_cast<uint8_t>(10 + 20 * x), static_cast<uint8_t>(15 + 30 * y), 200);
}

// A 6 x 4 BGRA PNG: column 0 and pixel (3, 2) transparent, the rest opaque or half transparent.
fs::path WriteAlphaPng(const fs::path& dir) {
  cv::Mat bgra(4, 6, CV_8UC4);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 6; ++x) {
      const cv::Vec3b c = Colour(x, y);
      const uint8_t alpha = (x == 0 || (x == 3 && y == 2)) ? 0 : (x == 5 ? 1 : 255);
      bgra.at<cv::Vec4b>(y, x) = cv::Vec4b(c[0], c[1], c[2], alpha);
    }
  }
  const fs::path path = dir / "alpha.png";
  EXPECT_TRUE(cv::imwrite(path.string(), bgra));
  return path;
}

bool PixelIsData(int x, int y) { return !(x == 0 || (x == 3 && y == 2)); }

StatusOr<std::unique_ptr<GroundImage>> Load(const fs::path& path, double gsd,
                                            Eigen::Vector2d centre = {0, 0}) {
  GroundImageOptions options;
  options.path = path;
  options.gsd_m = gsd;
  options.centre_m = centre;
  return GroundImage::Load(options);
}

// Checks a render of raster pixels `region` against the synthetic image placed at `offset`.
void ExpectRenderMatches(const GroundImage& ground, const cv::Rect& region, cv::Point offset) {
  cv::Mat bgr, valid;
  ground.Render(region, &bgr, &valid);
  ASSERT_EQ(bgr.type(), CV_8UC3);
  ASSERT_EQ(valid.type(), CV_8UC1);
  ASSERT_EQ(bgr.size(), region.size());
  ASSERT_EQ(valid.size(), region.size());
  for (int r = 0; r < region.height; ++r) {
    for (int c = 0; c < region.width; ++c) {
      const int x = region.x + c - offset.x;
      const int y = region.y + r - offset.y;
      const bool inside = x >= 0 && x < 6 && y >= 0 && y < 4;
      const bool data = inside && PixelIsData(x, y);
      SCOPED_TRACE(::testing::Message() << "raster (" << region.x + c << ", " << region.y + r
                                        << "), image (" << x << ", " << y << ")");
      EXPECT_EQ(valid.at<uint8_t>(r, c), data ? 255 : 0);
      EXPECT_EQ(bgr.at<cv::Vec3b>(r, c), data ? Colour(x, y) : cv::Vec3b(0, 0, 0));
    }
  }
}

TEST(GroundImageOptionsTest, ValidateRejectsNonsense) {
  GroundImageOptions options;
  EXPECT_FALSE(options.Validate().ok());  // no path
  options.path = "ortho.png";
  EXPECT_TRUE(options.Validate().ok());
  options.gsd_m = -0.5;
  EXPECT_FALSE(options.Validate().ok());
  EXPECT_TRUE(Contains(options.Validate().message(), "ortho.png"));
  options.gsd_m = NAN;
  EXPECT_FALSE(options.Validate().ok());
  options.gsd_m = 0.2;
  options.centre_m.x() = INFINITY;
  EXPECT_FALSE(options.Validate().ok());
}

TEST(GroundImageTest, PngWithAlphaRendersExactPixelsAndMask) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  // Centre (10, -20) m at 0.5 m/px is raster (20, 40); the 6 x 4 image's centre is pixel
  // (2.5, 1.5), so image (0, 0) goes to raster (17.5, 38.5), rounded away from zero: (18, 39).
  auto ground = Load(WriteAlphaPng(dir), 0.5, {10, -20});
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  const GroundImage& image = **ground;
  const cv::Point offset(18, 39);
  EXPECT_EQ(image.raster_offset(), offset);
  EXPECT_EQ(image.gsd_m(), 0.5);
  EXPECT_EQ(image.image().size(), cv::Size(6, 4));
  EXPECT_EQ(image.image().type(), CV_8UC3);
  // Outer pixel edges: raster columns 17.5 .. 23.5, rows 38.5 .. 42.5.
  const cv::Rect2d extent = image.extent_m();
  EXPECT_DOUBLE_EQ(extent.x, 8.75);
  EXPECT_DOUBLE_EQ(extent.y, -21.25);
  EXPECT_DOUBLE_EQ(extent.width, 3.0);
  EXPECT_DOUBLE_EQ(extent.height, 2.0);

  // Transparent pixels are invalid and black; alpha 1 is still data.
  EXPECT_EQ(image.mask().at<uint8_t>(2, 3), 0);
  EXPECT_EQ(image.mask().at<uint8_t>(0, 5), 255);
  EXPECT_EQ(image.image().at<cv::Vec3b>(2, 3), cv::Vec3b(0, 0, 0));

  ExpectRenderMatches(image, cv::Rect(19, 40, 4, 3), offset);    // inside
  ExpectRenderMatches(image, cv::Rect(15, 37, 6, 5), offset);    // over the north-west corner
  ExpectRenderMatches(image, cv::Rect(22, 41, 5, 5), offset);    // over the south-east corner
  ExpectRenderMatches(image, cv::Rect(10, 30, 20, 20), offset);  // around the whole image
  ExpectRenderMatches(image, cv::Rect(24, 39, 3, 4), offset);    // just east: nothing
  ExpectRenderMatches(image, cv::Rect(-50, -60, 7, 3), offset);  // far away, negative indices

  // An empty region gives empty images; stale output buffers are replaced.
  cv::Mat bgr(9, 9, CV_32F), valid(2, 2, CV_8UC3, cv::Scalar::all(7));
  image.Render(cv::Rect(19, 40, 0, 0), &bgr, &valid);
  EXPECT_TRUE(bgr.empty());
  EXPECT_TRUE(valid.empty());
  image.Render(cv::Rect(18, 39, 2, 2), &bgr, &valid);
  EXPECT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(valid.at<uint8_t>(0, 1), 255);
  EXPECT_EQ(valid.at<uint8_t>(0, 0), 0);
}

TEST(GroundImageTest, PlacementPutsTheCentrePixelAtTheCentre) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  cv::Mat grey(5, 7, CV_8UC1, cv::Scalar(90));
  const fs::path path = dir / "odd.png";
  ASSERT_TRUE(cv::imwrite(path.string(), grey));
  // Odd sizes and a centre on a raster pixel: the centre pixel (3, 2) lands exactly on it.
  auto ground = Load(path, 0.25, {-3.0, 1.0});
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  EXPECT_EQ((*ground)->raster_offset() + cv::Point(3, 2), cv::Point(-12, -4));
  // Off the pixel grid by 0.4 pixel east: rounded to the nearest raster pixel.
  ground = Load(path, 0.25, {-2.9, 1.0});
  ASSERT_TRUE(ground.ok());
  EXPECT_EQ((*ground)->raster_offset() + cv::Point(3, 2), cv::Point(-12, -4));
  const cv::Rect2d extent = (*ground)->extent_m();
  EXPECT_NEAR(extent.x + 0.5 * extent.width, -3.0, 1e-12);
  EXPECT_NEAR(extent.y + 0.5 * extent.height, 1.0, 1e-12);
}

TEST(GroundImageTest, GreySixteenBitBecomesEightBitBgr) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  cv::Mat grey(2, 3, CV_16UC1);
  grey.at<uint16_t>(0, 0) = 0;
  grey.at<uint16_t>(0, 1) = 257 * 100;
  grey.at<uint16_t>(0, 2) = 65535;
  grey.row(1).setTo(257 * 7);
  const fs::path path = dir / "grey16.png";
  ASSERT_TRUE(cv::imwrite(path.string(), grey));
  auto ground = Load(path, 1.0);
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  const cv::Mat& image = (*ground)->image();
  EXPECT_EQ(image.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(image.at<cv::Vec3b>(0, 1), cv::Vec3b(100, 100, 100));
  EXPECT_EQ(image.at<cv::Vec3b>(0, 2), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(image.at<cv::Vec3b>(1, 1), cv::Vec3b(7, 7, 7));
  EXPECT_EQ(cv::countNonZero((*ground)->mask()), 6);  // no alpha: all data, even black
}

// ---- GeoTIFF ----

struct GeoTiff {
  std::vector<cv::Mat> bands;  // CV_8UC1, in file order
  std::optional<std::array<double, 6>> geotransform;
  int epsg = 0;  // 0 = no coordinate system
  std::optional<double> nodata;
  bool last_band_alpha = false;
};

void WriteGeoTiff(const fs::path& path, const GeoTiff& tiff) {
  GDALAllRegister();
  GDALDriverH driver = GDALGetDriverByName("GTiff");
  ASSERT_NE(driver, nullptr);
  std::vector<const char*> options;
  if (tiff.bands.size() >= 3) options.push_back("PHOTOMETRIC=RGB");
  if (tiff.last_band_alpha) options.push_back("ALPHA=YES");
  options.push_back(nullptr);
  const cv::Size size = tiff.bands[0].size();
  GDALDatasetH dataset =
      GDALCreate(driver, path.c_str(), size.width, size.height, static_cast<int>(tiff.bands.size()),
                 GDT_Byte, const_cast<char**>(options.data()));
  ASSERT_NE(dataset, nullptr) << CPLGetLastErrorMsg();
  for (size_t i = 0; i < tiff.bands.size(); ++i) {
    GDALRasterBandH band = GDALGetRasterBand(dataset, static_cast<int>(i) + 1);
    cv::Mat pixels = tiff.bands[i].clone();
    ASSERT_EQ(GDALRasterIO(band, GF_Write, 0, 0, size.width, size.height, pixels.data, size.width,
                           size.height, GDT_Byte, 0, 0),
              CE_None);
    if (tiff.nodata) GDALSetRasterNoDataValue(band, *tiff.nodata);
  }
  if (tiff.geotransform) {
    std::array<double, 6> gt = *tiff.geotransform;
    GDALSetGeoTransform(dataset, gt.data());
  }
  if (tiff.epsg != 0) {
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    ASSERT_EQ(OSRImportFromEPSG(srs, tiff.epsg), OGRERR_NONE);
    GDALSetSpatialRef(dataset, srs);
    OSRDestroySpatialReference(srs);
  }
  GDALClose(dataset);
}

// Three 8 x 6 colour bands (R, G, B in file order) holding Colour(x, y) where x < 6, y < 4.
std::vector<cv::Mat> RgbBands() {
  std::vector<cv::Mat> bands(3);
  for (cv::Mat& band : bands) band = cv::Mat(6, 8, CV_8UC1);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) {
      const cv::Vec3b c = Colour(x % 6, y % 4);
      bands[0].at<uint8_t>(y, x) = c[2];
      bands[1].at<uint8_t>(y, x) = c[1];
      bands[2].at<uint8_t>(y, x) = c[0];
    }
  }
  return bands;
}

TEST(GroundImageTest, GeoTiffGivesItsGsdAndNodata) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  GeoTiff tiff;
  tiff.bands = RgbBands();
  tiff.geotransform = {{500000, 0.25, 0, 4000000, 0, -0.25}};
  tiff.epsg = 32617;  // UTM 17N, metres
  tiff.nodata = 0;
  // Pixel (1, 1) is nodata in every band; pixel (2, 1) only in red, which is a colour, not a hole.
  for (cv::Mat& band : tiff.bands) band.at<uint8_t>(1, 1) = 0;
  tiff.bands[0].at<uint8_t>(1, 2) = 0;
  const fs::path path = dir / "ortho.tif";
  WriteGeoTiff(path, tiff);

  auto ground = Load(path, 0);
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  EXPECT_DOUBLE_EQ((*ground)->gsd_m(), 0.25);
  const cv::Mat& image = (*ground)->image();
  ASSERT_EQ(image.size(), cv::Size(8, 6));
  EXPECT_EQ(image.at<cv::Vec3b>(3, 4), Colour(4, 3));  // bands reordered to BGR
  EXPECT_EQ((*ground)->mask().at<uint8_t>(1, 1), 0);
  EXPECT_EQ((*ground)->mask().at<uint8_t>(1, 2), 255);
  EXPECT_EQ(image.at<cv::Vec3b>(1, 2), cv::Vec3b(Colour(2, 1)[0], Colour(2, 1)[1], 0));
  EXPECT_EQ(cv::countNonZero((*ground)->mask()), 47);
  // The geotransform origin is not used: the image is centred on centre_m.
  EXPECT_EQ((*ground)->raster_offset(), cv::Point(-4, -3));  // round(-3.5), round(-2.5)

  // A GSD given by the user wins.
  ground = Load(path, 0.3);
  ASSERT_TRUE(ground.ok());
  EXPECT_DOUBLE_EQ((*ground)->gsd_m(), 0.3);
}

TEST(GroundImageTest, GeoTiffAlphaBandAndFeet) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  GeoTiff tiff;
  tiff.bands = RgbBands();
  tiff.bands.push_back(cv::Mat(6, 8, CV_8UC1, cv::Scalar(255)));
  tiff.bands[3].col(7).setTo(0);
  tiff.last_band_alpha = true;
  tiff.geotransform = {{1000, 2, 0, 2000, 0, -2}};
  tiff.epsg = 2236;  // NAD83 / Florida East, US survey feet
  const fs::path path = dir / "alpha.tiff";
  WriteGeoTiff(path, tiff);
  auto ground = Load(path, 0);
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  EXPECT_NEAR((*ground)->gsd_m(), 2 * 1200.0 / 3937.0, 1e-9);
  EXPECT_EQ(cv::countNonZero((*ground)->mask()), 42);
  EXPECT_EQ((*ground)->mask().at<uint8_t>(3, 7), 0);
  EXPECT_EQ((*ground)->image().at<cv::Vec3b>(3, 7), cv::Vec3b(0, 0, 0));
  EXPECT_EQ((*ground)->image().at<cv::Vec3b>(3, 6), Colour(0, 3));
}

TEST(GroundImageTest, GeoTiffWithoutAUsableGeotransformNeedsTheGsd) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  struct Case {
    const char* name;
    std::optional<std::array<double, 6>> geotransform;
    int epsg;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"plain.tif", std::nullopt, 0, "no geotransform"},
      {"rotated.tif", std::array<double, 6>{0, 0.3, 0.1, 0, 0.1, -0.3}, 32617, "not north up"},
      {"oblong.tif", std::array<double, 6>{0, 0.3, 0, 0, 0, -0.5}, 32617, "not square"},
      {"degrees.tif", std::array<double, 6>{8, 1e-5, 0, 47, 0, -1e-5}, 4326, "geographic"},
  };
  for (const Case& c : cases) {
    GeoTiff tiff;
    tiff.bands = {cv::Mat(4, 4, CV_8UC1, cv::Scalar(50))};
    tiff.geotransform = c.geotransform;
    tiff.epsg = c.epsg;
    const fs::path path = dir / c.name;
    WriteGeoTiff(path, tiff);
    auto ground = Load(path, 0);
    ASSERT_FALSE(ground.ok()) << c.name;
    EXPECT_EQ(ground.status().code(), StatusCode::kInvalidArgument);
    EXPECT_TRUE(Contains(ground.status().message(), c.name)) << ground.status().message();
    EXPECT_TRUE(Contains(ground.status().message(), c.reason)) << ground.status().message();
    EXPECT_TRUE(Contains(ground.status().message(), "--gsd")) << ground.status().message();
    ground = Load(path, 0.5);
    ASSERT_TRUE(ground.ok()) << c.name << ": " << ground.status().ToString();
    EXPECT_EQ((*ground)->image().at<cv::Vec3b>(0, 0), cv::Vec3b(50, 50, 50));  // grey to BGR
  }
}

// ---- errors ----

TEST(GroundImageTest, ErrorsNameTheFile) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  auto ground = Load(dir / "missing.png", 0.2);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kNotFound);
  EXPECT_TRUE(Contains(ground.status().message(), "missing.png")) << ground.status().message();

  const fs::path corrupt = dir / "corrupt.png";
  std::ofstream(corrupt, std::ios::binary) << "\x89PNG\r\n\x1a\n this is not a PNG at all";
  ground = Load(corrupt, 0.2);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kInvalidData);
  EXPECT_TRUE(Contains(ground.status().message(), "corrupt.png")) << ground.status().message();

  const fs::path empty = dir / "empty.jpg";
  std::ofstream(empty, std::ios::binary).flush();
  ground = Load(empty, 0.2);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kInvalidData);

  const fs::path tif = dir / "corrupt.tif";
  std::ofstream(tif, std::ios::binary) << "II* garbage garbage garbage";
  ground = Load(tif, 0.2);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kInvalidData);
  EXPECT_TRUE(Contains(ground.status().message(), "corrupt.tif")) << ground.status().message();

  const fs::path png = WriteAlphaPng(dir);
  ground = Load(png, 0);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(ground.status().message(), "alpha.png")) << ground.status().message();
  EXPECT_TRUE(Contains(ground.status().message(), "--gsd")) << ground.status().message();

  ground = Load(dir, 0.2);  // a directory
  ASSERT_FALSE(ground.ok());
  EXPECT_TRUE(Contains(ground.status().message(), "not a regular file"));
}

TEST(GroundImageTest, RejectsImagesBeyondTheSizeLimit) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  const fs::path path = dir / "wide.png";
  // One row compresses to a few hundred bytes; the limit applies per side.
  ASSERT_TRUE(
      cv::imwrite(path.string(), cv::Mat(1, kMaxGroundImageSide + 1, CV_8UC1, cv::Scalar(3))));
  auto ground = Load(path, 0.2);
  ASSERT_FALSE(ground.ok());
  EXPECT_EQ(ground.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(Contains(ground.status().message(), "20001x1")) << ground.status().message();
  EXPECT_TRUE(Contains(ground.status().message(), "wide.png")) << ground.status().message();
}

// ---- the real orthophoto ----

TEST(GroundImageTest, EdgeFillColourIsNoData) {
  const fs::path dir = testing::MakeTempDir("ground_image");
  // White surround with a green 3 x 3 middle that has a white pixel inside (a white roof).
  cv::Mat bgr(5, 6, CV_8UC3, cv::Scalar(255, 255, 255));
  bgr(cv::Rect(1, 1, 3, 3)).setTo(cv::Scalar(40, 160, 60));
  bgr.at<cv::Vec3b>(2, 2) = cv::Vec3b(255, 255, 255);
  const fs::path path = dir / "filled.png";
  ASSERT_TRUE(cv::imwrite(path.string(), bgr));
  GroundImageOptions options;
  options.path = path;
  options.gsd_m = 1;
  auto ground = GroundImage::Load(options);
  ASSERT_TRUE(ground.ok());
  EXPECT_EQ(cv::countNonZero((*ground)->mask()), 30);  // without the option, white is ground
  options.nodata_fill_bgr = cv::Vec3b(255, 255, 255);
  ground = GroundImage::Load(options);
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  const cv::Mat& mask = (*ground)->mask();
  EXPECT_EQ(cv::countNonZero(mask), 9);
  EXPECT_EQ(mask.at<uint8_t>(2, 2), 255);
  EXPECT_EQ(mask.at<uint8_t>(0, 5), 0);
  EXPECT_EQ((*ground)->image().at<cv::Vec3b>(2, 2), cv::Vec3b(255, 255, 255));
  EXPECT_EQ((*ground)->image().at<cv::Vec3b>(4, 4), cv::Vec3b(0, 0, 0));
}

TEST(GroundImageTest, AukermanOrthophotoHasNoDataBordersAndTexture) {
  SAKER_REQUIRE_TEST_DATA(path, "imagery/odm_aukerman_orthomosaic.png");
  // This copy of the mosaic is RGBA but fully opaque: outside its footprint it is filled with
  // opaque white, so the fill colour marks the no-data border (alpha 0 would too, if present).
  GroundImageOptions options;
  options.path = path;
  options.gsd_m = 0.1;
  options.nodata_fill_bgr = cv::Vec3b(255, 255, 255);
  auto ground = GroundImage::Load(options);
  ASSERT_TRUE(ground.ok()) << ground.status().ToString();
  const GroundImage& image = **ground;
  ASSERT_EQ(image.image().size(), cv::Size(1053, 810));
  const cv::Mat& mask = image.mask();
  // The corners are outside the mosaic's footprint; the middle is inside.
  EXPECT_EQ(mask.at<uint8_t>(0, 0), 0);
  EXPECT_EQ(mask.at<uint8_t>(809, 1052), 0);
  EXPECT_EQ(mask.at<uint8_t>(0, 1052), 0);
  const double valid_fraction = cv::countNonZero(mask) / static_cast<double>(mask.total());
  EXPECT_GT(valid_fraction, 0.6);
  EXPECT_LT(valid_fraction, 0.8);

  // Render 100 x 100 raster pixels around the centre: all data, with texture.
  cv::Mat bgr, valid;
  image.Render(cv::Rect(-50, -50, 100, 100), &bgr, &valid);
  EXPECT_EQ(cv::countNonZero(valid), 100 * 100);
  cv::Scalar mean, stddev;
  cv::meanStdDev(bgr, mean, stddev);
  EXPECT_GT(stddev[1], 8.0) << "the middle of the orthophoto should not be flat";

  // A region over the north-west corner: outside the image and in its fill border alike are
  // invalid and black.
  const cv::Point offset = image.raster_offset();
  image.Render(cv::Rect(offset.x - 20, offset.y - 20, 60, 60), &bgr, &valid);
  EXPECT_EQ(cv::countNonZero(valid(cv::Rect(0, 0, 20, 60))), 0);
  EXPECT_EQ(valid.at<uint8_t>(20, 20), 0);
  cv::Mat colour_where_invalid;
  bgr.copyTo(colour_where_invalid, valid == 0);
  EXPECT_EQ(cv::countNonZero(colour_where_invalid.reshape(1)), 0);
}

}  // namespace
}  // namespace saker::sim
