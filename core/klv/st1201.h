#pragma once

// MISB ST 1201 floating-point to integer mapping, IMAPB form (the caller
// gives the range and the byte count). ST 0601 uses it for its newer tags
// (96, 103-105, 109, 112-114, 117-120, 132, 134).

#include "core/klv/klv.h"
#include "core/util/status.h"

#include <cstdint>
#include <vector>

namespace saker::klv {

// Decodes `bytes` (1 to 8 bytes, big-endian) mapped onto [min, max] with
// MISB ST 1201 IMAPB. Special values come back as IEEE specials: +/- infinity
// for the infinity patterns, a quiet NaN for the NaN and reserved patterns
// (MSB set, any pattern other than the all-zero "maximum" one). Errors: no
// bytes, more than 8 bytes, or min >= max.
StatusOr<double> DecodeImapb(double min, double max, ByteSpan bytes);

// Encodes `value` in `length` bytes (1 to 8, big-endian) mapped onto
// [min, max]: the forward mapping of ST 1201, rounded to the nearest code.
// (ST 1201 writes the forward mapping with a floor; any code is a valid
// encoding for a decoder, and rounding halves the worst error and makes
// DecodeImapb followed by EncodeImapb give back every code exactly.)
// Errors: a value outside [min, max] (never clamped), NaN or infinity (the
// ST 1201 special values are not written), a bad length, or min >= max.
StatusOr<std::vector<uint8_t>> EncodeImapb(double min, double max, size_t length, double value);

// The step between two adjacent IMAPB codes for this range and length (the
// reverse scale factor of ST 1201), or 0 for an invalid range or length.
double ImapbResolution(double min, double max, size_t length);

}  // namespace saker::klv
