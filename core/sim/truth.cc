#include "core/sim/truth.h"

#include "core/util/durable_file.h"

#include <algorithm>
#include <fstream>

namespace saker::sim {
namespace {

using nlohmann::json;

json Vec(const Eigen::Vector2d& v) { return json::array({v.x(), v.y()}); }
json Vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

// Reads a fixed-size array of numbers, or fails naming the field.
template <int N>
StatusOr<Eigen::Matrix<double, N, 1>> ReadVector(const json& j, const char* field) {
  if (!j.is_array() || j.size() != static_cast<size_t>(N)) {
    return InvalidDataError(std::string("truth: '") + field + "' must be an array of " +
                            std::to_string(N) + " numbers");
  }
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) {
    if (!j[static_cast<size_t>(i)].is_number()) {
      return InvalidDataError(std::string("truth: '") + field + "' holds a non-number");
    }
    v[i] = j[static_cast<size_t>(i)].get<double>();
  }
  return v;
}

}  // namespace

json TruthToJson(const Truth& truth) {
  json frames = json::array();
  for (const FrameTruth& f : truth.frames) {
    json h = json::array();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) h.push_back(f.frame_from_ground(r, c));
    }
    frames.push_back({{"index", f.index},
                      {"time_s", f.time_s},
                      {"frame_from_ground", h},
                      {"position_m", Vec(f.position_m)},
                      {"heading_deg", f.heading_deg},
                      {"pitch_deg", f.pitch_deg},
                      {"roll_deg", f.roll_deg},
                      {"blank", f.blank},
                      {"klv", f.klv},
                      {"cut", f.cut},
                      {"repeated", f.repeated},
                      {"hfov_deg", f.hfov_deg},
                      {"gimbal_azimuth_deg", f.gimbal_azimuth_deg},
                      {"gimbal_off_nadir_deg", f.gimbal_off_nadir_deg}});
  }
  json targets = json::array();
  for (const TargetTruth& t : truth.targets) {
    json ground = json::array(), image = json::array(), velocity = json::array(),
         visible = json::array();
    for (const TargetSampleTruth& s : t.samples) {
      ground.push_back(Vec(s.ground_m));
      image.push_back(Vec(s.image_px));
      velocity.push_back(Vec(s.velocity_mps));
      visible.push_back(s.visible);
    }
    targets.push_back({{"id", t.id},
                       {"class", t.target_class},
                       {"length_m", t.length_m},
                       {"width_m", t.width_m},
                       {"ground_m", ground},
                       {"image_px", image},
                       {"velocity_mps", velocity},
                       {"visible", visible}});
  }
  json overlays = json::array();
  for (const OverlayTruth& o : truth.overlays) {
    overlays.push_back({{"kind", o.kind}, {"box_px", {o.x, o.y, o.width, o.height}}});
  }
  return {{"format", kTruthFormat},
          {"version", kTruthVersion},
          {"generator", truth.generator},
          {"origin",
           {{"latitude_deg", truth.origin_latitude_deg},
            {"longitude_deg", truth.origin_longitude_deg},
            {"height_m", truth.origin_height_m}}},
          {"ground_frame", "east-north metres from the origin; ground plane z = 0"},
          {"camera",
           {{"width", truth.width},
            {"height", truth.height},
            {"fx", truth.fx},
            {"fy", truth.fy},
            {"cx", truth.cx},
            {"cy", truth.cy},
            {"pixels", "integer coordinates are pixel centres"}}},
          {"fps", truth.fps},
          {"start_utc_us", truth.start_utc_us},
          {"frames", frames},
          {"targets", targets},
          {"overlays", overlays}};
}

