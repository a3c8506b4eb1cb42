#include "core/ingest/video_scan.h"

#include "core/util/check.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <utility>

namespace saker::ingest {

Status ScanOptions::Validate() const {
  SAKER_RETURN_IF_ERROR(reader.Validate());
  if (max_frames < 0) {
    return InvalidArgumentError("ScanOptions.max_frames must be >= 0 (0 = no limit), got " +
                                std::to_string(max_frames));
  }
  return alignment.Validate();
}

const klv::FrameMetadata* VideoScan::MetadataOf(size_t frame) const {
  if (frame >= frames.size()) return nullptr;
  const auto& match = frames[frame].metadata;
  if (!match.packet || *match.packet >= packets.size()) return nullptr;
  const auto& metadata = packets[*match.packet].decoded.metadata;
  return metadata ? &*metadata : nullptr;
}

int64_t VideoScan::FramesWithMetadata() const {
  int64_t n = 0;
  for (size_t i = 0; i < frames.size(); ++i) n += MetadataOf(i) != nullptr;
  return n;
}

int64_t VideoScan::FramesWithCorners() const {
  int64_t n = 0;
  for (size_t i = 0; i < frames.size(); ++i) {
    const auto* m = MetadataOf(i);
    n += m != nullptr && m->HasCorners();
  }
  return n;
}

int64_t VideoScan::ChecksumFailures() const {
  int64_t n = 0;
  for (const KlvStreamSummary& s : klv_streams) n += s.checksum_failures;
  return n;
}

std::optional<VideoScan::UtcRange> VideoScan::UtcSpan() const {
  std::optional<UtcRange> range;
  for (const auto& p : packets) {
    if (!p.trusted || !p.decoded.metadata || !p.decoded.metadata->unix_time_us) continue;
    const uint64_t t = *p.decoded.metadata->unix_time_us;
    if (!range) {
      range = UtcRange{t, t};
    } else {
      range->first_us = std::min(range->first_us, t);
      range->last_us = std::max(range->last_us, t);
    }
  }
  return range;
}

namespace {

// Warnings repeat per packet on bad streams; keep the list readable.
constexpr size_t kMaxWarnings = 50;

void AddWarning(VideoScan* scan, int64_t* suppressed, std::string text) {
  if (scan->warnings.size() < kMaxWarnings) {
    scan->warnings.push_back(std::move(text));
  } else {
    ++*suppressed;
  }
}

void DecodeDataPacket(const video::DataPacket& data, bool accept_bad_checksums,
                      KlvStreamSummary* summary, VideoScan* scan, int64_t* suppressed) {
  ++summary->demuxed_packets;
  const klv::KlvSplitResult split = klv::SplitKlvPackets(data.bytes);
  if (!split.errors.empty()) {
    summary->framing_errors += static_cast<int64_t>(split.errors.size());
    std::ostringstream m;
    m << "KLV stream " << data.stream_index << " at " << data.time_s
      << " s: " << split.errors.front();
    AddWarning(scan, suppressed, m.str());
  }
  for (const auto& packet : split.packets) {
    MetadataPacket received;
    received.stream_index = data.stream_index;
    received.time_s = data.time_s;
    received.byte_pos = data.byte_pos;
    received.decoded = klv::DecodePacket(packet);
    ++summary->klv_packets;
    const auto& decoded = received.decoded;
    switch (decoded.kind) {
      case klv::PacketKind::kSt0601:
        ++summary->st0601_packets;
        break;
      case klv::PacketKind::kEg0104:
        ++summary->eg0104_packets;
        break;
      default:
        ++summary->other_packets;
        break;
    }
    if (!decoded.status.ok()) {
      ++summary->decode_errors;
      std::ostringstream m;
      m << "KLV stream " << data.stream_index << " at " << data.time_s
        << " s: " << decoded.status.message();
      AddWarning(scan, suppressed, m.str());
    }
    const bool checksum_failed = decoded.st0601 && !decoded.st0601->checksum_ok;
    if (checksum_failed) ++summary->checksum_failures;
    received.trusted = decoded.metadata.has_value() && (accept_bad_checksums || !checksum_failed);
    scan->packets.push_back(std::move(received));
  }
}

// Gives each packet without a timestamp the time of the first frame carried
// after it in the file, or of the last frame when none follows.
void InferMissingTimes(VideoScan* scan) {
  std::vector<std::pair<int64_t, double>> frame_positions;  // (byte_pos, time_s)
  for (const auto& f : scan->frames) {
    if (f.byte_pos >= 0) frame_positions.emplace_back(f.byte_pos, f.time_s);
  }
  if (frame_positions.empty()) return;
  std::sort(frame_positions.begin(), frame_positions.end());
  for (auto& p : scan->packets) {
    if (std::isfinite(p.time_s) || p.byte_pos < 0) continue;
    auto next = std::upper_bound(
        frame_positions.begin(), frame_positions.end(), p.byte_pos,
        [](int64_t pos, const std::pair<int64_t, double>& frame) { return pos < frame.first; });
    p.time_s = next != frame_positions.end() ? next->second : frame_positions.back().second;
    p.time_inferred = true;
  }
}

// The scan proper, on an opened reader; `path` names the input in messages.
StatusOr<VideoScan> ScanReader(video::VideoReader& reader, const std::string& path,
                               const ScanOptions& options, JobContext* context,
                               const FrameCallback& on_frame) {
  VideoScan scan;
  scan.info = reader.info();
  std::map<int, KlvStreamSummary> summaries;
  std::vector<StreamTiming> declared;
  for (const auto& stream : scan.info.streams) {
    if (stream.kind != video::StreamKind::kKlv) continue;
    KlvStreamSummary s;
    s.stream_index = stream.index;
    s.pid = stream.pid;
    summaries[stream.index] = s;
    declared.push_back({stream.index, stream.klv_synchronous});
  }

  int64_t suppressed = 0;
  const int64_t expected_frames = scan.info.declared_frame_count > 0
                                      ? scan.info.declared_frame_count
                                      : static_cast<int64_t>(scan.info.duration_s * scan.info.fps);
  video::Frame frame;
  std::vector<video::DataPacket> data;
  for (;;) {
    if (context != nullptr && context->IsCancelled()) {
      return CancelledError("scan of " + path + " cancelled after " +
                            std::to_string(scan.frames.size()) + " frames");
    }
    data.clear();
    auto more = reader.ReadNext(&frame, &data);
    if (!more.ok()) return more.status();
    for (const auto& d : data) {
      auto it = summaries.find(d.stream_index);
      if (it == summaries.end()) continue;  // a data stream that is not KLV
      const size_t first = scan.packets.size();
      DecodeDataPacket(d, options.alignment.accept_bad_checksums, &it->second, &scan, &suppressed);
      if (options.on_packet) {
        for (size_t i = first; i < scan.packets.size(); ++i) options.on_packet(scan.packets[i]);
      }
    }
    if (!*more) break;
    if (options.max_frames > 0 && static_cast<int64_t>(scan.frames.size()) >= options.max_frames) {
      // Not subject to the warning cap: a reader of the scan must know it is partial.
      scan.warnings.push_back(path + ": scan stopped after " + std::to_string(options.max_frames) +
                              " frames (max_frames); the rest of the video was not read");
      break;
    }
    FrameRecord record;
    record.index = frame.index;
    record.time_s = frame.time_s;
    record.key_frame = frame.key_frame;
    record.byte_pos = frame.byte_pos;
    scan.frames.push_back(record);
    if (on_frame) on_frame(frame);
    if (context != nullptr && expected_frames > 0 && scan.frames.size() % 32 == 0) {
      context->ReportProgress("scan", std::min(1.0, static_cast<double>(scan.frames.size()) /
                                                        static_cast<double>(expected_frames)));
    }
  }
  scan.stats = reader.stats();

  // Align frames with metadata now that every packet is known.
  InferMissingTimes(&scan);
  std::vector<double> frame_times;
  frame_times.reserve(scan.frames.size());
  for (const auto& f : scan.frames) frame_times.push_back(f.time_s);
  std::vector<AlignablePacket> alignable;
  alignable.reserve(scan.packets.size());
  for (const auto& p : scan.packets) {
    const auto& m = p.decoded.metadata;
    alignable.push_back(
        {p.stream_index, p.time_s, m && m->HasCorners(), p.trusted, p.time_inferred});
  }
  const auto timing = ClassifyStreams(frame_times, alignable, declared, options.alignment);
  for (const auto& t : timing) {
    if (auto it = summaries.find(t.stream_index); it != summaries.end()) {
      it->second.synchronous = t.synchronous;
    }
  }
  const auto matches = AlignFrames(frame_times, alignable, timing, options.alignment);
  for (size_t i = 0; i < matches.size(); ++i) scan.frames[i].metadata = matches[i];

  for (auto& [index, summary] : summaries) scan.klv_streams.push_back(summary);
  if (scan.stats.corrupt_packets > 0 || scan.stats.decode_errors > 0) {
    std::ostringstream m;
    m << path << ": skipped " << scan.stats.corrupt_packets << " corrupt packets and "
      << scan.stats.decode_errors << " undecodable frames";
    scan.warnings.insert(scan.warnings.begin(), m.str());
  }
  if (scan.stats.timestamp_discontinuities > 0) {
    std::ostringstream m;
    m << path << ": the timestamps jump back " << scan.stats.timestamp_discontinuities
      << (scan.stats.timestamp_discontinuities == 1 ? " time" : " times")
      << " (a spliced or restarted recording); the frames and metadata after each jump are timed "
         "to follow on";
    scan.warnings.push_back(m.str());
  }
  if (const int64_t failed = scan.ChecksumFailures(); failed > 0) {
    std::ostringstream m;
    m << path << ": " << failed << " KLV packet" << (failed == 1 ? "" : "s")
      << " failed the checksum: "
      << (options.alignment.accept_bad_checksums
              ? "used all the same (accept_bad_checksums)"
              : "kept for display, not used for time, position or the map "
                "(--accept-bad-checksums uses them)");
    scan.warnings.push_back(m.str());
  }
  if (suppressed > 0) {
    scan.warnings.push_back("... and " + std::to_string(suppressed) + " more warnings");
  }
  if (context != nullptr) context->ReportProgress("scan", 1.0);
  return scan;
}

}  // namespace

StatusOr<VideoScan> ScanVideo(const std::string& path, const ScanOptions& options,
                              JobContext* context, const FrameCallback& on_frame) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> reader,
                         video::VideoReader::Open(path, options.reader));
  return ScanVideo(std::move(reader), options, context, on_frame);
}

StatusOr<VideoScan> ScanVideo(std::unique_ptr<video::VideoReader> reader,
                              const ScanOptions& options, JobContext* context,
                              const FrameCallback& on_frame) {
  SAKER_CHECK(reader != nullptr) << "ScanVideo needs an opened reader";
  SAKER_CHECK(reader->stats().frames_decoded == 0)
      << reader->info().path << ": the scan needs a reader that has not been read from";
  SAKER_RETURN_IF_ERROR(options.Validate());
  return ScanReader(*reader, reader->info().path, options, context, on_frame);
}

StatusOr<VideoScan> ScanVideoMemory(std::vector<uint8_t> bytes, const std::string& name,
                                    const ScanOptions& options, JobContext* context,
                                    const FrameCallback& on_frame) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  SAKER_ASSIGN_OR_RETURN(std::unique_ptr<video::VideoReader> reader,
                         video::VideoReader::OpenMemory(std::move(bytes), name, options.reader));
  return ScanVideo(std::move(reader), options, context, on_frame);
}

}  // namespace saker::ingest
