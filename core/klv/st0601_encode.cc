#include "core/klv/st0601_encode.h"

#include "core/klv/st0601.h"
#include "core/klv/st0601_tags.h"
#include "core/klv/st1201.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>
#include <utility>

namespace saker::klv {

namespace {

using internal::FindTagSpec;
using internal::Mapping;
using internal::TagSpec;

// The largest tag a four-byte BER-OID holds: as far as ReadBerOid reads.
constexpr uint32_t kMaxBerOidTag = (uint32_t{1} << 28) - 1;

// Shortest text that reads back as `v`, so a message never shows a rounded
// value that looks in range.
std::string NumberText(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

Status Refuse(std::string why) { return InvalidArgumentError(std::move(why)); }

// What a tag holds and which call writes it, for "wrong type" messages.
std::string Expects(const TagSpec* spec) {
  if (spec == nullptr) return "is not an ST 0601.17 tag (use AddRaw)";
  switch (spec->mapping) {
    case Mapping::kRaw:
      return "is kept raw (use AddRaw)";
    case Mapping::kString:
      return "holds text (use AddString)";
    case Mapping::kUint:
      return "holds an unsigned integer (use AddUnsigned)";
    case Mapping::kInt:
      return "holds a signed integer (use AddSigned)";
    case Mapping::kUnsignedMap:
    case Mapping::kSignedMap:
    case Mapping::kImapb:
      return "holds a number in its unit (use Add)";
    case Mapping::kChecksum:
      return "is the checksum, written by Finish()";
  }
  return "";
}

Status WrongType(const TagSpec* spec, const std::string& got) {
  return Refuse("wrong type: got " + got + ", but the tag " + Expects(spec));
}

std::string Bytes(size_t n) { return std::to_string(n) + (n == 1 ? " byte" : " bytes"); }

// The length to write for a fixed-length mapping: `length` must be 0 or the
// fixed length.
StatusOr<size_t> FixedLength(const TagSpec& spec, size_t length) {
  if (length != 0 && length != spec.length) {
    return Refuse("bad length " + std::to_string(length) + ": the tag takes exactly " +
                  Bytes(spec.length));
  }
  return spec.length;
}

// Checks a caller's length for a variable-length item: 1..spec.length.
Status CheckVariableLength(const TagSpec& spec, size_t length) {
  if (length < 1 || length > spec.length) {
    return Refuse("bad length " + std::to_string(length) + ": the tag takes 1 to " +
                  Bytes(spec.length));
  }
  return Status::Ok();
}

std::vector<uint8_t> BigEndian(uint64_t v, size_t length) {
  std::vector<uint8_t> bytes(length);
  for (size_t i = 0; i < length; ++i) bytes[length - 1 - i] = static_cast<uint8_t>(v >> (8 * i));
  return bytes;
}

bool FitsUnsigned(uint64_t v, size_t length) { return length >= 8 || (v >> (8 * length)) == 0; }

bool FitsSigned(int64_t v, size_t length) {
  if (length >= 8) return true;
  const int64_t limit = int64_t{1} << (8 * length - 1);
  return v >= -limit && v < limit;
}

StatusOr<std::vector<uint8_t>> EncodeNumber(const TagSpec* spec, double value, size_t length) {
  if (spec == nullptr ||
      (spec->mapping != Mapping::kUnsignedMap && spec->mapping != Mapping::kSignedMap &&
       spec->mapping != Mapping::kImapb)) {
    return WrongType(spec, "the number " + NumberText(value));
  }
  if (!std::isfinite(value)) {
    return Refuse("value " + NumberText(value) +
                  " is not a finite number (use AddAbsent for a missing value)");
  }
  const double low = spec->mapping == Mapping::kSignedMap ? -spec->max : spec->min;
  const double high = spec->max;
  if (value < low || value > high) {
    return Refuse("value " + NumberText(value) + " is out of the mapping's range [" +
                  NumberText(low) + ", " + NumberText(high) + "]");
  }
  switch (spec->mapping) {
    case Mapping::kUnsignedMap: {
      auto n = FixedLength(*spec, length);
      if (!n.ok()) return n.status();
      // The decoder's code * (max - min) / (2^n - 1) + min, inverted.
      const double codes = std::ldexp(1.0, static_cast<int>(8 * *n)) - 1;
      const long long code = std::llround((value - spec->min) * codes / (spec->max - spec->min));
      SAKER_CHECK(code >= 0 && static_cast<double>(code) <= codes) << value;
      return BigEndian(static_cast<uint64_t>(code), *n);
    }
    case Mapping::kSignedMap: {
      auto n = FixedLength(*spec, length);
      if (!n.ok()) return n.status();
      // The decoder's code * 2 max / (2^n - 2), inverted. |value| <= max
      // keeps the code within +/-(2^(n-1) - 1), so the error indicator
      // -2^(n-1) is never produced by a value.
      const double steps = std::ldexp(1.0, static_cast<int>(8 * *n)) - 2;
      const long long code = std::llround(value * steps / (2 * spec->max));
      SAKER_CHECK(std::abs(static_cast<double>(code)) <= steps / 2) << value;
      return BigEndian(static_cast<uint64_t>(code), *n);
    }
    case Mapping::kImapb: {
      const size_t n = length == 0 ? spec->default_length : length;
      SAKER_RETURN_IF_ERROR(CheckVariableLength(*spec, n));
      return EncodeImapb(spec->min, spec->max, n, value);
    }
    default:
      break;
  }
  return WrongType(spec, "the number " + NumberText(value));
}

// The item length for an integer value: the tag's fixed length, the length asked for, or (0 for
// a variable-length tag) the shortest that holds the value; a value too big for the longest is
// refused by the caller.
template <typename Fits>
StatusOr<size_t> IntegerLength(const TagSpec& spec, size_t length, Fits fits) {
  size_t n = length;
  if (!spec.variable_length) {
    SAKER_ASSIGN_OR_RETURN(n, FixedLength(spec, length));
  } else if (n == 0) {
    n = 1;
    while (n < spec.length && !fits(n)) ++n;
  }
  SAKER_RETURN_IF_ERROR(CheckVariableLength(spec, n));
  return n;
}

StatusOr<std::vector<uint8_t>> EncodeUnsigned(const TagSpec* spec, uint64_t value, size_t length) {
  if (spec == nullptr || spec->mapping != Mapping::kUint) {
    return WrongType(spec, "the unsigned integer " + std::to_string(value));
  }
  SAKER_ASSIGN_OR_RETURN(const size_t n, IntegerLength(*spec, length, [&](size_t k) {
                           return FitsUnsigned(value, k);
                         }));
  if (!FitsUnsigned(value, n)) {
    return Refuse("value " + std::to_string(value) + " does not fit in " + Bytes(n));
  }
  return BigEndian(value, n);
}

StatusOr<std::vector<uint8_t>> EncodeSigned(const TagSpec* spec, int64_t value, size_t length) {
  if (spec == nullptr || spec->mapping != Mapping::kInt) {
    return WrongType(spec, "the signed integer " + std::to_string(value));
  }
  SAKER_ASSIGN_OR_RETURN(
      const size_t n, IntegerLength(*spec, length, [&](size_t k) { return FitsSigned(value, k); }));
  if (!FitsSigned(value, n)) {
    return Refuse("value " + std::to_string(value) + " does not fit in " + Bytes(n));
  }
  return BigEndian(static_cast<uint64_t>(value), n);
}

StatusOr<std::vector<uint8_t>> EncodeText(const TagSpec* spec, std::string_view text) {
  // Messages quote at most this much of the text.
  constexpr size_t kQuoted = 24;
  // Only built for error messages.
  const auto quoted = [&] {
    return "\"" + ToValidUtf8(text.substr(0, kQuoted)) + (text.size() > kQuoted ? "...\"" : "\"");
  };
  if (spec == nullptr || spec->mapping != Mapping::kString) {
    return WrongType(spec, "the text " + quoted());
  }
  if (text.empty()) {
    return Refuse(
        "empty text: a zero-length item means \"no value\" in MISB KLV (use AddAbsent for that)");
  }
  if (text.size() > spec->length) {
    return Refuse("text " + quoted() + " of " + Bytes(text.size()) + " is longer than the " +
                  std::to_string(spec->length) + " the tag allows");
  }
  return std::vector<uint8_t>(text.begin(), text.end());
}

StatusOr<std::vector<uint8_t>> EncodeAbsent(const TagSpec* spec) {
  if (spec == nullptr) {
    return Refuse(
        "\"no value\" for a tag ST 0601.17 does not define (use AddRaw with no bytes for an "
        "empty item)");
  }
  if (spec->mapping == Mapping::kSignedMap) {
    // The error indicator: the most negative code, which no value maps to.
    return BigEndian(uint64_t{1} << (8 * spec->length - 1), spec->length);
  }
  // Every other mapping has no indicator of its own; a zero-length item is
  // MISB's general "value unknown" (and what the decoder reads as Absent).
  return std::vector<uint8_t>{};
}

void AppendBerOid(uint32_t tag, std::vector<uint8_t>* out) {
  size_t groups = 1;
  while (groups < 5 && (tag >> (7 * groups)) != 0) ++groups;
  for (size_t i = groups; i-- > 0;) {
    const auto bits = static_cast<uint8_t>((tag >> (7 * i)) & 0x7F);
    out->push_back(i > 0 ? static_cast<uint8_t>(bits | 0x80) : bits);
  }
}

}  // namespace

St0601Encoder& St0601Encoder::Add(uint32_t tag, double value, size_t length) {
  return Append(tag, EncodeNumber(FindTagSpec(tag), value, length));
}

St0601Encoder& St0601Encoder::AddUnsigned(uint32_t tag, uint64_t value, size_t length) {
  return Append(tag, EncodeUnsigned(FindTagSpec(tag), value, length));
}

St0601Encoder& St0601Encoder::AddSigned(uint32_t tag, int64_t value, size_t length) {
  return Append(tag, EncodeSigned(FindTagSpec(tag), value, length));
}

St0601Encoder& St0601Encoder::AddString(uint32_t tag, std::string_view text) {
  return Append(tag, EncodeText(FindTagSpec(tag), text));
}

St0601Encoder& St0601Encoder::AddAbsent(uint32_t tag) {
  return Append(tag, EncodeAbsent(FindTagSpec(tag)));
}

St0601Encoder& St0601Encoder::AddRaw(uint32_t tag, ByteSpan bytes) {
  return Append(tag, std::vector<uint8_t>(bytes.begin(), bytes.end()));
}

St0601Encoder& St0601Encoder::Append(uint32_t tag, StatusOr<std::vector<uint8_t>> value) {
  ++calls_;
  if (!error_.ok()) return *this;
  auto fail = [&](const std::string& why) -> St0601Encoder& {
    error_ = InvalidArgumentError("ST 0601 item " + std::to_string(calls_) + ", tag " +
                                  std::to_string(tag) + " (" + St0601TagName(tag) + "): " + why);
    return *this;
  };
  // The tag checks come first: "tag 1 added by hand" says more than the
  // type mismatch the same call also makes.
  if (tag == 0) return fail("tag 0 is not a local set tag");
  if (tag == 1) return fail("the checksum is computed by Finish(); do not add it");
  if (tag > kMaxBerOidTag) return fail("tag is beyond a four-byte BER-OID");
  if (!value.ok()) return fail(value.status().message());
  const TagSpec* spec = FindTagSpec(tag);
  if (spec != nullptr && !spec->multiples &&
      std::any_of(items_.begin(), items_.end(), [tag](const Item& i) { return i.tag == tag; })) {
    return fail("added twice; ST 0601.17 allows the tag once per packet");
  }
  items_.push_back({tag, std::move(value).value()});
  return *this;
}

StatusOr<std::vector<uint8_t>> St0601Encoder::Finish() const {
  if (!error_.ok()) return error_;
  // ST 0601.17 makes these two mandatory in every packet (with the
  // checksum). A zero-length item does not count: a packet whose time or
  // version is "unknown" cannot be interpreted.
  for (uint32_t mandatory : {2u, 65u}) {
    if (std::none_of(items_.begin(), items_.end(), [mandatory](const Item& i) {
          return i.tag == mandatory && !i.value.empty();
        })) {
      return InvalidArgumentError("ST 0601 packet without a value for tag " +
                                  std::to_string(mandatory) + " (" + St0601TagName(mandatory) +
                                  "), which ST 0601.17 makes mandatory");
    }
  }
  std::vector<uint8_t> value;
  for (const Item& item : items_) {
    AppendBerOid(item.tag, &value);
    AppendBerLength(item.value.size(), &value);
    value.insert(value.end(), item.value.begin(), item.value.end());
  }
  // The checksum item goes last, and its two value bytes are the only ones
  // the checksum does not cover.
  value.insert(value.end(), {0x01, 0x02, 0x00, 0x00});

  std::vector<uint8_t> packet(kSt0601Key.bytes.begin(), kSt0601Key.bytes.end());
  AppendBerLength(value.size(), &packet);
  packet.insert(packet.end(), value.begin(), value.end());
  const uint16_t bcc = Bcc16(ByteSpan(packet).first(packet.size() - 2));
  packet[packet.size() - 2] = static_cast<uint8_t>(bcc >> 8);
  packet[packet.size() - 1] = static_cast<uint8_t>(bcc & 0xFF);
  return packet;
}

}  // namespace saker::klv
