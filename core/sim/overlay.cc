#include "core/sim/overlay.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace saker::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// The box of pixels a text line drawn at `origin` can touch, outline included.
cv::Rect TextBox(const std::string& text, cv::Point origin, double scale, int thickness) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, kFont, scale, thickness + 2, &baseline);
  const int pad = thickness + 3;
  return cv::Rect(origin.x - pad, origin.y - size.height - pad, size.width + 2 * pad,
                  size.height + baseline + 2 * pad);
}

// Draws white text with a black outline (how ground stations key telemetry) into the overlay
// layer and its coverage.
void DrawOutlinedText(const std::string& text, cv::Point origin, double scale, int thickness,
                      cv::Mat* layer, cv::Mat* alpha) {
  cv::putText(*layer, text, origin, kFont, scale, cv::Scalar::all(0), thickness + 2, cv::LINE_AA);
  cv::putText(*alpha, text, origin, kFont, scale, cv::Scalar(255), thickness + 2, cv::LINE_AA);
  cv::putText(*layer, text, origin, kFont, scale, cv::Scalar::all(255), thickness, cv::LINE_AA);
}

OverlayTruth ToTruth(const char* kind, const cv::Rect& box, int width, int height) {
  const cv::Rect clipped = box & cv::Rect(0, 0, width, height);
  return {kind, clipped.x, clipped.y, clipped.width, clipped.height};
}

}  // namespace

const char* LogoMotionName(LogoMotion motion) {
  switch (motion) {
    case LogoMotion::kNone:
      return "none";
    case LogoMotion::kStatic:
      return "static";
    case LogoMotion::kRotating:
      return "rotating";
    case LogoMotion::kPulsing:
      return "pulsing";
  }
  return "none";
}

std::optional<LogoMotion> ParseLogoMotion(std::string_view name) {
  for (LogoMotion m :
       {LogoMotion::kNone, LogoMotion::kStatic, LogoMotion::kRotating, LogoMotion::kPulsing}) {
    if (name == LogoMotionName(m)) return m;
  }
  return std::nullopt;
}

Status OverlayOptions::Validate() const {
  if (!(opacity > 0 && opacity <= 1)) {
    return InvalidArgumentError("overlay: opacity must be in (0, 1]");
  }
  if (!(std::abs(logo_turn_deg_per_s) <= 3600)) {
    return InvalidArgumentError("overlay: the logo's turn rate must be within 3600 degrees/s");
  }
  if (!(logo_pulse_hz >= 0 && logo_pulse_hz <= 30)) {
    return InvalidArgumentError("overlay: the logo's pulse rate must be in [0, 30] Hz");
  }
  return Status::Ok();
}

OverlayPainter::OverlayPainter(const OverlayOptions& options, int width, int height)
    : options_(options), width_(width), height_(height) {
  // Text about 2.2 % of the image height tall, as on typical FMV HUDs.
  font_scale_ = std::max(0.3, height / 720.0 * 0.55);
  font_thickness_ = height >= 540 ? 2 : 1;
  const int margin = std::max(4, height / 60);
  int baseline = 0;
  const cv::Size text = cv::getTextSize("0", kFont, font_scale_, font_thickness_, &baseline);
  top_line_ = cv::Point(margin, margin + text.height);
  bottom_line_ = cv::Point(margin, height - margin - baseline);
  logo_radius_ = std::max(8, static_cast<int>(std::lround(0.045 * height)));
  logo_centre_ = cv::Point(width - margin - logo_radius_ - 2,
                           top_line_.y + baseline + margin + logo_radius_ + 2);
  reticle_centre_ = cv::Point(width / 2, height / 2);
  reticle_arm_ = std::max(6, static_cast<int>(std::lround(0.05 * height)));
  reticle_gap_ = std::max(2, static_cast<int>(std::lround(0.015 * height)));

  if (options_.hud_text) {
    // The widest the lines get: every number at its widest (the font's digits share one width).
    HudTelemetry widest;
    widest.utc_us = 1790000000000000;
    widest.frame_index = 999999;
    widest.latitude_deg = -88.88888, widest.longitude_deg = -188.88888;
    widest.height_m = 88888, widest.heading_deg = 888.8, widest.hfov_deg = 88.8;
    const auto [top, bottom] = HudLines(widest);
    regions_.push_back(ToTruth("hud-text", TextBox(top, top_line_, font_scale_, font_thickness_),
                               width_, height_));
    regions_.push_back(ToTruth(
        "hud-text", TextBox(bottom, bottom_line_, font_scale_, font_thickness_), width_, height_));
  }
  if (options_.reticle) {
    const int reach = reticle_arm_ + 4;
    regions_.push_back(ToTruth("reticle",
                               cv::Rect(reticle_centre_.x - reach, reticle_centre_.y - reach,
                                        2 * reach + 1, 2 * reach + 1),
                               width_, height_));
  }
  if (options_.logo != LogoMotion::kNone) {
    const int reach = logo_radius_ + 3;
    regions_.push_back(ToTruth(
        "logo",
        cv::Rect(logo_centre_.x - reach, logo_centre_.y - reach, 2 * reach + 1, 2 * reach + 1),
        width_, height_));
  }
}

