#include "core/video/video_reader.h"

#include "core/video/decode_session.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <sstream>
#include <utility>

namespace saker::video {

const char* StreamKindName(StreamKind kind) {
  switch (kind) {
    case StreamKind::kVideo:
      return "video";
    case StreamKind::kAudio:
      return "audio";
    case StreamKind::kKlv:
      return "klv";
    case StreamKind::kOtherData:
      return "data";
    case StreamKind::kOther:
      return "other";
  }
  return "other";
}
namespace {

using internal::DecodeSession;
using internal::FrameConverter;
using internal::SessionConfig;

// Turns the decoder's timestamps into the strictly increasing sequence the API promises: a
// missing or non-increasing timestamp becomes the previous one plus one frame interval.
class TimestampSequencer {
 public:
  TimestampSequencer(int64_t first_default, int64_t step)
      : first_default_(first_default), step_(step) {}

  int64_t Next(int64_t raw) {
    int64_t pts = raw;
    if (has_last_ && (raw == AV_NOPTS_VALUE || raw <= last_)) {
      pts = last_ + step_;
    } else if (!has_last_ && raw == AV_NOPTS_VALUE) {
      pts = first_default_;
    }
    last_ = pts;
    has_last_ = true;
    return pts;
  }

 private:
  int64_t first_default_;
  int64_t step_;
  int64_t last_ = 0;
  bool has_last_ = false;
};

void EnsureNetworkInit(const std::string& path) {
  if (path.find("://") == std::string::npos) return;
  static std::once_flag once;
  std::call_once(once, [] { avformat_network_init(); });
}

// Outcome of decoding forward on the random-access session.
enum class Forward { kFound, kLate, kOvershot, kEnd };

}  // namespace

std::vector<int> VideoInfo::KlvStreams() const {
  std::vector<int> result;
  for (const StreamInfo& stream : streams) {
    if (stream.kind == StreamKind::kKlv) result.push_back(stream.index);
  }
  return result;
}

Status ReaderOptions::Validate() const {
  if (decoder_threads < 0 || decoder_threads > 64) {
    return InvalidArgumentError(
        "ReaderOptions.decoder_threads must be in [0, 64] (0 = automatic), got " +
        std::to_string(decoder_threads));
  }
  if (max_pixels < 1) {
    return InvalidArgumentError("ReaderOptions.max_pixels must be positive, got " +
                                std::to_string(max_pixels));
  }
  return Status::Ok();
}

struct VideoReader::Impl {
  std::string path;
  std::shared_ptr<const std::vector<uint8_t>> memory;  // OpenMemory's bytes, else null
  ReaderOptions options;
  VideoInfo info;

  // Sequential pass.
  std::unique_ptr<DecodeSession> sequential;
  FrameConverter sequential_converter;
  std::unique_ptr<TimestampSequencer> sequencer;
  FrameIndex next_index = 0;
  bool sequential_done = false;
  ReadStats stats;

  std::vector<FrameIndexEntry> index;
  bool index_complete = false;

  // Random access: its own session, opened on first use.
  std::unique_ptr<DecodeSession> random;
  FrameConverter random_converter;
  FrameIndex random_cursor = -1;  // index of the frame held by random->frame(), -1 when none

  SessionConfig Config(bool sequential_pass) const {
    SessionConfig config;
    config.memory = memory;
    config.keep_klv = sequential_pass;
    config.probe_klv_sync = sequential_pass;
    config.decoder_threads = options.decoder_threads;
    config.max_pixels = options.max_pixels;
    config.join_discontinuities = sequential_pass;
    return config;
  }

  Status OpenSequential() {
    sequential.reset();
    auto session = DecodeSession::Open(path, Config(true));
    if (!session.ok()) return session.status();
    sequential = std::move(session).value();
    sequencer =
        std::make_unique<TimestampSequencer>(sequential->start_pts(), sequential->frame_step());
    next_index = 0;
    sequential_done = false;
    stats = ReadStats{};
    return Status::Ok();
  }

