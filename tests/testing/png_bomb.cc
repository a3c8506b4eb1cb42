#include "tests/testing/png_bomb.h"

#include <array>
#include <string>

namespace saker::testing {
namespace {

uint32_t Crc32(const uint8_t* data, size_t size) {
  uint32_t crc = 0xffffffffU;
  for (size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xedb88320U & (0U - (crc & 1U)));
  }
  return crc ^ 0xffffffffU;
}

void PutBigEndian(uint32_t value, std::vector<uint8_t>* out) {
  for (int shift = 24; shift >= 0; shift -= 8) out->push_back(static_cast<uint8_t>(value >> shift));
}

void PutChunk(const std::string& type, const std::vector<uint8_t>& data,
              std::vector<uint8_t>* out) {
  PutBigEndian(static_cast<uint32_t>(data.size()), out);
  std::vector<uint8_t> typed(type.begin(), type.end());
  typed.insert(typed.end(), data.begin(), data.end());
  out->insert(out->end(), typed.begin(), typed.end());
  PutBigEndian(Crc32(typed.data(), typed.size()), out);
}

}  // namespace

std::vector<uint8_t> PngBomb(uint32_t width, uint32_t height) {
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<uint8_t> header;
  PutBigEndian(width, &header);
  PutBigEndian(height, &header);
  // 8 bits, colour type 6 (RGBA), deflate, adaptive filtering, no interlace.
  header.insert(header.end(), {8, 6, 0, 0, 0});
  PutChunk("IHDR", header, &png);
  // A zlib stream of one stored block of 16 zero bytes (the first row's start).
  constexpr uint8_t kZeros = 16;
  std::vector<uint8_t> data = {0x78, 0x01, 0x01, kZeros, 0x00, static_cast<uint8_t>(~kZeros), 0xff};
  data.insert(data.end(), kZeros, 0);
  PutBigEndian((static_cast<uint32_t>(kZeros) << 16) | 1U, &data);  // Adler-32 of the zeros
  PutChunk("IDAT", data, &png);
  PutChunk("IEND", {}, &png);
  return png;
}

}  // namespace saker::testing