std::pair<std::string, std::string> OverlayPainter::HudLines(const HudTelemetry& t) const {
  const std::time_t seconds = static_cast<std::time_t>(t.utc_us / 1000000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char top[160], bottom[160];
  std::snprintf(top, sizeof(top), "%04d-%02d-%02d %02d:%02d:%02d.%03dZ  FRM %06lld  HFOV %4.1f",
                utc.tm_year + 1900, utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min,
                utc.tm_sec, static_cast<int>(t.utc_us / 1000 % 1000),
                static_cast<long long>(t.frame_index), t.hfov_deg);
  std::snprintf(bottom, sizeof(bottom), "LAT %9.5f  LON %10.5f  ALT %5.0fm  HDG %5.1f",
                t.latitude_deg, t.longitude_deg, t.height_m, t.heading_deg);
  return {top, bottom};
}

void OverlayPainter::PaintLogo(double time_s, cv::Mat* layer, cv::Mat* alpha) const {
  // A badge: a dark disc with a white ring, and a star with a bar through it that turns when
  // the logo rotates.
  const double angle = options_.logo == LogoMotion::kRotating
                           ? options_.logo_turn_deg_per_s * time_s * kPi / 180.0
                           : 0.0;
  const cv::Point c = logo_centre_;
  const int r = logo_radius_;
  cv::circle(*layer, c, r, cv::Scalar(90, 40, 20), cv::FILLED, cv::LINE_AA);
  cv::circle(*layer, c, r, cv::Scalar(255, 255, 255), std::max(1, r / 10), cv::LINE_AA);
  cv::circle(*alpha, c, r, cv::Scalar(255), cv::FILLED, cv::LINE_AA);
  std::vector<cv::Point> star;
  for (int k = 0; k < 10; ++k) {
    const double a = angle + k * kPi / 5;
    const double radius = (k % 2 == 0 ? 0.75 : 0.32) * r;
    star.emplace_back(c.x + static_cast<int>(std::lround(radius * std::sin(a))),
                      c.y - static_cast<int>(std::lround(radius * std::cos(a))));
  }
  cv::fillPoly(*layer, std::vector<std::vector<cv::Point>>{star}, cv::Scalar(40, 200, 255),
               cv::LINE_AA);
  const cv::Point bar(static_cast<int>(std::lround(0.8 * r * std::cos(angle))),
                      static_cast<int>(std::lround(0.8 * r * std::sin(angle))));
  cv::line(*layer, c - bar, c + bar, cv::Scalar(255, 255, 255), std::max(1, r / 8), cv::LINE_AA);
}

void OverlayPainter::Paint(const HudTelemetry& telemetry, double time_s, cv::Mat* bgr) const {
  if (!options_.any()) return;
  cv::Mat layer(bgr->size(), CV_8UC3, cv::Scalar::all(0));
  cv::Mat alpha(bgr->size(), CV_8U, cv::Scalar(0));
  if (options_.hud_text) {
    const auto [top, bottom] = HudLines(telemetry);
    DrawOutlinedText(top, top_line_, font_scale_, font_thickness_, &layer, &alpha);
    DrawOutlinedText(bottom, bottom_line_, font_scale_, font_thickness_, &layer, &alpha);
  }
  if (options_.reticle) {
    const cv::Point c = reticle_centre_;
    const int a = reticle_arm_, g = reticle_gap_;
    const std::array<std::pair<cv::Point, cv::Point>, 4> arms = {
        {{c + cv::Point(g, 0), c + cv::Point(a, 0)},
         {c - cv::Point(g, 0), c - cv::Point(a, 0)},
         {c + cv::Point(0, g), c + cv::Point(0, a)},
         {c - cv::Point(0, g), c - cv::Point(0, a)}}};
    for (const auto& [from, to] : arms) {
      cv::line(layer, from, to, cv::Scalar::all(0), 4);
      cv::line(alpha, from, to, cv::Scalar(255), 4);
    }
    for (const auto& [from, to] : arms) cv::line(layer, from, to, cv::Scalar::all(255), 2);
  }
  cv::Mat logo_alpha;
  if (options_.logo != LogoMotion::kNone) {
    logo_alpha = cv::Mat::zeros(bgr->size(), CV_8U);
    PaintLogo(time_s, &layer, &logo_alpha);
    if (options_.logo == LogoMotion::kPulsing) {
      const double pulse =
          0.35 + 0.65 * (0.5 + 0.5 * std::sin(2 * kPi * options_.logo_pulse_hz * time_s));
      logo_alpha.convertTo(logo_alpha, CV_8U, pulse);
    }
    cv::max(alpha, logo_alpha, alpha);
  }
  // out = picture (1 - a) + layer a, with a = coverage x opacity.
  const double opacity = options_.opacity;
  for (int y = 0; y < bgr->rows; ++y) {
    const uint8_t* a_row = alpha.ptr<uint8_t>(y);
    const cv::Vec3b* l_row = layer.ptr<cv::Vec3b>(y);
    cv::Vec3b* p_row = bgr->ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr->cols; ++x) {
      if (a_row[x] == 0) continue;
      const double a = opacity * a_row[x] / 255.0;
      for (int c = 0; c < 3; ++c) {
        p_row[x][c] = cv::saturate_cast<uint8_t>(p_row[x][c] * (1 - a) + l_row[x][c] * a);
      }
    }
  }
}

}  // namespace saker::sim