  Status OpenRandom() {
    random.reset();
    random_cursor = -1;
    auto session = DecodeSession::Open(path, Config(false));
    if (!session.ok()) return session.status();
    random = std::move(session).value();
    return Status::Ok();
  }

  Status Convert(FrameConverter* converter, const DecodeSession& session, Frame* frame) {
    const bool chroma = options.want_grey && options.want_chroma;
    return converter->Convert(session.frame(), options.want_bgr ? &frame->bgr : nullptr,
                              options.want_grey ? &frame->grey : nullptr,
                              chroma ? &frame->chroma : nullptr, &frame->coding);
  }

  StatusOr<bool> ReadNext(Frame* frame, std::vector<DataPacket>* data) {
    SAKER_CHECK(frame != nullptr) << "ReadNext needs a frame to fill";
    if (!sequential) return IoError(path + ": cannot read on: reopening the input failed");
    if (sequential_done) return false;
    auto decoded = sequential->DecodeNext(data, &stats);
    if (!decoded.ok()) return decoded.status();
    if (!*decoded) {
      sequential_done = true;
      index_complete = true;
      return false;
    }
    const AVFrame& av_frame = sequential->frame();
    const int64_t pts = sequencer->Next(sequential->RawTimestamp());
    frame->index = next_index++;
    frame->pts = pts;
    frame->time_s = sequential->SecondsFromStart(pts);
    frame->key_frame = av_frame.key_frame != 0;
    frame->byte_pos = av_frame.pkt_pos;
    frame->bgr.release();
    frame->grey.release();
    frame->chroma.release();
    SAKER_RETURN_IF_ERROR(Convert(&sequential_converter, *sequential, frame));
    if (!index_complete) {
      index.push_back({frame->index, frame->pts, frame->time_s, frame->key_frame});
    }
    return true;
  }

  // Builds the index with a decode-only pass on the random-access session.
  Status EnsureIndex() {
    if (index_complete) return Status::Ok();
    SAKER_RETURN_IF_ERROR(OpenRandom());
    TimestampSequencer timestamps(random->start_pts(), random->frame_step());
    std::vector<FrameIndexEntry> built;
    while (true) {
      auto decoded = random->DecodeNext(nullptr, nullptr);
      if (!decoded.ok()) return decoded.status();
      if (!*decoded) break;
      const int64_t pts = timestamps.Next(random->RawTimestamp());
      built.push_back({static_cast<FrameIndex>(built.size()), pts, random->SecondsFromStart(pts),
                       random->frame().key_frame != 0});
    }
    index = std::move(built);
    index_complete = true;
    random_cursor = -1;  // the session sits at the end of the file
    return Status::Ok();
  }

  // Which index entry the random session's current frame is, given the previous one: by its
  // timestamp when that names a later entry, else the next entry in order (mirrors the
  // sequencer, which extrapolates missing and non-increasing timestamps).
  FrameIndex Identify(FrameIndex previous) const {
    const int64_t raw = random->RawTimestamp();
    if (raw != AV_NOPTS_VALUE) {
      auto it = std::lower_bound(index.begin(), index.end(), raw,
                                 [](const FrameIndexEntry& e, int64_t pts) { return e.pts < pts; });
      if (it != index.end() && it->pts == raw && it->index > previous) return it->index;
    }
    return previous >= 0 ? previous + 1 : -1;
  }

  // Decodes forward until the random session holds frame `target`. `latest_start`: the first
  // frame identified must not come after it (else the seek landed past the key frame and the
  // frames decoded from there could differ from the sequential pass); -1 disables the check.
  StatusOr<Forward> DecodeForward(FrameIndex target, FrameIndex latest_start) {
    bool first = random_cursor < 0;
    while (true) {
      auto decoded = random->DecodeNext(nullptr, nullptr);
      if (!decoded.ok()) return decoded.status();
      if (!*decoded) {
        random_cursor = -1;
        return Forward::kEnd;
      }
      const FrameIndex current = Identify(random_cursor);
      if (current < 0) continue;  // before anything we can place; keep going
      random_cursor = current;
      if (first && latest_start >= 0 && current > latest_start) return Forward::kLate;
      first = false;
      if (current == target) return Forward::kFound;
      if (current > target) return Forward::kOvershot;
    }
  }

