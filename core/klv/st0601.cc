#include "core/klv/st0601.h"

#include "core/klv/st1201.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace saker::klv {

namespace {

// How a tag's value bytes turn into a St0601Value.
enum class Mapping {
  kRaw,          // kept as bytes (nested sets, packs, lists)
  kString,       // text
  kUint,         // big-endian unsigned, 1..length bytes
  kInt,          // big-endian two's complement, 1..length bytes
  kUnsignedMap,  // exactly `length` bytes, 0..2^n-1 onto [min, max]
  kSignedMap,    // exactly `length` bytes, -(2^(n-1)-1)..2^(n-1)-1 onto [-max, max];
                 // -2^(n-1) is the error indicator
  kImapb,        // MISB ST 1201 IMAPB onto [min, max], 1..8 bytes
  kChecksum,     // tag 1, exactly 2 bytes
};

struct TagSpec {
  uint32_t tag = 0;
  const char* name = nullptr;
  Mapping mapping = Mapping::kRaw;
  size_t length = 0;  // fixed length, or the maximum for integers
  double min = 0;
  double max = 0;
};

constexpr uint32_t kMaxTag = 143;

// ST 0601.17, tags 1-143. Tag 66 is deprecated and tag 98 (Geo-Registration
// Local Set) only appears inside the Amend set.
constexpr TagSpec kTagSpecs[] = {
    {1, "Checksum", Mapping::kChecksum, 2},
    {2, "Precision Time Stamp", Mapping::kUint, 8},
    {3, "Mission ID", Mapping::kString},
    {4, "Platform Tail Number", Mapping::kString},
    {5, "Platform Heading Angle", Mapping::kUnsignedMap, 2, 0, 360},
    {6, "Platform Pitch Angle", Mapping::kSignedMap, 2, 0, 20},
    {7, "Platform Roll Angle", Mapping::kSignedMap, 2, 0, 50},
    {8, "Platform True Airspeed", Mapping::kUint, 1},
    {9, "Platform Indicated Airspeed", Mapping::kUint, 1},
    {10, "Platform Designation", Mapping::kString},
    {11, "Image Source Sensor", Mapping::kString},
    {12, "Image Coordinate System", Mapping::kString},
    {13, "Sensor Latitude", Mapping::kSignedMap, 4, 0, 90},
    {14, "Sensor Longitude", Mapping::kSignedMap, 4, 0, 180},
    {15, "Sensor True Altitude", Mapping::kUnsignedMap, 2, -900, 19000},
    {16, "Sensor Horizontal Field of View", Mapping::kUnsignedMap, 2, 0, 180},
    {17, "Sensor Vertical Field of View", Mapping::kUnsignedMap, 2, 0, 180},
    {18, "Sensor Relative Azimuth Angle", Mapping::kUnsignedMap, 4, 0, 360},
    {19, "Sensor Relative Elevation Angle", Mapping::kSignedMap, 4, 0, 180},
    {20, "Sensor Relative Roll Angle", Mapping::kUnsignedMap, 4, 0, 360},
    {21, "Slant Range", Mapping::kUnsignedMap, 4, 0, 5000000},
    {22, "Target Width", Mapping::kUnsignedMap, 2, 0, 10000},
    {23, "Frame Center Latitude", Mapping::kSignedMap, 4, 0, 90},
    {24, "Frame Center Longitude", Mapping::kSignedMap, 4, 0, 180},
    {25, "Frame Center Elevation", Mapping::kUnsignedMap, 2, -900, 19000},
    {26, "Offset Corner Latitude Point 1", Mapping::kSignedMap, 2, 0, 0.075},
    {27, "Offset Corner Longitude Point 1", Mapping::kSignedMap, 2, 0, 0.075},
    {28, "Offset Corner Latitude Point 2", Mapping::kSignedMap, 2, 0, 0.075},
    {29, "Offset Corner Longitude Point 2", Mapping::kSignedMap, 2, 0, 0.075},
    {30, "Offset Corner Latitude Point 3", Mapping::kSignedMap, 2, 0, 0.075},
    {31, "Offset Corner Longitude Point 3", Mapping::kSignedMap, 2, 0, 0.075},
    {32, "Offset Corner Latitude Point 4", Mapping::kSignedMap, 2, 0, 0.075},
    {33, "Offset Corner Longitude Point 4", Mapping::kSignedMap, 2, 0, 0.075},
    {34, "Icing Detected", Mapping::kUint, 1},
    {35, "Wind Direction", Mapping::kUnsignedMap, 2, 0, 360},
    {36, "Wind Speed", Mapping::kUnsignedMap, 1, 0, 100},
    {37, "Static Pressure", Mapping::kUnsignedMap, 2, 0, 5000},
    {38, "Density Altitude", Mapping::kUnsignedMap, 2, -900, 19000},
    {39, "Outside Air Temperature", Mapping::kInt, 1},
    {40, "Target Location Latitude", Mapping::kSignedMap, 4, 0, 90},
    {41, "Target Location Longitude", Mapping::kSignedMap, 4, 0, 180},
    {42, "Target Location Elevation", Mapping::kUnsignedMap, 2, -900, 19000},
    {43, "Target Track Gate Width", Mapping::kUnsignedMap, 1, 0, 510},
    {44, "Target Track Gate Height", Mapping::kUnsignedMap, 1, 0, 510},
    {45, "Target Error Estimate - CE90", Mapping::kUnsignedMap, 2, 0, 4095},
    {46, "Target Error Estimate - LE90", Mapping::kUnsignedMap, 2, 0, 4095},
    {47, "Generic Flag Data", Mapping::kUint, 1},
    {48, "Security Local Set", Mapping::kRaw},
    {49, "Differential Pressure", Mapping::kUnsignedMap, 2, 0, 5000},
    {50, "Platform Angle of Attack", Mapping::kSignedMap, 2, 0, 20},
    {51, "Platform Vertical Speed", Mapping::kSignedMap, 2, 0, 180},
    {52, "Platform Sideslip Angle", Mapping::kSignedMap, 2, 0, 20},
    {53, "Airfield Barometric Pressure", Mapping::kUnsignedMap, 2, 0, 5000},
    {54, "Airfield Elevation", Mapping::kUnsignedMap, 2, -900, 19000},
    {55, "Relative Humidity", Mapping::kUnsignedMap, 1, 0, 100},
    {56, "Platform Ground Speed", Mapping::kUint, 1},
    {57, "Ground Range", Mapping::kUnsignedMap, 4, 0, 5000000},
    {58, "Platform Fuel Remaining", Mapping::kUnsignedMap, 2, 0, 10000},
    {59, "Platform Call Sign", Mapping::kString},
    {60, "Weapon Load", Mapping::kUint, 2},
    {61, "Weapon Fired", Mapping::kUint, 1},
    {62, "Laser PRF Code", Mapping::kUint, 2},
    {63, "Sensor Field of View Name", Mapping::kUint, 1},
    {64, "Platform Magnetic Heading", Mapping::kUnsignedMap, 2, 0, 360},
    {65, "UAS Datalink LS Version Number", Mapping::kUint, 1},
    {66, "Deprecated (Target Location Covariance Matrix)", Mapping::kRaw},
    {67, "Alternate Platform Latitude", Mapping::kSignedMap, 4, 0, 90},
    {68, "Alternate Platform Longitude", Mapping::kSignedMap, 4, 0, 180},
    {69, "Alternate Platform Altitude", Mapping::kUnsignedMap, 2, -900, 19000},
    {70, "Alternate Platform Name", Mapping::kString},
    {71, "Alternate Platform Heading", Mapping::kUnsignedMap, 2, 0, 360},
    {72, "Event Start Time - UTC", Mapping::kUint, 8},
    {73, "RVT Local Set", Mapping::kRaw},
    {74, "VMTI Local Set", Mapping::kRaw},
    {75, "Sensor Ellipsoid Height", Mapping::kUnsignedMap, 2, -900, 19000},
    {76, "Alternate Platform Ellipsoid Height", Mapping::kUnsignedMap, 2, -900, 19000},
    {77, "Operational Mode", Mapping::kUint, 1},
    {78, "Frame Center Height Above Ellipsoid", Mapping::kUnsignedMap, 2, -900, 19000},
    {79, "Sensor North Velocity", Mapping::kSignedMap, 2, 0, 327},
    {80, "Sensor East Velocity", Mapping::kSignedMap, 2, 0, 327},
    {81, "Image Horizon Pixel Pack", Mapping::kRaw},
    {82, "Corner Latitude Point 1 (Full)", Mapping::kSignedMap, 4, 0, 90},
    {83, "Corner Longitude Point 1 (Full)", Mapping::kSignedMap, 4, 0, 180},
    {84, "Corner Latitude Point 2 (Full)", Mapping::kSignedMap, 4, 0, 90},
    {85, "Corner Longitude Point 2 (Full)", Mapping::kSignedMap, 4, 0, 180},
    {86, "Corner Latitude Point 3 (Full)", Mapping::kSignedMap, 4, 0, 90},
    {87, "Corner Longitude Point 3 (Full)", Mapping::kSignedMap, 4, 0, 180},
    {88, "Corner Latitude Point 4 (Full)", Mapping::kSignedMap, 4, 0, 90},
    {89, "Corner Longitude Point 4 (Full)", Mapping::kSignedMap, 4, 0, 180},
    {90, "Platform Pitch Angle (Full)", Mapping::kSignedMap, 4, 0, 90},
    {91, "Platform Roll Angle (Full)", Mapping::kSignedMap, 4, 0, 90},
    {92, "Platform Angle of Attack (Full)", Mapping::kSignedMap, 4, 0, 90},
    {93, "Platform Sideslip Angle (Full)", Mapping::kSignedMap, 4, 0, 180},
    {94, "MIIS Core Identifier", Mapping::kRaw},
    {95, "SAR Motion Imagery Local Set", Mapping::kRaw},
    {96, "Target Width Extended", Mapping::kImapb, 8, 0, 1500000},
    {97, "Range Image Local Set", Mapping::kRaw},
    {98, "Geo-Registration Local Set", Mapping::kRaw},
    {99, "Composite Imaging Local Set", Mapping::kRaw},
    {100, "Segment Local Set", Mapping::kRaw},
    {101, "Amend Local Set", Mapping::kRaw},
    {102, "SDCC-FLP", Mapping::kRaw},
    {103, "Density Altitude Extended", Mapping::kImapb, 8, -900, 40000},
    {104, "Sensor Ellipsoid Height Extended", Mapping::kImapb, 8, -900, 40000},
    {105, "Alternate Platform Ellipsoid Height Extended", Mapping::kImapb, 8, -900, 40000},
    {106, "Stream Designator", Mapping::kString},
    {107, "Operational Base", Mapping::kString},
    {108, "Broadcast Source", Mapping::kString},
    {109, "Range To Recovery Location", Mapping::kImapb, 8, 0, 21000},
    {110, "Time Airborne", Mapping::kUint, 4},
    {111, "Propulsion Unit Speed", Mapping::kUint, 4},
    {112, "Platform Course Angle", Mapping::kImapb, 8, 0, 360},
    {113, "Altitude Above Ground Level", Mapping::kImapb, 8, -900, 40000},
    {114, "Radar Altimeter", Mapping::kImapb, 8, -900, 40000},
    {115, "Control Command", Mapping::kRaw},
    {116, "Control Command Verification List", Mapping::kRaw},
    {117, "Sensor Azimuth Rate", Mapping::kImapb, 8, -1000, 1000},
    {118, "Sensor Elevation Rate", Mapping::kImapb, 8, -1000, 1000},
    {119, "Sensor Roll Rate", Mapping::kImapb, 8, -1000, 1000},
    {120, "On-board MI Storage Percent Full", Mapping::kImapb, 8, 0, 100},
    {121, "Active Wavelength List", Mapping::kRaw},
    {122, "Country Codes", Mapping::kRaw},
    {123, "Number of NAVSATs in View", Mapping::kUint, 1},
    {124, "Positioning Method Source", Mapping::kUint, 1},
    {125, "Platform Status", Mapping::kUint, 1},
    {126, "Sensor Control Mode", Mapping::kUint, 1},
    {127, "Sensor Frame Rate Pack", Mapping::kRaw},
    {128, "Wavelengths List", Mapping::kRaw},
    {129, "Target ID", Mapping::kString},
    {130, "Airbase Locations", Mapping::kRaw},
    {131, "Take-off Time", Mapping::kUint, 8},
    {132, "Transmission Frequency", Mapping::kImapb, 8, 1, 99999},
    {133, "On-board MI Storage Capacity", Mapping::kUint, 4},
    {134, "Zoom Percentage", Mapping::kImapb, 8, 0, 100},
    {135, "Communications Method", Mapping::kString},
    {136, "Leap Seconds", Mapping::kInt, 4},
    {137, "Correction Offset", Mapping::kInt, 8},
    {138, "Payload List", Mapping::kRaw},
    {139, "Active Payloads", Mapping::kRaw},
    {140, "Weapons Stores", Mapping::kRaw},
    {141, "Waypoint List", Mapping::kRaw},
    {142, "View Domain", Mapping::kRaw},
    {143, "Metadata Substream ID Pack", Mapping::kRaw},
};

// The spec of `tag`, or null for tags outside 1-143.
const TagSpec* FindSpec(uint32_t tag) {
  static const std::array<const TagSpec*, kMaxTag + 1> by_tag = [] {
    std::array<const TagSpec*, kMaxTag + 1> table{};
    for (const TagSpec& spec : kTagSpecs) {
      SAKER_CHECK(spec.tag <= kMaxTag && table[spec.tag] == nullptr) << "tag " << spec.tag;
      table[spec.tag] = &spec;
    }
    return table;
  }();
  return tag <= kMaxTag ? by_tag[tag] : nullptr;
}

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
  const TagSpec* spec = FindSpec(tag);
  return spec != nullptr ? spec->name : "Unknown tag";
}

std::optional<double> St0601Resolution(uint32_t tag, size_t length) {
  const TagSpec* spec = FindSpec(tag);
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
  const TagSpec* spec = FindSpec(tag);
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
    const uint64_t n = value.size();
    if (n < 0x80) {
      rebuilt.push_back(static_cast<uint8_t>(n));
    } else {
      int count = 0;
      for (uint64_t rest = n; rest != 0; rest >>= 8) ++count;
      rebuilt.push_back(static_cast<uint8_t>(0x80 | count));
      for (int i = count - 1; i >= 0; --i) rebuilt.push_back(static_cast<uint8_t>(n >> (8 * i)));
    }
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
