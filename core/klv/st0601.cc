#include "core/klv/st0601.h"

#include "core/klv/st0601_tags.h"
#include "core/klv/st1201.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace saker::klv {

namespace {

using internal::FindTagSpec;
using internal::Mapping;
using internal::TagSpec;

uint64_t ReadUnsigned(ByteSpan raw) {
  uint64_t v = 0;
  for (uint8_t b : raw) v = (v << 8) | b;
  return v;
}

// Two's complement of `raw` (1..8 bytes), sign-extended.
int64_t ReadSigned(ByteSpan raw) {
  const uint64_t v = ReadUnsigned(raw);
  const int bits = static_cast<int>(8 * raw.size());
  if (bits == 64) return static_cast<int64_t>(v);
  const uint64_t sign = uint64_t{1} << (bits - 1);
  if ((v & sign) == 0) return static_cast<int64_t>(v);
  return static_cast<int64_t>(v) - static_cast<int64_t>(uint64_t{1} << bits);
}

double UnsignedMapStep(const TagSpec& spec) {
  return (spec.max - spec.min) / (std::ldexp(1.0, static_cast<int>(8 * spec.length)) - 1);
}

double SignedMapStep(const TagSpec& spec) {
  return 2 * spec.max / (std::ldexp(1.0, static_cast<int>(8 * spec.length)) - 2);
}

std::string LengthWarning(const TagSpec& spec, size_t got, const char* expected) {
  std::ostringstream m;
  m << "tag " << spec.tag << " (" << spec.name << "): length " << got << ", expected " << expected
    << "; kept raw";
  return m.str();
}

}  // namespace

uint16_t Bcc16(ByteSpan data) {
  uint16_t bcc = 0;
  for (size_t i = 0; i < data.size(); ++i) {
    bcc = static_cast<uint16_t>(bcc + (i % 2 == 0 ? data[i] << 8 : data[i]));
  }
  return bcc;
}

const char* St0601TagName(uint32_t tag) {
  const TagSpec* spec = FindTagSpec(tag);
  return spec != nullptr ? spec->name : "Unknown tag";
}

std::optional<double> St0601Resolution(uint32_t tag, size_t length) {
  const TagSpec* spec = FindTagSpec(tag);
  if (spec == nullptr) return std::nullopt;
  switch (spec->mapping) {
    case Mapping::kUint:
    case Mapping::kInt:
    case Mapping::kChecksum:
      return 1.0;
    case Mapping::kUnsignedMap:
      return UnsignedMapStep(*spec);
    case Mapping::kSignedMap:
      return SignedMapStep(*spec);
    case Mapping::kImapb: {
      const double step = ImapbResolution(spec->min, spec->max, length);
      return step > 0 ? std::optional<double>(step) : std::nullopt;
    }
    case Mapping::kRaw:
    case Mapping::kString:
      return std::nullopt;
  }
  return std::nullopt;
}

St0601Value DecodeSt0601Value(uint32_t tag, ByteSpan raw, std::string* warning) {
  const TagSpec* spec = FindTagSpec(tag);
  if (spec == nullptr || spec->mapping == Mapping::kRaw) return std::monostate{};
  // An empty item carries no value, whatever its mapping.
  if (raw.empty()) return Absent{};
  auto reject = [&](const char* expected) -> St0601Value {
    if (warning != nullptr) *warning = LengthWarning(*spec, raw.size(), expected);
    return std::monostate{};
  };
  switch (spec->mapping) {
    case Mapping::kString:
      return std::string(raw.begin(), raw.end());
    case Mapping::kChecksum:
      if (raw.size() != 2) return reject("2");
      return ReadUnsigned(raw);
    case Mapping::kUint:
      if (raw.size() > spec->length) {
        return reject(("1 to " + std::to_string(spec->length)).c_str());
      }
      return ReadUnsigned(raw);
    case Mapping::kInt:
      if (raw.size() > spec->length) {
        return reject(("1 to " + std::to_string(spec->length)).c_str());
      }
      return ReadSigned(raw);
    case Mapping::kUnsignedMap:
      if (raw.size() != spec->length) return reject(std::to_string(spec->length).c_str());
      return static_cast<double>(ReadUnsigned(raw)) * (spec->max - spec->min) /
                 (std::ldexp(1.0, static_cast<int>(8 * spec->length)) - 1) +
             spec->min;
    case Mapping::kSignedMap: {
      if (raw.size() != spec->length) return reject(std::to_string(spec->length).c_str());
      const int64_t v = ReadSigned(raw);
      const int64_t error_indicator = -(int64_t{1} << (8 * spec->length - 1));
      if (v == error_indicator) return Absent{};
      return static_cast<double>(v) * (2 * spec->max) /
             (std::ldexp(1.0, static_cast<int>(8 * spec->length)) - 2);
    }
    case Mapping::kImapb: {
      if (raw.size() > 8) return reject("1 to 8");
      auto v = DecodeImapb(spec->min, spec->max, raw);
      if (!v.ok() || !std::isfinite(*v)) return Absent{};
      return *v;
    }
    case Mapping::kRaw:
      break;
  }
  return std::monostate{};
}

const St0601Item* St0601Set::Find(uint32_t tag) const {
  for (const auto& item : items) {
    if (item.tag == tag) return &item;
  }
  return nullptr;
}

std::optional<double> St0601Set::GetDouble(uint32_t tag) const {
  const St0601Item* item = Find(tag);
  if (item == nullptr) return std::nullopt;
  if (auto* d = std::get_if<double>(&item->value)) return *d;
  if (auto* i = std::get_if<int64_t>(&item->value)) return static_cast<double>(*i);
  if (auto* u = std::get_if<uint64_t>(&item->value)) return static_cast<double>(*u);
  return std::nullopt;
}