StatusOr<Truth> TruthFromJson(const json& j) {
  try {
    if (!j.is_object() || j.value("format", "") != kTruthFormat) {
      return InvalidDataError(std::string("truth: not a ") + kTruthFormat + " file");
    }
    if (j.value("version", 0) != kTruthVersion) {
      return UnsupportedError("truth: version " + j.value("version", json()).dump() +
                              " is not supported (this build reads version " +
                              std::to_string(kTruthVersion) + ")");
    }
    Truth truth;
    truth.generator = j.value("generator", json::object());
    const json& origin = j.at("origin");
    truth.origin_latitude_deg = origin.at("latitude_deg").get<double>();
    truth.origin_longitude_deg = origin.at("longitude_deg").get<double>();
    truth.origin_height_m = origin.at("height_m").get<double>();
    const json& camera = j.at("camera");
    truth.width = camera.at("width").get<int>();
    truth.height = camera.at("height").get<int>();
    truth.fx = camera.at("fx").get<double>();
    truth.fy = camera.at("fy").get<double>();
    truth.cx = camera.at("cx").get<double>();
    truth.cy = camera.at("cy").get<double>();
    truth.fps = j.at("fps").get<double>();
    truth.start_utc_us = j.at("start_utc_us").get<uint64_t>();
    for (const json& f : j.at("frames")) {
      FrameTruth frame;
      frame.index = f.at("index").get<int64_t>();
      frame.time_s = f.at("time_s").get<double>();
      SAKER_ASSIGN_OR_RETURN(const auto h,
                             (ReadVector<9>(f.at("frame_from_ground"), "frame_from_ground")));
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) frame.frame_from_ground(r, c) = h[r * 3 + c];
      }
      SAKER_ASSIGN_OR_RETURN(frame.position_m, ReadVector<3>(f.at("position_m"), "position_m"));
      frame.heading_deg = f.at("heading_deg").get<double>();
      frame.pitch_deg = f.at("pitch_deg").get<double>();
      frame.roll_deg = f.at("roll_deg").get<double>();
      frame.blank = f.at("blank").get<bool>();
      frame.klv = f.at("klv").get<bool>();
      // Fields added after version 1 first shipped: older files lack them.
      frame.cut = f.value("cut", false);
      frame.repeated = f.value("repeated", false);
      frame.hfov_deg = f.value("hfov_deg", 0.0);
      frame.gimbal_azimuth_deg = f.value("gimbal_azimuth_deg", 0.0);
      frame.gimbal_off_nadir_deg = f.value("gimbal_off_nadir_deg", 0.0);
      truth.frames.push_back(frame);
    }
    for (const json& t : j.at("targets")) {
      TargetTruth target;
      target.id = t.at("id").get<int>();
      target.target_class = t.at("class").get<std::string>();
      target.length_m = t.at("length_m").get<double>();
      target.width_m = t.at("width_m").get<double>();
      const json& ground = t.at("ground_m");
      const json& image = t.at("image_px");
      const json& velocity = t.at("velocity_mps");
      const json& visible = t.at("visible");
      if (ground.size() != truth.frames.size() || image.size() != ground.size() ||
          velocity.size() != ground.size() || visible.size() != ground.size()) {
        return InvalidDataError("truth: target " + std::to_string(target.id) +
                                " does not have one sample per frame");
      }
      for (size_t i = 0; i < ground.size(); ++i) {
        TargetSampleTruth s;
        SAKER_ASSIGN_OR_RETURN(s.ground_m, ReadVector<2>(ground[i], "ground_m"));
        SAKER_ASSIGN_OR_RETURN(s.image_px, ReadVector<2>(image[i], "image_px"));
        SAKER_ASSIGN_OR_RETURN(s.velocity_mps, ReadVector<2>(velocity[i], "velocity_mps"));
        s.visible = visible[i].get<bool>();
        target.samples.push_back(s);
      }
      truth.targets.push_back(std::move(target));
    }
    for (const json& o : j.value("overlays", json::array())) {
      OverlayTruth overlay;
      overlay.kind = o.at("kind").get<std::string>();
      SAKER_ASSIGN_OR_RETURN(const auto box, ReadVector<4>(o.at("box_px"), "box_px"));
      overlay.x = static_cast<int>(box[0]), overlay.y = static_cast<int>(box[1]);
      overlay.width = static_cast<int>(box[2]), overlay.height = static_cast<int>(box[3]);
      if (overlay.width < 0 || overlay.height < 0) {
        return InvalidDataError("truth: overlay '" + overlay.kind + "' has a negative size");
      }
      truth.overlays.push_back(overlay);
    }
    return truth;
  } catch (const json::exception& e) {
    return InvalidDataError(std::string("truth: ") + e.what());
  }
}

bool Truth::OnOverlay(const Eigen::Vector2d& pixel) const {
  return std::any_of(overlays.begin(), overlays.end(),
                     [&](const OverlayTruth& o) { return o.Contains(pixel); });
}

std::vector<int64_t> Truth::CutFrames() const {
  std::vector<int64_t> cuts;
  for (const FrameTruth& f : frames) {
    if (f.cut) cuts.push_back(f.index);
  }
  return cuts;
}

Status WriteTruth(const Truth& truth, const std::filesystem::path& path) {
  return ReplaceFileFromStream(path.string(), [&](std::ostream& out) {
    out << TruthToJson(truth).dump() << '\n';
    return Status::Ok();
  });
}

StatusOr<Truth> ReadTruth(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return NotFoundError("cannot open truth file " + path.string());
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    return InvalidDataError(path.string() + ": not valid JSON: " + e.what());
  }
  StatusOr<Truth> truth = TruthFromJson(j);
  if (!truth.ok())
    return Status(truth.status().code(), path.string() + ": " + truth.status().message());
  return truth;
}

}  // namespace saker::sim