  StatusOr<Frame> FrameFromRandom(FrameIndex target) {
    const FrameIndexEntry& entry = index[static_cast<size_t>(target)];
    Frame frame;
    frame.index = entry.index;
    frame.pts = entry.pts;
    frame.time_s = entry.time_s;
    frame.key_frame = entry.key_frame;
    frame.byte_pos = random->frame().pkt_pos;
    SAKER_RETURN_IF_ERROR(Convert(&random_converter, *random, &frame));
    return frame;
  }

  StatusOr<Frame> ReadFrame(FrameIndex target) {
    SAKER_RETURN_IF_ERROR(EnsureIndex());
    const auto count = static_cast<FrameIndex>(index.size());
    if (count == 0) return OutOfRangeError(path + ": has no decodable frames");
    if (target < 0 || target >= count) {
      return OutOfRangeError(path + ": frame " + std::to_string(target) +
                             " is out of range; valid frames are 0.." + std::to_string(count - 1));
    }
    if (!random) SAKER_RETURN_IF_ERROR(OpenRandom());

    FrameIndex key = target;
    while (key > 0 && !index[static_cast<size_t>(key)].key_frame) --key;

    // Recall of the frame held, or a later frame of the same GOP, or of the next GOP when only a
    // few frames lie before its key frame (playback crosses GOPs this way): no seek.
    constexpr FrameIndex kDecodeRatherThanSeek = 4;
    if (random_cursor == target) return FrameFromRandom(target);
    if (random_cursor >= 0 && random_cursor >= key - kDecodeRatherThanSeek &&
        random_cursor < target) {
      auto outcome = DecodeForward(target, -1);
      if (!outcome.ok()) return outcome.status();
      if (*outcome == Forward::kFound) return FrameFromRandom(target);
    }

    // Seek a little before the key frame (its packet's dts precedes its pts when frames are
    // reordered), then further back when the demuxer lands past it anyway.
    const AVRational time_base = random->video_time_base();
    const int64_t key_pts = index[static_cast<size_t>(key)].pts;
    const int64_t step = random->frame_step();
    const std::array<int64_t, 4> margins = {3 * step, av_rescale_q(1, AVRational{1, 1}, time_base),
                                            av_rescale_q(4, AVRational{1, 1}, time_base),
                                            av_rescale_q(16, AVRational{1, 1}, time_base)};
    for (int64_t margin : margins) {
      const int64_t seek_pts = key_pts - margin;
      // Seeking before the first frame is no better than starting over.
      if (margin != margins.front() && seek_pts <= index.front().pts) break;
      if (!random->SeekBackward(seek_pts).ok()) break;
      random_cursor = -1;
      auto outcome = DecodeForward(target, key);
      if (!outcome.ok()) return outcome.status();
      if (*outcome == Forward::kFound) return FrameFromRandom(target);
    }

    // Last resort, always exact: decode from the very beginning.
    SAKER_RETURN_IF_ERROR(OpenRandom());
    auto outcome = DecodeForward(target, key);
    if (!outcome.ok()) return outcome.status();
    if (*outcome == Forward::kFound) return FrameFromRandom(target);
    return InvalidDataError(path + ": frame " + std::to_string(target) +
                            " could not be decoded again; the file changed or the frame index "
                            "does not belong to it");
  }