std::optional<std::string> St0601Set::GetString(uint32_t tag) const {
  const St0601Item* item = Find(tag);
  if (item == nullptr) return std::nullopt;
  if (auto* s = std::get_if<std::string>(&item->value)) return *s;
  return std::nullopt;
}

std::optional<uint64_t> St0601Set::GetUnsigned(uint32_t tag) const {
  const St0601Item* item = Find(tag);
  if (item == nullptr) return std::nullopt;
  if (auto* u = std::get_if<uint64_t>(&item->value)) return *u;
  return std::nullopt;
}

StatusOr<St0601Set> DecodeSt0601(const KlvPacket& packet) {
  if (!SameKeyIgnoringVersion(packet.key, kSt0601Key)) {
    return InvalidArgumentError("not a MISB ST 0601 packet: key " + packet.key.ToHex());
  }
  const ByteSpan value(packet.value);

  // The checksum runs over the packet as sent, so use its bytes when they
  // hold this value; otherwise rebuild key + shortest BER length + value.
  std::vector<uint8_t> rebuilt;
  ByteSpan whole(packet.bytes);
  if (whole.size() < value.size() + 17 ||
      !std::equal(value.begin(), value.end(), whole.end() - value.size())) {
    rebuilt.assign(packet.key.bytes.begin(), packet.key.bytes.end());
    AppendBerLength(value.size(), &rebuilt);
    rebuilt.insert(rebuilt.end(), value.begin(), value.end());
    whole = rebuilt;
  }
  const size_t header_size = whole.size() - value.size();

  St0601Set set;
  std::optional<size_t> checksum_value_offset;  // in `value`
  size_t pos = 0;
  while (pos < value.size()) {
    size_t tag_size = 0;
    auto tag = ReadBerOid(value.subspan(pos), &tag_size);
    if (!tag.ok()) {
      set.warnings.push_back("offset " + std::to_string(pos) + ": " + tag.status().message() +
                             "; rest of the set ignored");
      break;
    }
    size_t length_size = 0;
    auto length = ReadBerLength(value.subspan(pos + tag_size), &length_size);
    if (!length.ok()) {
      set.warnings.push_back("tag " + std::to_string(*tag) + ": " + length.status().message() +
                             "; rest of the set ignored");
      break;
    }
    const size_t start = pos + tag_size + length_size;
    if (*length > value.size() - start) {
      set.warnings.push_back("tag " + std::to_string(*tag) + ": length " + std::to_string(*length) +
                             " overruns the set (" + std::to_string(value.size() - start) +
                             " bytes left); rest of the set ignored");
      break;
    }
    St0601Item item;
    item.tag = static_cast<uint32_t>(*tag);
    const ByteSpan raw = value.subspan(start, static_cast<size_t>(*length));
    item.raw.assign(raw.begin(), raw.end());
    std::string warning;
    item.value = DecodeSt0601Value(item.tag, raw, &warning);
    if (!warning.empty()) set.warnings.push_back(std::move(warning));
    if (item.tag == 1) {
      if (auto* stored = std::get_if<uint64_t>(&item.value)) {
        set.stored_checksum = static_cast<uint16_t>(*stored);
        checksum_value_offset = start;
      }
    }
    set.items.push_back(std::move(item));
    pos = start + raw.size();
  }

  if (set.items.empty() && !value.empty()) {
    return InvalidDataError("ST 0601 set of " + std::to_string(value.size()) +
                            " bytes has no readable item: " + set.warnings.front());
  }

  if (checksum_value_offset) {
    set.computed_checksum = Bcc16(whole.first(header_size + *checksum_value_offset));
    set.checksum_ok = set.computed_checksum == *set.stored_checksum;
    if (!set.checksum_ok) {
      std::ostringstream m;
      m << std::hex << "checksum mismatch: stored 0x" << *set.stored_checksum << ", computed 0x"
        << set.computed_checksum;
      set.warnings.push_back(m.str());
    }
    if (set.items.back().tag != 1) set.warnings.push_back("checksum (tag 1) is not the last item");
  } else {
    set.computed_checksum = Bcc16(whole);
    set.warnings.push_back("no checksum (tag 1) in the set; checksum not verified");
  }
  return set;
}

nlohmann::json St0601ValueToJson(const St0601Value& value) {
  using nlohmann::json;
  struct Visitor {
    json operator()(std::monostate) const { return nullptr; }
    json operator()(Absent) const { return "absent"; }
    json operator()(double v) const { return v; }
    json operator()(int64_t v) const { return v; }
    json operator()(uint64_t v) const { return v; }
    json operator()(const std::string& v) const { return ToValidUtf8(v); }
  };
  return std::visit(Visitor{}, value);
}

nlohmann::json St0601ToJson(const St0601Set& set) {
  using nlohmann::json;
  json items = json::array();
  for (const auto& item : set.items) {
    items.push_back({{"tag", item.tag},
                     {"name", St0601TagName(item.tag)},
                     {"value", St0601ValueToJson(item.value)},
                     {"raw", BytesToHex(item.raw)}});
  }
  auto hex16 = [](uint16_t v) {
    std::ostringstream s;
    s << std::hex;
    s.width(4);
    s.fill('0');
    s << v;
    return s.str();
  };
  json checksum = {{"stored", set.stored_checksum ? json(hex16(*set.stored_checksum)) : json()},
                   {"computed", hex16(set.computed_checksum)},
                   {"ok", set.checksum_ok}};
  json warnings = json::array();
  for (const auto& w : set.warnings) warnings.push_back(ToValidUtf8(w));
  return {{"items", std::move(items)}, {"checksum", std::move(checksum)}, {"warnings", warnings}};
}

}  // namespace saker::klv
