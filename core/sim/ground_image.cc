#include "core/sim/ground_image.h"

#include "core/util/check.h"

#include <cpl_error.h>
#include <gdal.h>
#include <ogr_srs_api.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace saker::sim {
namespace {

// What a decoder hands back: the pixels, validity, and the GSD when the file knows it.
struct Decoded {
  cv::Mat bgr;   // CV_8UC3
  cv::Mat mask;  // CV_8UC1, 255 = data
  std::optional<double> gsd_m;
  std::string no_gsd_reason;  // why gsd_m is empty, for the error message
};

std::string Name(const std::filesystem::path& path) { return "ground image " + path.string(); }

std::string LowerExtension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

Status CheckSize(const std::filesystem::path& path, long long width, long long height) {
  if (width <= 0 || height <= 0) {
    return InvalidDataError(Name(path) + ": the image is empty (0 pixels)");
  }
  if (width > kMaxGroundImageSide || height > kMaxGroundImageSide) {
    std::ostringstream message;
    message << Name(path) << ": " << width << "x" << height << " pixels is larger than the "
            << kMaxGroundImageSide << "x" << kMaxGroundImageSide
            << " limit; crop or downsample it (and scale the GSD)";
    return InvalidArgumentError(message.str());
  }
  return Status::Ok();
}

// 16-bit to 8-bit by 1/257, so 65535 maps to 255.
cv::Mat To8Bit(const cv::Mat& channel) {
  if (channel.depth() == CV_8U) return channel;
  cv::Mat converted;
  channel.convertTo(converted, CV_8U, 1.0 / 257.0);
  return converted;
}

// Marks pixels of `fill` connected to the image edge as no data. Flood fill from every edge pixel
// of that colour, in place on an 8-bit map (255 = fill colour, 128 = reached from the edge), so a
// 20000 x 20000 image needs no label image.
void MaskEdgeFill(const cv::Vec3b& fill, Decoded* decoded) {
  cv::Mat same;
  cv::inRange(decoded->bgr, cv::Scalar(fill[0], fill[1], fill[2]),
              cv::Scalar(fill[0], fill[1], fill[2]), same);
  auto flood_from = [&same](int x, int y) {
    if (same.at<uint8_t>(y, x) == 255) {
      cv::floodFill(same, cv::Point(x, y), cv::Scalar(128), nullptr, cv::Scalar(), cv::Scalar(), 4);
    }
  };
  for (int x = 0; x < same.cols; ++x) {
    flood_from(x, 0);
    flood_from(x, same.rows - 1);
  }
  for (int y = 0; y < same.rows; ++y) {
    flood_from(0, y);
    flood_from(same.cols - 1, y);
  }
  decoded->mask.setTo(cv::Scalar(0), same == 128);
}

// Black wherever there is no data, as GroundSource::Render promises.
void BlackenInvalid(Decoded* decoded) {
  cv::Mat invalid;
  cv::bitwise_not(decoded->mask, invalid);
  decoded->bgr.setTo(cv::Scalar::all(0), invalid);
}

// ---- GDAL (GeoTIFF, and the size probe) ----

void RegisterGdalDrivers() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// Keeps GDAL's messages off stderr while it runs: failures are reported through Status, with
// GDAL's last message quoted.
class QuietGdalErrors {
 public:
  QuietGdalErrors() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdalErrors() { CPLPopErrorHandler(); }
  QuietGdalErrors(const QuietGdalErrors&) = delete;
  QuietGdalErrors& operator=(const QuietGdalErrors&) = delete;
};

std::string GdalMessage() {
  const char* message = CPLGetLastErrorMsg();
  return message != nullptr && *message != '\0' ? std::string(" (GDAL: ") + message + ")" : "";
}

struct GdalCloser {
  void operator()(void* dataset) const { GDALClose(dataset); }
};
using GdalDataset = std::unique_ptr<void, GdalCloser>;

GdalDataset OpenWithGdal(const std::filesystem::path& path) {
  RegisterGdalDrivers();
  return GdalDataset(
      GDALOpenEx(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY, nullptr, nullptr, nullptr));
}

// The GSD of a north-up geotransform with square pixels in a metric (or unknown) unit; otherwise
// nullopt and the reason.
std::optional<double> GsdFromGeotransform(GDALDatasetH dataset, std::string* reason) {
  std::array<double, 6> gt{};
  if (GDALGetGeoTransform(dataset, gt.data()) != CE_None) {
    *reason = "it has no geotransform";
    return std::nullopt;
  }
  if (gt[2] != 0.0 || gt[4] != 0.0 || !(gt[1] > 0.0) || !(gt[5] < 0.0)) {
    std::ostringstream text;
    text << "its geotransform is not north up (pixel axes " << gt[1] << ", " << gt[2] << " / "
         << gt[4] << ", " << gt[5] << ")";
    *reason = text.str();
    return std::nullopt;
  }
  if (std::abs(gt[1] + gt[5]) > 1e-4 * gt[1]) {
    std::ostringstream text;
    text << "its pixels are not square (" << gt[1] << " x " << -gt[5] << ")";
    *reason = text.str();
    return std::nullopt;
  }
  double metres_per_unit = 1.0;  // no coordinate system: take the geotransform as metres
  if (OGRSpatialReferenceH srs = GDALGetSpatialRef(dataset); srs != nullptr) {
    if (OSRIsGeographic(srs)) {
      *reason = "its coordinate system is geographic (pixel size in degrees, not metres)";
      return std::nullopt;
    }
    metres_per_unit = OSRGetLinearUnits(srs, nullptr);
  }
  return gt[1] * metres_per_unit;
}

// The colour bands to read, in B, G, R order or one grey band: by their declared role, else by
// position. `*alpha` receives the first band declared alpha (alpha only when declared), or null.
StatusOr<std::vector<GDALRasterBandH>> ColourBands(const std::filesystem::path& path,
                                                   GDALDatasetH dataset, GDALRasterBandH* alpha) {
  const int band_count = GDALGetRasterCount(dataset);
  GDALRasterBandH red = nullptr, green = nullptr, blue = nullptr;
  *alpha = nullptr;
  for (int i = 1; i <= band_count; ++i) {
    GDALRasterBandH band = GDALGetRasterBand(dataset, i);
    switch (GDALGetRasterColorInterpretation(band)) {
      case GCI_RedBand:
        red = band;
        break;
      case GCI_GreenBand:
        green = band;
        break;
      case GCI_BlueBand:
        blue = band;
        break;
      case GCI_AlphaBand:
        if (*alpha == nullptr) *alpha = band;
        break;
      case GCI_PaletteIndex:
        return UnsupportedError(Name(path) +
                                ": palette images are not supported; expand them to RGB first "
                                "(gdal_translate -expand rgb)");
      default:
        break;
    }
  }
  if (red != nullptr && green != nullptr && blue != nullptr) {
    return std::vector<GDALRasterBandH>{blue, green, red};
  }
  if (band_count - (*alpha != nullptr ? 1 : 0) >= 3) {
    return std::vector<GDALRasterBandH>{GDALGetRasterBand(dataset, 3),
                                        GDALGetRasterBand(dataset, 2),
                                        GDALGetRasterBand(dataset, 1)};
  }
  GDALRasterBandH grey = GDALGetRasterBand(dataset, 1) == *alpha ? GDALGetRasterBand(dataset, 2)
                                                                 : GDALGetRasterBand(dataset, 1);
  if (grey == nullptr) return InvalidDataError(Name(path) + ": only an alpha band");
  return std::vector<GDALRasterBandH>{grey};
}

// The pixel type of `bands` (the first band's), which all must share: 8- or 16-bit unsigned.
StatusOr<GDALDataType> SharedBandType(const std::filesystem::path& path,
                                      const std::vector<GDALRasterBandH>& bands) {
  const GDALDataType type = GDALGetRasterDataType(bands[0]);
  for (GDALRasterBandH band : bands) {
    const GDALDataType band_type = GDALGetRasterDataType(band);
    if (band_type != type || (type != GDT_Byte && type != GDT_UInt16)) {
      return UnsupportedError(Name(path) + ": pixel type " + GDALGetDataTypeName(band_type) +
                              " is not supported (8- or 16-bit unsigned bands only; convert "
                              "with gdal_translate -ot Byte -scale)");
    }
  }
  return type;
}

// The whole of `band`, read as `as` into a matrix of `mat_type`.
StatusOr<cv::Mat> ReadBand(const std::filesystem::path& path, GDALRasterBandH band, GDALDataType as,
                           int mat_type, cv::Size size) {
  cv::Mat pixels(size, mat_type);
  if (GDALRasterIO(band, GF_Read, 0, 0, size.width, size.height, pixels.data, size.width,
                   size.height, as, 0, 0) != CE_None) {
    return InvalidDataError(Name(path) + ": reading the pixels failed" + GdalMessage());
  }
  return pixels;
}

// Validity without an alpha band, from nodata: a pixel is missing when every colour band that
// declares a nodata value holds it (one band at 0 is just a dark colour). Without nodata, from
// GDAL's mask band when it has one (an internal or .msk mask); else every pixel is data.
StatusOr<cv::Mat> MaskWithoutAlpha(const std::filesystem::path& path,
                                   const std::vector<GDALRasterBandH>& colour,
                                   const std::vector<cv::Mat>& channels, GDALDataType type) {
  const cv::Size size = channels[0].size();
  cv::Mat mask(size, CV_8UC1, cv::Scalar(255));
  bool any_nodata = false;
  for (size_t i = 0; i < colour.size(); ++i) {
    int has_nodata = 0;
    const double nodata = GDALGetRasterNoDataValue(colour[i], &has_nodata);
    if (!has_nodata) continue;
    cv::Mat equal;
    if (nodata >= 0 && nodata <= (type == GDT_Byte ? 255 : 65535) && nodata == std::floor(nodata)) {
      equal = channels[i] == nodata;
    } else {
      equal = cv::Mat::zeros(size, CV_8UC1);  // a value the band cannot hold
    }
    mask = any_nodata ? (mask | ~equal) : ~equal;
    any_nodata = true;
  }
  if (!any_nodata && GDALGetMaskFlags(colour[0]) == GMF_PER_DATASET) {
    SAKER_ASSIGN_OR_RETURN(const cv::Mat pixels,
                           ReadBand(path, GDALGetMaskBand(colour[0]), GDT_Byte, CV_8UC1, size));
    mask = pixels > 0;
  }
  return mask;
}

// 8-bit BGR from one grey channel or B, G, R channels, each of 8 or 16 bits.
cv::Mat ToBgr(std::vector<cv::Mat> channels) {
  for (cv::Mat& channel : channels) channel = To8Bit(channel);
  cv::Mat bgr;
  if (channels.size() == 1) {
    cv::cvtColor(channels[0], bgr, cv::COLOR_GRAY2BGR);
  } else {
    cv::merge(channels, bgr);
  }
  return bgr;
}

StatusOr<Decoded> DecodeWithGdal(const std::filesystem::path& path) {
  QuietGdalErrors quiet;
  GdalDataset owner = OpenWithGdal(path);
  if (!owner) {
    return InvalidDataError(Name(path) + ": not a readable TIFF / GeoTIFF" + GdalMessage());
  }
  GDALDatasetH dataset = owner.get();
  const int width = GDALGetRasterXSize(dataset);
  const int height = GDALGetRasterYSize(dataset);
  SAKER_RETURN_IF_ERROR(CheckSize(path, width, height));
  if (GDALGetRasterCount(dataset) < 1) return InvalidDataError(Name(path) + ": no raster bands");

  GDALRasterBandH alpha = nullptr;
  SAKER_ASSIGN_OR_RETURN(const std::vector<GDALRasterBandH> colour,
                         ColourBands(path, dataset, &alpha));
  std::vector<GDALRasterBandH> used = colour;
  if (alpha != nullptr) used.push_back(alpha);
  SAKER_ASSIGN_OR_RETURN(const GDALDataType type, SharedBandType(path, used));
  const int cv_type = type == GDT_Byte ? CV_8UC1 : CV_16UC1;
  const cv::Size size(width, height);

  std::vector<cv::Mat> channels;
  for (GDALRasterBandH band : colour) {
    SAKER_ASSIGN_OR_RETURN(cv::Mat pixels, ReadBand(path, band, type, cv_type, size));
    channels.push_back(std::move(pixels));
  }
  Decoded decoded;
  if (alpha != nullptr) {
    SAKER_ASSIGN_OR_RETURN(const cv::Mat pixels, ReadBand(path, alpha, type, cv_type, size));
    // Validity from the full-depth alpha: a 16-bit alpha of 100 is still data.
    decoded.mask = pixels > 0;
  } else {
    SAKER_ASSIGN_OR_RETURN(decoded.mask, MaskWithoutAlpha(path, colour, channels, type));
  }
  decoded.bgr = ToBgr(std::move(channels));
  decoded.gsd_m = GsdFromGeotransform(dataset, &decoded.no_gsd_reason);
  return decoded;
}

// ---- OpenCV (PNG, JPEG, ...) ----

StatusOr<Decoded> DecodeWithOpenCv(const std::filesystem::path& path) {
  // Check the size before decoding, so a huge file fails fast instead of allocating gigabytes.
  // GDAL reads PNG and JPEG headers; if it cannot, OpenCV's own decoder decides.
  {
    QuietGdalErrors quiet;
    if (GdalDataset probe = OpenWithGdal(path)) {
      SAKER_RETURN_IF_ERROR(
          CheckSize(path, GDALGetRasterXSize(probe.get()), GDALGetRasterYSize(probe.get())));
    }
  }
  cv::Mat pixels;
  try {
    pixels = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return InvalidDataError(Name(path) + ": cannot be decoded (" + e.what() + ")");
  }
  if (pixels.empty()) {
    return InvalidDataError(Name(path) + ": not a readable image (corrupt, truncated, or a " +
                            "format OpenCV does not read)");
  }
  SAKER_RETURN_IF_ERROR(CheckSize(path, pixels.cols, pixels.rows));
  if (pixels.depth() != CV_8U && pixels.depth() != CV_16U) {
    return UnsupportedError(Name(path) +
                            ": pixel type is not supported (8- or 16-bit images only)");
  }

  Decoded decoded;
  std::vector<cv::Mat> channels;
  cv::split(pixels, channels);
  decoded.mask = cv::Mat(pixels.rows, pixels.cols, CV_8UC1, cv::Scalar(255));
  if (channels.size() == 2 || channels.size() == 4) {
    decoded.mask = channels.back() > 0;  // alpha 0 = no data, at full depth
    channels.pop_back();
  }
  decoded.bgr = ToBgr(std::move(channels));
  decoded.no_gsd_reason = "PNG and JPEG files carry no ground sample distance";
  return decoded;
}

}  // namespace

