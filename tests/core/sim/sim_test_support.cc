#include "tests/core/sim/sim_test_support.h"

#include "core/video/video_reader.h"
#include "tests/core/video/read_all.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <fstream>
#include <sstream>

namespace saker::sim {

SimulationOptions SmallOptions(const std::filesystem::path& output) {
  SimulationOptions options;
  options.output = output;
  options.camera.width = 320;
  options.camera.height = 180;
  options.flight.altitude_m = 100;
  options.fps = 10;
  options.duration_s = 2;
  options.crf = 18;
  return options;
}

namespace {

// Every frame of the video (with BGR images when `want_bgr`).
video::Pass ReadVideo(const std::filesystem::path& path, bool want_bgr) {
  video::ReaderOptions options;
  options.want_bgr = want_bgr;
  video::Pass pass;
  auto reader = video::VideoReader::Open(path.string(), options);
  EXPECT_TRUE(reader.ok()) << reader.status().ToString();
  if (!reader.ok()) return pass;
  const Status status = video::ReadAll(reader->get(), &pass);
  EXPECT_TRUE(status.ok()) << status.ToString();
  return pass;
}

}  // namespace

std::vector<double> DecodeTimes(const std::filesystem::path& path) {
  std::vector<double> times;
  for (const video::Frame& frame : ReadVideo(path, false).frames) times.push_back(frame.time_s);
  return times;
}

std::vector<cv::Mat> DecodeAll(const std::filesystem::path& path) {
  std::vector<cv::Mat> frames;
  for (const video::Frame& frame : ReadVideo(path, true).frames) frames.push_back(frame.bgr);
  return frames;
}

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

cv::Mat ToCv(const Eigen::Matrix3d& h) {
  cv::Mat m(3, 3, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.at<double>(r, c) = h(r, c);
  }
  return m;
}

double Ncc(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  cv::Mat ga, gb;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  ga.convertTo(ga, CV_64F);
  gb.convertTo(gb, CV_64F);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(ga, ma, sa, mask);
  cv::meanStdDev(gb, mb, sb, mask);
  cv::Mat product = (ga - ma[0]).mul(gb - mb[0]);
  return cv::mean(product, mask)[0] / (sa[0] * sb[0]);
}

double GroundCorrelation(const SimulationSetup& setup, const Truth& truth, int64_t frame,
                         const cv::Mat& decoded, const Eigen::Matrix3d& frame_from_ground) {
  const GroundSource& ground = setup.ground();
  const Eigen::Matrix3d raster_from_frame =
      RasterFromGround(ground.gsd_m()) * frame_from_ground.inverse();
  std::vector<cv::Point2f> corners;
  for (const Eigen::Vector2d& c : ImageCorners(setup.options().camera)) {
    const Eigen::Vector2d p = (raster_from_frame * c.homogeneous()).hnormalized();
    corners.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
  const cv::Rect region = cv::boundingRect(corners);
  cv::Mat rendered, valid;
  ground.Render(region, &rendered, &valid);
  Eigen::Matrix3d region_from_raster = Eigen::Matrix3d::Identity();
  region_from_raster(0, 2) = -region.x;
  region_from_raster(1, 2) = -region.y;
  cv::Mat warped, seen;
  const cv::Mat h = ToCv(region_from_raster * raster_from_frame);
  cv::warpPerspective(decoded, warped, h, region.size(), cv::INTER_LINEAR);
  cv::warpPerspective(cv::Mat(decoded.size(), CV_8U, cv::Scalar(255)), seen, h, region.size(),
                      cv::INTER_NEAREST);
  cv::erode(seen, seen, cv::Mat(), cv::Point(-1, -1), 2);
  cv::Mat mask = valid & seen;
  // Targets (and their shadows) are in the frame but not in the ground render.
  for (const TargetTruth& t : truth.targets) {
    const Eigen::Vector2d p = (RasterFromGround(ground.gsd_m()) *
                               t.samples[static_cast<size_t>(frame)].ground_m.homogeneous())
                                  .hnormalized();
    cv::circle(mask,
               cv::Point(static_cast<int>(p.x()) - region.x, static_cast<int>(p.y()) - region.y),
               static_cast<int>(6.0 / ground.gsd_m()), cv::Scalar(0), cv::FILLED);
  }
  EXPECT_GT(cv::countNonZero(mask), mask.total() / 3);
  return Ncc(warped, rendered, mask);
}

}  // namespace saker::sim
