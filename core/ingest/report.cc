#include "core/ingest/report.h"

#include <cmath>
#include <ctime>
#include <iomanip>
#include <map>
#include <sstream>

namespace saker::ingest {

namespace {

nlohmann::json OptionalTime(double t) {
  return std::isfinite(t) ? nlohmann::json(t) : nlohmann::json(nullptr);
}

std::string Hex(int value) {
  std::ostringstream s;
  s << "0x" << std::hex << value;
  return s.str();
}

// For each packet, the frames it was matched to.
std::map<size_t, std::vector<int64_t>> FramesByPacket(const VideoScan& scan) {
  std::map<size_t, std::vector<int64_t>> result;
  for (const auto& f : scan.frames) {
    if (f.metadata.packet) result[*f.metadata.packet].push_back(f.index);
  }
  return result;
}

}  // namespace

std::string FormatUtcMicros(uint64_t unix_time_us) {
  const std::time_t seconds = static_cast<std::time_t>(unix_time_us / 1000000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  std::ostringstream s;
  s << std::put_time(&utc, "%Y-%m-%dT%H:%M:%S") << '.' << std::setw(6) << std::setfill('0')
    << unix_time_us % 1000000 << 'Z';
  return s.str();
}

nlohmann::json ProbeToJson(const VideoScan& scan) {
  using nlohmann::json;
  const auto& info = scan.info;
  json j;
  j["file"] = info.path;
  j["container"] = info.container;
  j["container_long_name"] = info.container_long;
  json streams = json::array();
  for (const auto& s : info.streams) {
    json js{{"index", s.index}, {"kind", video::StreamKindName(s.kind)}, {"codec", s.codec_name}};
    js["pid"] = s.pid >= 0 ? json(s.pid) : json(nullptr);
    streams.push_back(js);
  }
  j["streams"] = streams;
  j["video"] = {
      {"stream", info.video_stream},  {"codec", info.video_codec}, {"width", info.width},
      {"height", info.height},        {"fps", info.fps},           {"frames", scan.frames.size()},
      {"duration_s", info.duration_s}};
  if (!scan.frames.empty()) {
    j["video"]["first_frame_s"] = scan.frames.front().time_s;
    j["video"]["last_frame_s"] = scan.frames.back().time_s;
  }
  j["decode"] = {{"corrupt_packets", scan.stats.corrupt_packets},
                 {"decode_errors", scan.stats.decode_errors}};
  json klv = json::array();
  int64_t checksum_failures = 0;
  for (const auto& s : scan.klv_streams) {
    checksum_failures += s.checksum_failures;
    klv.push_back({{"stream", s.stream_index},
                   {"pid", s.pid >= 0 ? json(s.pid) : json(nullptr)},
                   {"timing", s.synchronous ? "synchronous" : "asynchronous"},
                   {"demuxed_packets", s.demuxed_packets},
                   {"klv_packets", s.klv_packets},
                   {"st0601_packets", s.st0601_packets},
                   {"eg0104_packets", s.eg0104_packets},
                   {"other_packets", s.other_packets},
                   {"checksum_failures", s.checksum_failures},
                   {"decode_errors", s.decode_errors},
                   {"framing_errors", s.framing_errors}});
  }
  j["klv_streams"] = klv;
  j["metadata"] = {{"packets", scan.packets.size()},
                   {"checksum_failures", checksum_failures},
                   {"frames_with_metadata", scan.FramesWithMetadata()},
                   {"frames_with_corners", scan.FramesWithCorners()}};
  if (const auto span = scan.UtcSpan()) {
    j["metadata"]["first_utc"] = FormatUtcMicros(span->first_us);
    j["metadata"]["last_utc"] = FormatUtcMicros(span->last_us);
    j["metadata"]["span_s"] = span->SpanSeconds();
  }
  j["warnings"] = scan.warnings;
  return j;
}

std::string ProbeToText(const VideoScan& scan) {
  const auto& info = scan.info;
  std::ostringstream s;
  s << std::fixed;
  s << "File:       " << info.path << "\n";
  s << "Container:  " << info.container_long << " (" << info.container << ")\n";
  s << "Video:      " << info.video_codec << " " << info.width << "x" << info.height << ", "
    << std::setprecision(3) << info.fps << " fps, " << scan.frames.size() << " frames";
  if (!scan.frames.empty()) {
    s << ", " << scan.frames.front().time_s << " to " << scan.frames.back().time_s << " s";
  }
  s << "\n";
  if (scan.stats.corrupt_packets > 0 || scan.stats.decode_errors > 0) {
    s << "Damage:     " << scan.stats.corrupt_packets << " corrupt packets skipped, "
      << scan.stats.decode_errors << " frames undecodable\n";
  }
  s << "Streams:   ";
  for (const auto& st : info.streams) {
    s << " #" << st.index << " " << video::StreamKindName(st.kind) << " " << st.codec_name;
    if (st.pid >= 0) s << " (PID " << Hex(st.pid) << ")";
    s << ";";
  }
  s << "\n";
  if (scan.klv_streams.empty()) {
    s << "Metadata:   none (no KLV data stream)\n";
  }
  for (const auto& k : scan.klv_streams) {
    s << "KLV #" << k.stream_index;
    if (k.pid >= 0) s << " (PID " << Hex(k.pid) << ")";
    s << ": " << k.klv_packets << " packets";
    if (k.st0601_packets > 0) s << ", " << k.st0601_packets << " ST 0601";
    if (k.eg0104_packets > 0) s << ", " << k.eg0104_packets << " EG 0104";
    if (k.other_packets > 0) s << ", " << k.other_packets << " other";
    s << ", " << (k.synchronous ? "synchronous" : "asynchronous");
    s << ", " << k.checksum_failures << " checksum failures";
    if (k.decode_errors > 0) s << ", " << k.decode_errors << " undecodable";
    if (k.framing_errors > 0) s << ", " << k.framing_errors << " framing errors";
    s << "\n";
  }
  if (!scan.klv_streams.empty()) {
    s << "Frames:     " << scan.FramesWithMetadata() << " of " << scan.frames.size()
      << " with metadata, " << scan.FramesWithCorners() << " with image corners\n";
  }
  if (const auto span = scan.UtcSpan()) {
    s << "UTC span:   " << FormatUtcMicros(span->first_us) << " to "
      << FormatUtcMicros(span->last_us) << " (" << std::setprecision(3) << span->SpanSeconds()
      << " s)\n";
  }
  for (const auto& w : scan.warnings) s << "Warning:    " << w << "\n";
  return s.str();
}

nlohmann::json KlvDumpToJson(const VideoScan& scan) {
  using nlohmann::json;
  const auto frames_by_packet = FramesByPacket(scan);
  json packets = json::array();
  for (size_t i = 0; i < scan.packets.size(); ++i) {
    const auto& p = scan.packets[i];
    json j = klv::ToJson(p.decoded);
    j["stream"] = p.stream_index;
    j["time_s"] = OptionalTime(p.time_s);
    j["time_inferred"] = p.time_inferred;
    j["used"] = p.trusted;  // false: undecodable, or failed its checksum (not accepted)
    auto it = frames_by_packet.find(i);
    j["frames"] = it == frames_by_packet.end() ? json::array() : json(it->second);
    packets.push_back(std::move(j));
  }
  return {{"file", scan.info.path}, {"packets", packets}, {"warnings", scan.warnings}};
}

std::string KlvDumpToText(const VideoScan& scan) {
  const auto frames_by_packet = FramesByPacket(scan);
  std::ostringstream s;
  for (size_t i = 0; i < scan.packets.size(); ++i) {
    const auto& p = scan.packets[i];
    s << "packet " << i << ": stream " << p.stream_index << ", t = " << p.time_s << " s"
      << (p.time_inferred ? " (from its place in the stream)" : "") << ", "
      << klv::PacketKindName(p.decoded.kind);
    if (auto it = frames_by_packet.find(i); it != frames_by_packet.end()) {
      s << ", frames " << it->second.front();
      if (it->second.size() > 1) s << "-" << it->second.back();
    }
    if (!p.decoded.status.ok()) s << ", ERROR " << p.decoded.status.message();
    if (p.decoded.st0601 && !p.decoded.st0601->checksum_ok) {
      s << ", checksum FAILED" << (p.trusted ? " (used: accepted)" : " (not used)");
    }
    s << "\n";
    // The per-tag dump is the JSON form, one item per line, which keeps the
    // text and JSON outputs from disagreeing.
    const auto j = klv::ToJson(p.decoded);
    if (j.contains("items")) {
      for (const auto& item : j["items"]) s << "  " << item.dump() << "\n";
    } else {
      s << "  " << j.dump() << "\n";
    }
  }
  for (const auto& w : scan.warnings) s << "warning: " << w << "\n";
  return s.str();
}

}  // namespace saker::ingest
