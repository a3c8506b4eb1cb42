// The PMT reader that tells synchronous (0x15) from asynchronous (0x06) KLV streams, on
// synthetic transport streams written at test time.

#include "core/video/mpegts_pmt.h"

#include "tests/core/video/synthetic_ts.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

namespace saker::video {
namespace {

namespace fs = std::filesystem;

std::vector<unsigned char> SyntheticBytes(bool synchronous) {
  saker::testing::SyntheticTsOptions options;
  options.frames = 4;
  options.klv_synchronous = synchronous;
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "clip.ts";
  const Status written = saker::testing::WriteSyntheticTs(path, options);
  EXPECT_TRUE(written.ok()) << written.ToString();
  return saker::testing::ReadFileBytes(path);
}

// libavformat's defaults: PMT on PID 0x1000, video 0x100 (MPEG-2: stream_type 0x02), KLV 0x101.
const std::map<int, int> kAsync = {{0x100, 0x02}, {0x101, kStreamTypePrivatePes}};
const std::map<int, int> kSync = {{0x100, 0x02}, {0x101, kStreamTypeMetadata}};

TEST(MpegTsPmtTest, ReadsStreamTypesOfSynchronousAndAsynchronousKlv) {
  const auto async_bytes = SyntheticBytes(false);
  EXPECT_EQ(ScanPmtStreamTypes(async_bytes.data(), async_bytes.size()), kAsync);
  const auto sync_bytes = SyntheticBytes(true);
  EXPECT_EQ(ScanPmtStreamTypes(sync_bytes.data(), sync_bytes.size()), kSync);
}

TEST(MpegTsPmtTest, ReadsAFileOnDisk) {
  saker::testing::SyntheticTsOptions options;
  options.frames = 3;
  options.klv_synchronous = true;
  const fs::path path = saker::testing::MakeTempDir("saker-video") / "clip.ts";
  ASSERT_TRUE(saker::testing::WriteSyntheticTs(path, options).ok());
  auto types = ScanPmtStreamTypesInFile(path.string());
  ASSERT_TRUE(types.ok()) << types.status().ToString();
  EXPECT_EQ(*types, kSync);
  EXPECT_EQ(ScanPmtStreamTypesInFile((path.parent_path() / "none.ts").string()).status().code(),
            StatusCode::kNotFound);
}

TEST(MpegTsPmtTest, HandlesM2tsPacketsAndAnOffsetStart) {
  const auto bytes = SyntheticBytes(true);
  // 192-byte packets (4-byte arrival time stamp in front of each), after 7 bytes of junk.
  std::vector<unsigned char> m2ts(7, 0xAB);
  for (size_t pos = 0; pos + 188 <= bytes.size(); pos += 188) {
    m2ts.insert(m2ts.end(), {0x00, 0x01, 0x02, 0x03});
    m2ts.insert(m2ts.end(), bytes.begin() + static_cast<std::ptrdiff_t>(pos),
                bytes.begin() + static_cast<std::ptrdiff_t>(pos + 188));
  }
  EXPECT_EQ(ScanPmtStreamTypes(m2ts.data(), m2ts.size()), kSync);
}

TEST(MpegTsPmtTest, SectionsFailingTheirCrcAreIgnored) {
  auto bytes = SyntheticBytes(true);
  // Change the KLV stream_type byte in every PMT packet: with the CRC now wrong, no PMT is used.
  int changed = 0;
  for (size_t pos = 0; pos + 188 <= bytes.size(); pos += 188) {
    const int pid = ((bytes[pos + 1] & 0x1F) << 8) | bytes[pos + 2];
    if (pid != 0x1000) continue;
    for (size_t i = pos + 5; i + 3 < pos + 188; ++i) {
      if (bytes[i] == kStreamTypeMetadata && bytes[i + 1] == 0xE1 && bytes[i + 2] == 0x01) {
        bytes[i] = kStreamTypePrivatePes;
        ++changed;
        break;
      }
    }
  }
  ASSERT_GT(changed, 0);
  EXPECT_TRUE(ScanPmtStreamTypes(bytes.data(), bytes.size()).empty());
}

TEST(MpegTsPmtTest, NonTransportStreamBytesGiveNothing) {
  std::mt19937 random(99);
  std::vector<unsigned char> noise(100000);
  for (auto& byte : noise) byte = static_cast<unsigned char>(random() & 0xFF);
  EXPECT_TRUE(ScanPmtStreamTypes(noise.data(), noise.size()).empty());
  EXPECT_TRUE(ScanPmtStreamTypes(nullptr, 0).empty());
  const auto bytes = SyntheticBytes(false);
  EXPECT_TRUE(ScanPmtStreamTypes(bytes.data(), 100).empty());  // less than one packet
}

}  // namespace
}  // namespace saker::video