  StatusOr<Frame> ReadFrameAtTime(double time_s) {
    if (!std::isfinite(time_s)) {
      return InvalidArgumentError(path + ": cannot look up a frame at a non-finite time");
    }
    SAKER_RETURN_IF_ERROR(EnsureIndex());
    if (index.empty()) return OutOfRangeError(path + ": has no decodable frames");
    const double interval = info.fps > 0
                                ? 1.0 / info.fps
                                : (index.size() > 1 ? (index.back().time_s - index.front().time_s) /
                                                          static_cast<double>(index.size() - 1)
                                                    : 0.04);
    const double first = index.front().time_s;
    const double last = index.back().time_s;
    if (time_s < first - interval || time_s > last + interval) {
      std::ostringstream message;
      message << path << ": time " << time_s << " s is outside the video (frames from " << first
              << " s to " << last << " s)";
      return OutOfRangeError(message.str());
    }
    auto it = std::lower_bound(index.begin(), index.end(), time_s,
                               [](const FrameIndexEntry& e, double t) { return e.time_s < t; });
    if (it == index.end()) {
      --it;
    } else if (it != index.begin() && (time_s - std::prev(it)->time_s) <= (it->time_s - time_s)) {
      --it;
    }
    return ReadFrame(it->index);
  }
};

VideoReader::VideoReader(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
VideoReader::~VideoReader() = default;

StatusOr<std::unique_ptr<VideoReader>> VideoReader::Open(const std::string& path_or_url,
                                                         const ReaderOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  EnsureNetworkInit(path_or_url);
  auto impl = std::make_unique<Impl>();
  impl->path = path_or_url;
  impl->options = options;
  SAKER_RETURN_IF_ERROR(impl->OpenSequential());
  impl->info = impl->sequential->info();
  return std::unique_ptr<VideoReader>(new VideoReader(std::move(impl)));
}

StatusOr<std::unique_ptr<VideoReader>> VideoReader::OpenMemory(std::vector<uint8_t> bytes,
                                                               const std::string& name,
                                                               const ReaderOptions& options) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  auto impl = std::make_unique<Impl>();
  impl->path = name.empty() ? std::string("<memory>") : name;
  impl->memory = std::make_shared<const std::vector<uint8_t>>(std::move(bytes));
  impl->options = options;
  SAKER_RETURN_IF_ERROR(impl->OpenSequential());
  impl->info = impl->sequential->info();
  return std::unique_ptr<VideoReader>(new VideoReader(std::move(impl)));
}

const VideoInfo& VideoReader::info() const { return impl_->info; }

const ReaderOptions& VideoReader::options() const { return impl_->options; }

StatusOr<bool> VideoReader::ReadNext(Frame* frame, std::vector<DataPacket>* data) {
  return impl_->ReadNext(frame, data);
}

const ReadStats& VideoReader::stats() const { return impl_->stats; }

const std::vector<FrameIndexEntry>& VideoReader::frame_index() const { return impl_->index; }

bool VideoReader::frame_index_complete() const { return impl_->index_complete; }

StatusOr<Frame> VideoReader::ReadFrame(FrameIndex index) { return impl_->ReadFrame(index); }

StatusOr<Frame> VideoReader::ReadFrameAtTime(double time_s) {
  return impl_->ReadFrameAtTime(time_s);
}

Status VideoReader::Rewind() {
  if (!impl_->index_complete) impl_->index.clear();
  return impl_->OpenSequential();
}

StatusOr<std::unique_ptr<VideoReader>> OpenWithIndex(const std::string& path,
                                                     std::vector<FrameIndexEntry> index,
                                                     const ReaderOptions& options) {
  if (index.empty()) {
    return InvalidArgumentError(path + ": OpenWithIndex needs a non-empty frame index");
  }
  for (size_t i = 0; i < index.size(); ++i) {
    if (index[i].index != static_cast<FrameIndex>(i)) {
      return InvalidArgumentError(path + ": frame index entry " + std::to_string(i) +
                                  " is numbered " + std::to_string(index[i].index));
    }
    if (i > 0 && index[i].pts <= index[i - 1].pts) {
      return InvalidArgumentError(path + ": frame index pts not strictly increasing at entry " +
                                  std::to_string(i));
    }
  }
  auto reader = VideoReader::Open(path, options);
  if (!reader.ok()) return reader.status();
  VideoReader::Impl& impl = *reader.value()->impl_;
  impl.index = std::move(index);
  impl.index_complete = true;
  return reader;
}

}  // namespace saker::video