Status GroundImageOptions::Validate() const {
  if (path.empty()) return InvalidArgumentError("ground image: no file given");
  if (!(gsd_m == 0.0 || (gsd_m >= 1e-3 && gsd_m <= 1000.0))) {
    std::ostringstream message;
    message << Name(path) << ": gsd " << gsd_m
            << " m is outside [0.001, 1000] m per pixel (or 0 to read it from a GeoTIFF)";
    return InvalidArgumentError(message.str());
  }
  if (!centre_m.allFinite()) return InvalidArgumentError(Name(path) + ": centre is not finite");
  return Status::Ok();
}

GroundImage::GroundImage(cv::Mat image, cv::Mat mask, double gsd_m, cv::Point raster_offset)
    : image_(std::move(image)),
      mask_(std::move(mask)),
      gsd_m_(gsd_m),
      raster_offset_(raster_offset) {}

StatusOr<std::unique_ptr<GroundImage>> GroundImage::Load(const GroundImageOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const std::filesystem::path& path = options.path;
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (!std::filesystem::exists(status)) return NotFoundError(Name(path) + ": file not found");
  if (!std::filesystem::is_regular_file(status)) {
    return InvalidArgumentError(Name(path) + ": not a regular file");
  }

  const std::string extension = LowerExtension(path);
  const bool tiff = extension == ".tif" || extension == ".tiff";
  // PNG and JPEG cannot supply a GSD: say so before spending time decoding.
  if (!tiff && options.gsd_m == 0.0) {
    return InvalidArgumentError(Name(path) +
                                ": no ground sample distance: PNG and JPEG files carry none, so "
                                "give it (metres per pixel, --gsd)");
  }
  StatusOr<Decoded> decoded = tiff ? DecodeWithGdal(path) : DecodeWithOpenCv(path);
  if (!decoded.ok()) return decoded.status();

  double gsd = options.gsd_m;
  if (gsd == 0.0) {
    if (!decoded->gsd_m) {
      return InvalidArgumentError(Name(path) + ": no ground sample distance: " +
                                  decoded->no_gsd_reason + "; give it (metres per pixel, --gsd)");
    }
    gsd = *decoded->gsd_m;
    if (!(gsd >= 1e-3 && gsd <= 1000.0)) {
      std::ostringstream message;
      message << Name(path) << ": the geotransform gives " << gsd
              << " m per pixel, outside [0.001, 1000]; give the GSD (--gsd)";
      return InvalidArgumentError(message.str());
    }
  }

  // Raster pixel of image pixel (0, 0): see the placement rule in the header.
  const double u = options.centre_m.x() / gsd - 0.5 * (decoded->bgr.cols - 1);
  const double v = -options.centre_m.y() / gsd - 0.5 * (decoded->bgr.rows - 1);
  constexpr double kMaxOffset = 1e9;  // keeps offset + size within int
  if (std::abs(u) > kMaxOffset || std::abs(v) > kMaxOffset) {
    return InvalidArgumentError(Name(path) + ": centre is too far from the world origin");
  }
  const cv::Point offset(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
  if (options.nodata_fill_bgr) MaskEdgeFill(*options.nodata_fill_bgr, &decoded.value());
  BlackenInvalid(&decoded.value());
  return std::unique_ptr<GroundImage>(
      new GroundImage(std::move(decoded->bgr), std::move(decoded->mask), gsd, offset));
}

cv::Rect2d GroundImage::extent_m() const {
  const double west = (raster_offset_.x - 0.5) * gsd_m_;
  const double south = -(raster_offset_.y + image_.rows - 0.5) * gsd_m_;
  return cv::Rect2d(west, south, image_.cols * gsd_m_, image_.rows * gsd_m_);
}

void GroundImage::Render(const cv::Rect& region, cv::Mat* bgr, cv::Mat* valid) const {
  SAKER_CHECK(bgr != nullptr && valid != nullptr && bgr != valid);
  SAKER_CHECK(region.width >= 0 && region.height >= 0) << "negative render region size";
  bgr->create(region.size(), CV_8UC3);
  valid->create(region.size(), CV_8UC1);
  bgr->setTo(cv::Scalar::all(0));
  valid->setTo(cv::Scalar::all(0));
  const cv::Rect covered = region & cv::Rect(raster_offset_, image_.size());
  if (covered.empty()) return;
  const cv::Rect source = covered - raster_offset_;
  const cv::Rect target = covered - region.tl();
  image_(source).copyTo((*bgr)(target));
  mask_(source).copyTo((*valid)(target));
}

}  // namespace saker::sim
