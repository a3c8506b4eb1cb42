#include "core/mosaic/mosaic_input.h"

#include <string>

namespace saker::mosaic {

Status MosaicInput::Validate() const {
  if (image_width <= 0 || image_height <= 0) {
    return InvalidArgumentError("mosaic input: the image size " + std::to_string(image_width) +
                                "x" + std::to_string(image_height) + " is not positive");
  }
  for (size_t k = 0; k < key_frames.size(); ++k) {
    const track::KeyFrame& kf = key_frames[k];
    if (static_cast<size_t>(kf.id) != k) {
      return InvalidArgumentError("mosaic input: key frame " + std::to_string(k) + " has id " +
                                  std::to_string(static_cast<int>(kf.id)));
    }
    if (kf.frame_index < 0 || static_cast<size_t>(kf.frame_index) >= frames.size()) {
      return InvalidArgumentError("mosaic input: key frame " + std::to_string(k) + " is frame " +
                                  std::to_string(kf.frame_index) + " of " +
                                  std::to_string(frames.size()));
    }
  }
  for (const track::SequentialLink& l : links) {
    if (static_cast<size_t>(l.from) >= key_frames.size() ||
        static_cast<size_t>(l.to) >= key_frames.size()) {
      return InvalidArgumentError("mosaic input: a link joins key frames " +
                                  std::to_string(static_cast<int>(l.from)) + " and " +
                                  std::to_string(static_cast<int>(l.to)) + " of " +
                                  std::to_string(key_frames.size()));
    }
  }
  if (!metadata_corners.empty() && metadata_corners.size() != frames.size()) {
    return InvalidArgumentError("mosaic input: metadata corners for " +
                                std::to_string(metadata_corners.size()) + " frames of " +
                                std::to_string(frames.size()));
  }
  if (!metadata_corners.empty() && !origin) {
    return InvalidArgumentError("mosaic input: metadata corners without a map origin");
  }
  return Status::Ok();
}

}  // namespace saker::mosaic
