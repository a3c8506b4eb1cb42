#pragma once

// Ties each video frame to the KLV metadata that belongs to it.
//
// Synchronous KLV streams (MPEG-TS stream type 0x15, or any stream whose
// packets carry exactly the frames' timestamps) are matched by timestamp:
// a packet belongs to the frame with the same presentation time. Asynchronous
// streams (stream type 0x06, the common case) are matched by nearest time
// within a tolerance. A frame with no packet in range has no metadata and
// says so; it is not an error.

#include "core/util/status.h"

#include <optional>
#include <string>
#include <vector>

namespace saker::ingest {

struct AlignmentOptions {
  // Largest |packet time - frame time| accepted for asynchronous streams, in
  // seconds. Encoders typically send metadata at 1-30 Hz; 0.5 s keeps 2 Hz
  // streams attached without borrowing metadata across a real gap.
  double async_tolerance_s = 0.5;
  // Largest timestamp difference for a synchronous match, in seconds. One
  // 90 kHz tick is 11 us; 1 ms absorbs rounding between time bases.
  double sync_tolerance_s = 0.001;
  // Packets whose checksum failed (ST 0601 BCC-16) are kept for display (`saker-cli klv`) but
  // give no frame its time, sensor position or footprint, and no UTC span, unless this is set
  // (`--accept-bad-checksums`): one flipped bit can move a frame by hours or kilometres.
  bool accept_bad_checksums = false;

  Status Validate() const;
};

// How a frame's metadata was found.
enum class MatchKind {
  kNone,         // no packet within tolerance
  kSynchronous,  // same timestamp as the frame
  kNearest,      // nearest asynchronous packet within tolerance
};

const char* MatchKindName(MatchKind kind);

// One timestamped metadata packet as the aligner sees it.
struct AlignablePacket {
  int stream_index = -1;
  double time_s = 0;           // NaN when the packet had no timestamp (never matched)
  bool has_corners = false;    // preferred when several streams offer a packet
  bool usable = true;          // false for packets that failed to decode
  bool time_inferred = false;  // time from the packet's place in the file, not a timestamp:
                               // no evidence of synchronous timing
};

struct FrameMatch {
  MatchKind kind = MatchKind::kNone;
  std::optional<size_t> packet;  // index into the packets given to AlignFrames
  double offset_s = 0;           // packet time - frame time
};

// Per stream: whether it is matched synchronously.
struct StreamTiming {
  int stream_index = -1;
  bool synchronous = false;
};

// Decides, per KLV stream, whether it is synchronous: declared so by the
// container, or it has timestamped packets and every one lies on a frame time
// (inferred times are not evidence).
std::vector<StreamTiming> ClassifyStreams(const std::vector<double>& frame_times,
                                          const std::vector<AlignablePacket>& packets,
                                          const std::vector<StreamTiming>& declared,
                                          const AlignmentOptions& options);

// For each frame time (increasing), the best packet: among candidates from all
// streams within tolerance, a packet with corners beats one without, then the
// smaller time offset wins, then the lower stream index. Runs in
// O((frames + packets) log packets); duplicated and out-of-order packet times
// are accepted.
std::vector<FrameMatch> AlignFrames(const std::vector<double>& frame_times,
                                    const std::vector<AlignablePacket>& packets,
                                    const std::vector<StreamTiming>& timing,
                                    const AlignmentOptions& options);

}  // namespace saker::ingest
