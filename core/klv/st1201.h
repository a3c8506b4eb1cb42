#pragma once

// MISB ST 1201 floating-point to integer mapping, reverse direction only
// (IMAPB: the caller gives the range and the byte count). ST 0601 uses it for
// its newer tags (96, 103-105, 109, 112-114, 117-120, 132, 134).

#include "core/klv/klv.h"
#include "core/util/status.h"

namespace saker::klv {

// Decodes `bytes` (1 to 8 bytes, big-endian) mapped onto [min, max] with
// MISB ST 1201 IMAPB. Special values come back as IEEE specials: +/- infinity
// for the infinity patterns, a quiet NaN for the NaN and reserved patterns
// (MSB set, any pattern other than the all-zero "maximum" one). Errors: no
// bytes, more than 8 bytes, or min >= max.
StatusOr<double> DecodeImapb(double min, double max, ByteSpan bytes);

// The step between two adjacent IMAPB codes for this range and length (the
// reverse scale factor of ST 1201), or 0 for an invalid range or length.
double ImapbResolution(double min, double max, size_t length);

}  // namespace saker::klv
