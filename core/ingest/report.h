#pragma once

// Human-readable and JSON summaries of a VideoScan, shared by
// `saker-cli probe`, `saker-cli klv` and (later) the GUI's file info panel.

#include "core/ingest/video_scan.h"

#include <nlohmann/json.hpp>

#include <string>

namespace saker::ingest {

// `saker-cli probe`: container, streams, resolution, fps, frame count, KLV
// streams with packet counts, checksum failures, frames with corner
// metadata, time span, warnings.
nlohmann::json ProbeToJson(const VideoScan& scan);
std::string ProbeToText(const VideoScan& scan);

// `saker-cli klv`: every decoded packet, with its stream, time, the frames it
// was matched to, and all raw tags.
nlohmann::json KlvDumpToJson(const VideoScan& scan);
std::string KlvDumpToText(const VideoScan& scan);

// ISO 8601 UTC text ("2008-10-24T00:13:29.913000Z") of a UNIX time in microseconds.
std::string FormatUtcMicros(uint64_t unix_time_us);

}  // namespace saker::ingest
