#include "core/klv/klv.h"

#include <algorithm>
#include <sstream>

namespace saker::klv {

const UniversalKey kSt0601Key = {{0x06, 0x0E, 0x2B, 0x34, 0x02, 0x0B, 0x01, 0x01, 0x0E, 0x01, 0x03,
                                  0x01, 0x01, 0x00, 0x00, 0x00}};
const UniversalKey kEg0104Key = {{0x06, 0x0E, 0x2B, 0x34, 0x02, 0x01, 0x01, 0x01, 0x0E, 0x01, 0x01,
                                  0x02, 0x01, 0x01, 0x00, 0x00}};
const UniversalKey kSt0903Key = {{0x06, 0x0E, 0x2B, 0x34, 0x02, 0x0B, 0x01, 0x01, 0x0E, 0x01, 0x03,
                                  0x03, 0x06, 0x00, 0x00, 0x00}};

namespace {

constexpr char kHexDigits[] = "0123456789abcdef";

void AppendHexByte(uint8_t byte, std::string* out) {
  out->push_back(kHexDigits[byte >> 4]);
  out->push_back(kHexDigits[byte & 0x0F]);
}

bool StartsWithPrefix(ByteSpan data, size_t pos) {
  return data.size() >= kUniversalKeyPrefix.size() &&
         pos <= data.size() - kUniversalKeyPrefix.size() &&
         std::equal(kUniversalKeyPrefix.begin(), kUniversalKeyPrefix.end(), data.begin() + pos);
}

// The offset of the next universal label prefix at or after `from`, or
// data.size() when there is none.
size_t FindPrefix(ByteSpan data, size_t from) {
  if (from >= data.size()) return data.size();
  auto it = std::search(data.begin() + from, data.end(), kUniversalKeyPrefix.begin(),
                        kUniversalKeyPrefix.end());
  return static_cast<size_t>(it - data.begin());
}

}  // namespace

std::string UniversalKey::ToHex() const {
  std::string out;
  out.reserve(35);
  for (size_t i = 0; i < bytes.size(); ++i) {
    if (i > 0 && i % 4 == 0) out.push_back(' ');
    AppendHexByte(bytes[i], &out);
  }
  return out;
}

bool SameKeyIgnoringVersion(const UniversalKey& a, const UniversalKey& b) {
  for (size_t i = 0; i < a.bytes.size(); ++i) {
    if (i != kKeyVersionByte && a.bytes[i] != b.bytes[i]) return false;
  }
  return true;
}

std::string BytesToHex(ByteSpan data) {
  std::string out;
  out.reserve(data.size() * 2);
  for (uint8_t byte : data) AppendHexByte(byte, &out);
  return out;
}

std::string ToValidUtf8(std::string_view text) {
  static constexpr char kReplacement[] = "\xEF\xBF\xBD";
  std::string out;
  out.reserve(text.size());
  size_t i = 0;
  while (i < text.size()) {
    const auto lead = static_cast<uint8_t>(text[i]);
    size_t extra = 0;
    uint32_t min_code = 0;
    if (lead < 0x80) {
      out.push_back(text[i++]);
      continue;
    } else if ((lead & 0xE0) == 0xC0) {
      extra = 1;
      min_code = 0x80;
    } else if ((lead & 0xF0) == 0xE0) {
      extra = 2;
      min_code = 0x800;
    } else if ((lead & 0xF8) == 0xF0) {
      extra = 3;
      min_code = 0x10000;
    } else {
      out += kReplacement;
      ++i;
      continue;
    }
    bool ok = text.size() - i > extra;
    uint32_t code = lead & (0x3F >> extra);
    for (size_t k = 1; ok && k <= extra; ++k) {
      const auto cont = static_cast<uint8_t>(text[i + k]);
      if ((cont & 0xC0) != 0x80) ok = false;
      code = (code << 6) | (cont & 0x3F);
    }
    // Reject overlong forms, UTF-16 surrogates and code points past U+10FFFF.
    ok = ok && code >= min_code && code <= 0x10FFFF && (code < 0xD800 || code > 0xDFFF);
    if (ok) {
      out.append(text.substr(i, extra + 1));
      i += extra + 1;
    } else {
      out += kReplacement;
      ++i;
    }
  }
  return out;
}

void AppendBerLength(uint64_t n, std::vector<uint8_t>* out) {
  if (n < 0x80) {
    out->push_back(static_cast<uint8_t>(n));
    return;
  }
  size_t count = 0;
  for (uint64_t rest = n; rest != 0; rest >>= 8) ++count;
  out->push_back(static_cast<uint8_t>(0x80 | count));
  for (size_t i = count; i-- > 0;) out->push_back(static_cast<uint8_t>(n >> (8 * i)));
}

StatusOr<uint64_t> ReadBerLength(ByteSpan data, size_t* consumed) {
  if (data.empty()) return InvalidDataError("BER length: no bytes left");
  const uint8_t first = data[0];
  if (first < 0x80) {
    if (consumed != nullptr) *consumed = 1;
    return static_cast<uint64_t>(first);
  }
  const size_t count = first & 0x7F;
  if (count == 0)
    return InvalidDataError("BER length: indefinite form (0x80) is not allowed in KLV");
  if (count > 8) {
    return InvalidDataError("BER length: long form with " + std::to_string(count) +
                            " length bytes (at most 8 supported)");
  }
  if (data.size() - 1 < count) {
    return InvalidDataError("BER length: long form needs " + std::to_string(count) +
                            " length bytes, only " + std::to_string(data.size() - 1) + " left");
  }
  uint64_t length = 0;
  for (size_t i = 1; i <= count; ++i) length = (length << 8) | data[i];
  if (consumed != nullptr) *consumed = 1 + count;
  return length;
}

StatusOr<uint64_t> ReadBerOid(ByteSpan data, size_t* consumed) {
  constexpr size_t kMaxBytes = 4;
  uint64_t value = 0;
  for (size_t i = 0; i < data.size(); ++i) {
    if (i == kMaxBytes) {
      return InvalidDataError("BER-OID tag longer than " + std::to_string(kMaxBytes) + " bytes");
    }
    value = (value << 7) | (data[i] & 0x7F);
    if ((data[i] & 0x80) == 0) {
      if (consumed != nullptr) *consumed = i + 1;
      return value;
    }
  }
  if (data.size() >= kMaxBytes) {
    return InvalidDataError("BER-OID tag longer than " + std::to_string(kMaxBytes) + " bytes");
  }
  return InvalidDataError("BER-OID tag runs past the end of the data");
}

KlvSplitResult SplitKlvPackets(ByteSpan data) {
  KlvSplitResult result;
  size_t pos = 0;
  // Records a failure of the packet that starts at `pos` and moves to the
  // next prefix after it.
  auto resync = [&](const std::string& why) {
    const size_t next = FindPrefix(data, pos + 1);
    std::ostringstream m;
    m << "offset " << pos << ": " << why;
    if (next < data.size()) {
      m << "; resynced at offset " << next;
    } else {
      m << "; no further KLV key in the buffer";
    }
    result.errors.push_back(m.str());
    result.skipped_bytes += next - pos;
    pos = next;
  };

  while (pos < data.size()) {
    if (!StartsWithPrefix(data, pos)) {
      const size_t next = FindPrefix(data, pos);
      std::ostringstream m;
      m << "offset " << pos << ": " << (next - pos) << " bytes of non-KLV data skipped";
      result.errors.push_back(m.str());
      result.skipped_bytes += next - pos;
      pos = next;
      continue;
    }
    const size_t remaining = data.size() - pos;
    if (remaining < 16 + 1) {
      resync("truncated packet: " + std::to_string(remaining) +
             " bytes, not enough for a 16-byte key and a length");
      continue;
    }
    size_t length_bytes = 0;
    auto length = ReadBerLength(data.subspan(pos + 16), &length_bytes);
    if (!length.ok()) {
      resync(length.status().message());
      continue;
    }
    const size_t header = 16 + length_bytes;
    if (*length > remaining - header) {
      resync("length " + std::to_string(*length) + " overruns the buffer (" +
             std::to_string(remaining - header) + " value bytes left)");
      continue;
    }
    const size_t value_size = static_cast<size_t>(*length);
    KlvPacket packet;
    std::copy_n(data.begin() + pos, 16, packet.key.bytes.begin());
    packet.value.assign(data.begin() + pos + header, data.begin() + pos + header + value_size);
    packet.bytes.assign(data.begin() + pos, data.begin() + pos + header + value_size);
    packet.offset = pos;
    result.packets.push_back(std::move(packet));
    pos += header + value_size;
  }
  return result;
}

}  // namespace saker::klv
