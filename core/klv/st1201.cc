#include "core/klv/st1201.h"

#include <cmath>
#include <limits>

namespace saker::klv {

namespace {

// The scale parameters of ST 1201 section 8.1.
struct ImapbParams {
  double forward = 0;   // sF: codes per unit
  double reverse = 0;   // sR: units per code
  double z_offset = 0;  // keeps zero exactly representable when min < 0 < max
};

bool ValidRange(double min, double max, size_t length) {
  return length >= 1 && length <= 8 && std::isfinite(min) && std::isfinite(max) && min < max;
}

ImapbParams Params(double min, double max, size_t length) {
  const int b_pow = static_cast<int>(std::ceil(std::log2(max - min)));
  const int d_pow = static_cast<int>(8 * length) - 1;
  ImapbParams p;
  p.forward = std::ldexp(1.0, d_pow - b_pow);
  p.reverse = std::ldexp(1.0, b_pow - d_pow);
  if (min < 0 && max > 0) p.z_offset = p.forward * min - std::floor(p.forward * min);
  return p;
}

}  // namespace

double ImapbResolution(double min, double max, size_t length) {
  if (!ValidRange(min, max, length)) return 0;
  return Params(min, max, length).reverse;
}

StatusOr<double> DecodeImapb(double min, double max, ByteSpan bytes) {
  if (!ValidRange(min, max, bytes.size())) {
    return InvalidDataError("IMAPB: " + std::to_string(bytes.size()) +
                            " bytes cannot be decoded (1 to 8 bytes and min < max needed)");
  }
  uint64_t code = 0;
  for (uint8_t b : bytes) code = (code << 8) | b;
  const int bits = static_cast<int>(8 * bytes.size());
  const uint64_t msb = uint64_t{1} << (bits - 1);
  if ((code & msb) != 0 && code != msb) {
    // Special values use the top five bits: 1 1 s t t with s the sign and tt
    // 01 infinity, 10 quiet NaN, 11 signalling NaN; 10xxx is reserved. With
    // one byte the five bits still fit.
    const unsigned top = static_cast<unsigned>(code >> (bits - 5)) & 0x1F;
    if (top == 0b11001) return std::numeric_limits<double>::infinity();
    if (top == 0b11101) return -std::numeric_limits<double>::infinity();
    return std::numeric_limits<double>::quiet_NaN();
  }
  const ImapbParams p = Params(min, max, bytes.size());
  return p.reverse * (static_cast<double>(code) - p.z_offset) + min;
}

}  // namespace saker::klv
