#pragma once

// Decompression bombs for the image decoders: a small, well-formed PNG whose header declares a
// huge picture (what a hostile mission file may hold in a tile or checkpoint record).

#include <cstdint>
#include <vector>

namespace saker::testing {

// About 100 bytes: a PNG of `width` x `height` 8-bit BGRA pixels as far as its header (IHDR, with
// a correct CRC) says, followed by a short image data chunk and the end chunk. A decoder that
// trusts the header allocates width x height x 4 bytes before it finds the data missing.
std::vector<uint8_t> PngBomb(uint32_t width, uint32_t height);

}  // namespace saker::testing
