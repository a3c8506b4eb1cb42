#include "core/klv/st1201.h"

#include <charconv>
#include <cmath>
#include <limits>
#include <string>

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

// Shortest text that reads back as `v`, for error messages.
std::string NumberText(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
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

StatusOr<std::vector<uint8_t>> EncodeImapb(double min, double max, size_t length, double value) {
  if (!ValidRange(min, max, length)) {
    return InvalidArgumentError("IMAPB: cannot encode in " + std::to_string(length) +
                                " bytes onto [" + NumberText(min) + ", " + NumberText(max) +
                                "] (1 to 8 bytes and min < max needed)");
  }
  if (!std::isfinite(value)) {
    return InvalidArgumentError("IMAPB: value " + NumberText(value) + " is not a finite number");
  }
  if (value < min || value > max) {
    return InvalidArgumentError("IMAPB: value " + NumberText(value) + " is outside [" +
                                NumberText(min) + ", " + NumberText(max) + "]");
  }
  const ImapbParams p = Params(min, max, length);
  const int bits = static_cast<int>(8 * length);
  const uint64_t msb = uint64_t{1} << (bits - 1);
  // sF * (max - min) <= 2^(8 * length - 1), so every value in range maps to
  // at most the MSB-alone code, the largest normal one. Only the zero offset
  // can lift the rounded code past it, and then the floor (ST 1201's own
  // rule), which is the MSB-alone code, is the nearest valid one. Codes with
  // the MSB and any other bit set are special values and never written.
  const double scaled = p.forward * (value - min) + p.z_offset;
  uint64_t code = static_cast<uint64_t>(std::floor(scaled + 0.5));
  if (code > msb) code = static_cast<uint64_t>(std::floor(scaled));
  if (code > msb) {
    // Only reachable when rounding in log2 misjudges a range a hair wider
    // than a power of two; refuse rather than write a special value.
    return InvalidArgumentError("IMAPB: value " + NumberText(value) + " does not fit in " +
                                std::to_string(length) + " bytes onto [" + NumberText(min) + ", " +
                                NumberText(max) + "]");
  }
  std::vector<uint8_t> bytes(length);
  for (size_t i = 0; i < length; ++i) {
    bytes[length - 1 - i] = static_cast<uint8_t>(code >> (8 * i));
  }
  return bytes;
}

}  // namespace saker::klv
