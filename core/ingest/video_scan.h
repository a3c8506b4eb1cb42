#pragma once

// One pass over a video: every frame decoded in order, every KLV packet of
// every data stream decoded as it is demuxed (no second read of the file),
// and each frame tied to its metadata. This is what `saker-cli probe` and
// `saker-cli klv` report, and what the processing pipeline builds on.

#include "core/ingest/metadata_alignment.h"
#include "core/klv/decode.h"
#include "core/util/job_context.h"
#include "core/util/status.h"
#include "core/video/video_reader.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace saker::ingest {

struct MetadataPacket;

struct ScanOptions {
  // Decoding options; by default no pixel conversion is done, since a scan
  // only needs timing. Set want_bgr / want_grey to receive images in
  // `on_frame`.
  video::ReaderOptions reader = [] {
    video::ReaderOptions r;
    r.want_bgr = false;
    r.want_grey = false;
    return r;
  }();
  AlignmentOptions alignment;  // how frames are tied to metadata
  // Stop after this many frames (0: no limit), e.g. to look at the start of a long flight or to
  // bound the work on untrusted input; a warning then says the scan stopped early.
  int64_t max_frames = 0;
  // Called for every KLV packet as it is decoded, in the order of the file (before the frames
  // demuxed after it reach `on_frame`), for a reader that needs the metadata as the video goes
  // rather than when the scan ends (the front end's ground scale). Its time may still be
  // unknown (MetadataPacket::time_s NaN: inferred when the scan ends).
  std::function<void(const MetadataPacket&)> on_packet;

  Status Validate() const;
};

// A KLV packet as received: which stream, when, and its decode.
struct MetadataPacket {
  int stream_index = -1;
  // Seconds on the frames' clock. Asynchronous KLV often has no timestamp;
  // such a packet takes the time of the next video frame in the multiplex
  // (encoders send metadata just before the frame it describes), and
  // time_inferred says so. NaN when even that is unknown.
  double time_s = 0;
  bool time_inferred = false;
  int64_t byte_pos = -1;  // offset in the file, -1 when unknown
  klv::DecodedPacket decoded;
  // Whether the packet may time, place or geo-reference frames: it decoded to metadata and its
  // checksum verified, or AlignmentOptions::accept_bad_checksums let it in. Every packet is kept
  // in VideoScan::packets for display either way.
  bool trusted = false;
};

// What we know about one frame after the scan.
struct FrameRecord {
  video::FrameIndex index = 0;
  double time_s = 0;
  bool key_frame = false;
  int64_t byte_pos = -1;  // offset in the file of the packet that carried the frame
  FrameMatch metadata;    // metadata.packet indexes VideoScan::packets
};

// Per-KLV-stream counts, for the probe summary.
struct KlvStreamSummary {
  int stream_index = -1;
  int pid = -1;
  bool synchronous = false;     // matched by timestamp (see metadata_alignment.h)
  int64_t demuxed_packets = 0;  // container packets of this stream
  int64_t klv_packets = 0;      // KLV packets found in them
  int64_t st0601_packets = 0;
  int64_t eg0104_packets = 0;
  int64_t other_packets = 0;      // other or unknown universal keys (e.g. ST 0903 alone)
  int64_t checksum_failures = 0;  // ST 0601 packets whose BCC-16 did not verify (not used for
                                  // timing or geometry unless accepted: AlignmentOptions)
  int64_t decode_errors = 0;      // packets that could not be decoded at all
  int64_t framing_errors = 0;     // bytes that were not valid KLV framing
};

struct VideoScan {
  video::VideoInfo info;
  std::vector<FrameRecord> frames;
  std::vector<MetadataPacket> packets;  // in demux order
  std::vector<KlvStreamSummary> klv_streams;
  video::ReadStats stats;
  std::vector<std::string> warnings;  // human-readable, each names the problem

  // The metadata of frame `index`, or nullptr when it has none.
  const klv::FrameMetadata* MetadataOf(size_t frame) const;
  int64_t FramesWithMetadata() const;
  int64_t FramesWithCorners() const;
  // ST 0601 packets whose checksum failed, over every stream.
  int64_t ChecksumFailures() const;
  // Earliest and latest metadata UTC time stamps (microseconds), when any
  // trusted packet (MetadataPacket::trusted) had one.
  struct UtcRange {
    uint64_t first_us = 0;
    uint64_t last_us = 0;
    double SpanSeconds() const { return static_cast<double>(last_us - first_us) * 1e-6; }
  };
  std::optional<UtcRange> UtcSpan() const;
};

// Called for every decoded frame during the scan (before alignment, which
// needs the whole stream for asynchronous metadata).
using FrameCallback = std::function<void(const video::Frame& frame)>;

// Scans `path` once. Fails only when the file cannot be opened as a video;
// corrupt packets and undecodable metadata are counted and listed in
// warnings. Cancelling through `context` returns a Cancelled status.
StatusOr<VideoScan> ScanVideo(const std::string& path, const ScanOptions& options,
                              JobContext* context = nullptr,
                              const FrameCallback& on_frame = nullptr);

// The same on a video already opened and not yet read from, so that a caller that looked at it
// first (its size and rate) does not open it again: the scan takes the reader and reads it to the
// end. Frames are decoded as the reader was opened to (options.reader is not used); messages
// name the reader's path.
StatusOr<VideoScan> ScanVideo(std::unique_ptr<video::VideoReader> reader,
                              const ScanOptions& options, JobContext* context = nullptr,
                              const FrameCallback& on_frame = nullptr);

// The same for a whole video file held in memory (video::VideoReader::OpenMemory); `name` stands
// for the path in VideoInfo::path and in every message.
StatusOr<VideoScan> ScanVideoMemory(std::vector<uint8_t> bytes, const std::string& name,
                                    const ScanOptions& options, JobContext* context = nullptr,
                                    const FrameCallback& on_frame = nullptr);

}  // namespace saker::ingest
