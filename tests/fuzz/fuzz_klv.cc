// libFuzzer harness for the KLV parser (core/klv): SMPTE 336 framing, MISB ST 0601 local sets,
// MISB EG 0104 universal sets, FrameMetadata and the JSON dumps of `saker-cli klv`.
//
// The input is used three ways, so the fuzzer need not rediscover the 16-byte keys:
//   1. as a demuxed KLV data packet: SplitKlvPackets, then DecodePacket and ToJson on every packet
//      (what core/ingest does with each data packet of a video);
//   2. as the value of an ST 0601 local set (the key and BER length put in front);
//   3. as the value of an EG 0104 universal set.
// Besides the sanitizers, it checks the promises the rest of Saker relies on: split packets lie
// inside the input, every decoded number and every FrameMetadata field is finite, and a failed
// decode always says why.

#include "core/klv/decode.h"
#include "core/klv/eg0104.h"
#include "core/klv/klv.h"
#include "core/klv/metadata.h"
#include "core/klv/st0601.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

namespace {

using namespace saker::klv;

[[noreturn]] void Fail(const char* what) {
  std::fprintf(stderr, "fuzz_klv: broken promise: %s\n", what);
  std::abort();
}

void CheckFinite(const std::optional<double>& value, const char* what) {
  if (value && !std::isfinite(*value)) Fail(what);
}

void CheckValue(const St0601Value& value) {
  if (const double* d = std::get_if<double>(&value); d != nullptr && !std::isfinite(*d)) {
    Fail("a decoded value is NaN or infinite (should be Absent)");
  }
}

void CheckMetadata(const FrameMetadata& m) {
  CheckFinite(m.platform_heading_deg, "platform heading");
  CheckFinite(m.platform_pitch_deg, "platform pitch");
  CheckFinite(m.platform_roll_deg, "platform roll");
  CheckFinite(m.sensor_latitude_deg, "sensor latitude");
  CheckFinite(m.sensor_longitude_deg, "sensor longitude");
  CheckFinite(m.sensor_altitude_m, "sensor altitude");
  CheckFinite(m.sensor_hfov_deg, "sensor hfov");
  CheckFinite(m.sensor_vfov_deg, "sensor vfov");
  CheckFinite(m.sensor_rel_azimuth_deg, "sensor relative azimuth");
  CheckFinite(m.sensor_rel_elevation_deg, "sensor relative elevation");
  CheckFinite(m.sensor_rel_roll_deg, "sensor relative roll");
  CheckFinite(m.slant_range_m, "slant range");
  CheckFinite(m.frame_center_elevation_m, "frame centre elevation");
  if (m.frame_center && (!std::isfinite(m.frame_center->latitude_deg) ||
                         !std::isfinite(m.frame_center->longitude_deg))) {
    Fail("frame centre not finite");
  }
  if (m.corners) {
    for (const LatLon& corner : *m.corners) {
      if (!std::isfinite(corner.latitude_deg) || !std::isfinite(corner.longitude_deg)) {
        Fail("corner not finite");
      }
    }
  }
  (void)FrameMetadataToJson(m).dump();
}

void CheckDecoded(const DecodedPacket& decoded) {
  if (!decoded.status.ok() && decoded.status.message().empty()) Fail("error without a message");
  if (decoded.st0601) {
    for (const St0601Item& item : decoded.st0601->items) CheckValue(item.value);
  }
  if (decoded.eg0104) {
    for (const Eg0104Item& item : decoded.eg0104->items) CheckValue(item.value);
  }
  if (decoded.metadata) CheckMetadata(*decoded.metadata);
  // The dump must never throw (nlohmann::json throws on invalid UTF-8).
  (void)ToJson(decoded).dump();
}

void DecodeAs(const UniversalKey& key, ByteSpan value) {
  KlvPacket packet;
  packet.key = key;
  packet.value.assign(value.begin(), value.end());
  packet.bytes.assign(key.bytes.begin(), key.bytes.end());
  AppendBerLength(value.size(), &packet.bytes);
  packet.bytes.insert(packet.bytes.end(), value.begin(), value.end());
  CheckDecoded(DecodePacket(packet));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const ByteSpan input(data, size);

  const KlvSplitResult split = SplitKlvPackets(input);
  size_t covered = split.skipped_bytes;
  for (const KlvPacket& packet : split.packets) {
    if (packet.offset > size || packet.bytes.size() > size - packet.offset) {
      Fail("a split packet lies outside the input");
    }
    covered += packet.bytes.size();
    CheckDecoded(DecodePacket(packet));
  }
  if (covered != size) Fail("split packets and skipped bytes do not add up to the input");
  if (split.skipped_bytes > 0 && split.errors.empty()) Fail("bytes skipped without an error");

  DecodeAs(kSt0601Key, input);
  DecodeAs(kEg0104Key, input);
  return 0;
}
