#pragma once

// Reads a whole sequential pass, for tests that compare passes.

#include "core/video/video_reader.h"

#include <vector>

namespace saker::video {

// Everything one sequential pass gives.
struct Pass {
  std::vector<Frame> frames;
  std::vector<DataPacket> data;
};

inline Status ReadAll(VideoReader* reader, Pass* pass) {
  while (true) {
    Frame frame;
    auto more = reader->ReadNext(&frame, &pass->data);
    if (!more.ok()) return more.status();
    if (!*more) return Status::Ok();
    pass->frames.push_back(std::move(frame));
  }
}

}  // namespace saker::video
