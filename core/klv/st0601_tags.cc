#include "core/klv/st0601_tags.h"

#include "core/util/check.h"

#include <array>

namespace saker::klv::internal {

namespace {

// ST 0601.17, tags 1-143. Tag 66 is deprecated and tag 98 (Geo-Registration
// Local Set) only appears inside the Amend set.
//
// The encoder-only columns follow the item definitions of ST 0601.17
// section 8: text is at most 127 bytes (Target ID 32); the IMAPB tags have a
// per-tag maximum and suggested length; Time Airborne, Propulsion Unit Speed,
// Take-off Time, On-board MI Storage Capacity, Leap Seconds and Correction
// Offset are variable-length integers; Segment, Amend, SDCC-FLP and Control
// Command are the only items that may repeat in a set.
constexpr TagSpec kTagSpecs[] = {
    {1, "Checksum", Mapping::kChecksum, 2},
    {2, "Precision Time Stamp", Mapping::kUint, 8},
    {3, "Mission ID", Mapping::kString, 127},
    {4, "Platform Tail Number", Mapping::kString, 127},
    {5, "Platform Heading Angle", Mapping::kUnsignedMap, 2, 0, 360},
    {6, "Platform Pitch Angle", Mapping::kSignedMap, 2, 0, 20},
    {7, "Platform Roll Angle", Mapping::kSignedMap, 2, 0, 50},
    {8, "Platform True Airspeed", Mapping::kUint, 1},
    {9, "Platform Indicated Airspeed", Mapping::kUint, 1},
    {10, "Platform Designation", Mapping::kString, 127},
    {11, "Image Source Sensor", Mapping::kString, 127},
    {12, "Image Coordinate System", Mapping::kString, 127},
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
    {59, "Platform Call Sign", Mapping::kString, 127},
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
    {70, "Alternate Platform Name", Mapping::kString, 127},
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
    {96, "Target Width Extended", Mapping::kImapb, 8, 0, 1500000, /*default_length=*/3},
    {97, "Range Image Local Set", Mapping::kRaw},
    {98, "Geo-Registration Local Set", Mapping::kRaw},
    {99, "Composite Imaging Local Set", Mapping::kRaw},
    {100, "Segment Local Set", Mapping::kRaw, 0, 0, 0, 0, false, /*multiples=*/true},
    {101, "Amend Local Set", Mapping::kRaw, 0, 0, 0, 0, false, /*multiples=*/true},
    {102, "SDCC-FLP", Mapping::kRaw, 0, 0, 0, 0, false, /*multiples=*/true},
    {103, "Density Altitude Extended", Mapping::kImapb, 8, -900, 40000, /*default_length=*/3},
    {104, "Sensor Ellipsoid Height Extended", Mapping::kImapb, 8, -900, 40000,
     /*default_length=*/3},
    {105, "Alternate Platform Ellipsoid Height Extended", Mapping::kImapb, 8, -900, 40000,
     /*default_length=*/3},
    {106, "Stream Designator", Mapping::kString, 127},
    {107, "Operational Base", Mapping::kString, 127},
    {108, "Broadcast Source", Mapping::kString, 127},
    {109, "Range To Recovery Location", Mapping::kImapb, 4, 0, 21000, /*default_length=*/4},
    {110, "Time Airborne", Mapping::kUint, 4, 0, 0, 0, /*variable_length=*/true},
    {111, "Propulsion Unit Speed", Mapping::kUint, 4, 0, 0, 0, /*variable_length=*/true},
    {112, "Platform Course Angle", Mapping::kImapb, 8, 0, 360, /*default_length=*/2},
    {113, "Altitude Above Ground Level", Mapping::kImapb, 4, -900, 40000, /*default_length=*/3},
    {114, "Radar Altimeter", Mapping::kImapb, 4, -900, 40000, /*default_length=*/3},
    {115, "Control Command", Mapping::kRaw, 0, 0, 0, 0, false, /*multiples=*/true},
    {116, "Control Command Verification List", Mapping::kRaw},
    {117, "Sensor Azimuth Rate", Mapping::kImapb, 4, -1000, 1000, /*default_length=*/3},
    {118, "Sensor Elevation Rate", Mapping::kImapb, 4, -1000, 1000, /*default_length=*/3},
    {119, "Sensor Roll Rate", Mapping::kImapb, 4, -1000, 1000, /*default_length=*/3},
    {120, "On-board MI Storage Percent Full", Mapping::kImapb, 3, 0, 100, /*default_length=*/2},
    {121, "Active Wavelength List", Mapping::kRaw},
    {122, "Country Codes", Mapping::kRaw},
    {123, "Number of NAVSATs in View", Mapping::kUint, 1},
    {124, "Positioning Method Source", Mapping::kUint, 1},
    {125, "Platform Status", Mapping::kUint, 1},
    {126, "Sensor Control Mode", Mapping::kUint, 1},
    {127, "Sensor Frame Rate Pack", Mapping::kRaw},
    {128, "Wavelengths List", Mapping::kRaw},
    {129, "Target ID", Mapping::kString, 32},
    {130, "Airbase Locations", Mapping::kRaw},
    {131, "Take-off Time", Mapping::kUint, 8, 0, 0, 0, /*variable_length=*/true},
    {132, "Transmission Frequency", Mapping::kImapb, 4, 1, 99999, /*default_length=*/3},
    {133, "On-board MI Storage Capacity", Mapping::kUint, 4, 0, 0, 0, /*variable_length=*/true},
    {134, "Zoom Percentage", Mapping::kImapb, 4, 0, 100, /*default_length=*/1},
    {135, "Communications Method", Mapping::kString, 127},
    {136, "Leap Seconds", Mapping::kInt, 4, 0, 0, 0, /*variable_length=*/true},
    {137, "Correction Offset", Mapping::kInt, 8, 0, 0, 0, /*variable_length=*/true},
    {138, "Payload List", Mapping::kRaw},
    {139, "Active Payloads", Mapping::kRaw},
    {140, "Weapons Stores", Mapping::kRaw},
    {141, "Waypoint List", Mapping::kRaw},
    {142, "View Domain", Mapping::kRaw},
    {143, "Metadata Substream ID Pack", Mapping::kRaw},
};

}  // namespace

const TagSpec* FindTagSpec(uint32_t tag) {
  static const std::array<const TagSpec*, kMaxSt0601Tag + 1> by_tag = [] {
    std::array<const TagSpec*, kMaxSt0601Tag + 1> table{};
    for (const TagSpec& spec : kTagSpecs) {
      SAKER_CHECK(spec.tag <= kMaxSt0601Tag && table[spec.tag] == nullptr) << "tag " << spec.tag;
      table[spec.tag] = &spec;
    }
    return table;
  }();
  return tag <= kMaxSt0601Tag ? by_tag[tag] : nullptr;
}

}  // namespace saker::klv::internal
