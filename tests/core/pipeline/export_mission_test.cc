// The exports of a saved mission behind pipeline::ExportMission (the CLI's and the GUI's): what
// a request may not name (the mission, its video, one file for two outputs), a declared mosaic
// size its tiles do not back, and a cancelled export leaving no temporary.

#include "core/pipeline/export_mission.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/process.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/png_bomb.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace saker::pipeline {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The names in `dir` other than those given (and SQLite's "-wal" and "-shm" beside them).
std::vector<std::string> OtherNames(const fs::path& dir, const std::vector<std::string>& known) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    std::string name = entry.path().filename().string();
    if (name.ends_with("-wal") || name.ends_with("-shm")) name.resize(name.size() - 4);
    if (std::find(known.begin(), known.end(), name) == known.end()) names.push_back(name);
  }
  return names;
}

// A mission of one track over a 64-pixel-tile pyramid of `width` x `height` pixels holding the
// level-0 tiles listed (an opaque grey square each), its video a file of its own.
class ExportMissionTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = saker::testing::MakeTempDir("saker-export-mission"); }
  void TearDown() override { fs::remove_all(dir_); }

  void MakeMission(int width, int height, const std::vector<std::pair<int, int>>& tiles) {
    video_ = dir_ / "flight.ts";
    std::ofstream(video_, std::ios::binary) << std::string(4096, 'v');
    path_ = (dir_ / "flight.saker").string();
    mission::Mission m;
    m.source.path = video_.string();
    m.source.width = 64;
    m.source.height = 48;
    mission::ActivityTrack track;
    track.id = 1;
    track.visit = 1;
    mission::TrackPoint point;
    point.map = {10, 20};
    track.points.push_back(point);
    m.tracks.push_back(track);
    mission::PyramidInfo pyramid;
    pyramid.tile_size = 64;
    pyramid.width = width;
    pyramid.height = height;
    pyramid.levels = 1;
    while ((int64_t{64} << (pyramid.levels - 1)) < std::max(width, height)) ++pyramid.levels;
    m.pyramid = pyramid;
    auto store = mission::MissionStore::Create(path_, /*replace=*/true);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)->Save(m, mission::kSaveTracks).ok());
    std::vector<uint8_t> png;
    ASSERT_TRUE(cv::imencode(".png", cv::Mat(64, 64, CV_8UC4, cv::Scalar(90, 90, 90, 255)), png));
    std::vector<mission::EncodedTile> encoded;
    for (const auto& [x, y] : tiles) encoded.push_back({0, x, y, png});
    ASSERT_TRUE((*store)->WriteTiles(encoded).ok());
  }

  StatusOr<std::vector<ExportedFile>> Export(const ExportRequest& request,
                                             JobContext* job = nullptr) {
    auto store = mission::MissionStore::Open(path_);
    if (!store.ok()) return store.status();
    auto m = (*store)->Load();
    if (!m.ok()) return m.status();
    return ExportMission(*m, **store, request, job);
  }

  fs::path dir_;
  fs::path video_;
  std::string path_;
};

// Item 5 of issue 29: `export M.saker --csv M.saker` replaced the mission and exited 0.
TEST_F(ExportMissionTest, AnExportOverItsOwnInputsIsRefusedAndWritesNothing) {
  MakeMission(128, 128, {{0, 0}, {1, 1}});
  const std::string mission_bytes = ReadText(path_);
  const std::string video_bytes = ReadText(video_);
  fs::create_hard_link(path_, dir_ / "alias.saker");
  const std::string alias = (dir_ / "alias.saker").string();
  const std::string ok = (dir_ / "tracks.geojson").string();
  std::vector<ExportRequest> requests(6);
  requests[0].csv = path_;
  requests[1].geojson = alias;  // another name, the same file
  requests[2].kml = path_;
  requests[3].geotiff = video_.string();
  requests[4].png = path_;
  requests[5].geojson = (dir_ / "." / "flight.saker").string();
  for (ExportRequest& request : requests) {
    request.csv = request.csv.empty() ? ok : request.csv;  // a good output first: not written
    const auto written = Export(request);
    ASSERT_FALSE(written.ok()) << request.csv;
    EXPECT_EQ(written.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(written.status().message().find("an input of this job"), std::string::npos)
        << written.status().message();
    EXPECT_EQ(ReadText(path_), mission_bytes);
    EXPECT_EQ(ReadText(video_), video_bytes);
    EXPECT_FALSE(fs::exists(ok));
  }
  // One file for two outputs.
  ExportRequest twice;
  twice.csv = ok;
  twice.geojson = ok;
  const auto written = Export(twice);
  ASSERT_FALSE(written.ok());
  EXPECT_NE(written.status().message().find("two outputs"), std::string::npos);
  EXPECT_FALSE(fs::exists(ok));
}

// Item 10 of issue 29: a small mission declaring a huge mosaic kept the GeoTIFF export busy for
// hours; the declared size is now checked against a limit and the tiles that exist first.
TEST_F(ExportMissionTest, AMosaicSizeItsTilesDoNotBackIsRefusedBeforeAnyWork) {
  const fs::path tif = dir_ / "mosaic.tif";
  for (const int side : {1'000'000'000, 1'000'000, 100'000}) {
    MakeMission(side, side, {{0, 0}, {1, 0}, {0, 1}});
    ExportRequest request;
    request.geotiff = tif.string();
    const auto written = Export(request);
    ASSERT_FALSE(written.ok()) << side;
    EXPECT_EQ(written.status().code(), StatusCode::kInvalidData);
    EXPECT_EQ(written.status().message().rfind(path_ + ": the mission declares a mosaic of", 0), 0u)
        << written.status().message();
    EXPECT_FALSE(fs::exists(tif));
    EXPECT_EQ(OtherNames(dir_, {"flight.ts", "flight.saker"}), std::vector<std::string>{});
  }
  // A mosaic whose tiles reach its edges (the last tile only partly inside) is exported.
  MakeMission(150, 100, {{0, 0}, {2, 1}});
  ExportRequest request;
  request.geotiff = tif.string();
  const auto written = Export(request);
  ASSERT_TRUE(written.ok()) << written.status().ToString();
  EXPECT_TRUE(fs::exists(tif));
}

// A GeoTIFF cancelled once under way (as Ctrl-C or SIGTERM do in `saker-cli export`) stops
// between tiles and leaves neither the file nor its temporary.
TEST_F(ExportMissionTest, ACancelledGeoTiffLeavesNoTemporary) {
  MakeMission(640, 640, {{0, 0}, {9, 9}});
  JobContext* self = nullptr;
  JobContext job([&](const std::string&, double fraction) {
    if (fraction >= 0.3) self->RequestCancel();  // as the GeoTIFF starts
  });
  self = &job;
  ExportRequest request;
  request.geotiff = (dir_ / "mosaic.tif").string();
  const auto written = Export(request, &job);
  ASSERT_FALSE(written.ok());
  EXPECT_EQ(written.status().code(), StatusCode::kCancelled) << written.status().ToString();
  EXPECT_EQ(OtherNames(dir_, {"flight.ts", "flight.saker"}), std::vector<std::string>{});
}

// Issue 29, minor: errors of a mission built under a temporary name gave the hidden temporary's
// path, twice, and not the file the person asked for.
TEST_F(ExportMissionTest, ACopyThatCannotBeCreatedNamesTheTargetOnce) {
  MakeMission(128, 128, {{0, 0}, {1, 1}});
  const std::string to = (dir_ / "no-such-folder" / "copy.saker").string();
  const Status copied = CopyMission(path_, to, false);
  ASSERT_FALSE(copied.ok());
  const std::string& message = copied.message();
  EXPECT_EQ(message.rfind(to + ": cannot create the mission: ", 0), 0u) << message;
  EXPECT_EQ(message.find("copy.saker", message.find("copy.saker") + 1), std::string::npos)
      << message;
  EXPECT_EQ(message.find(".part-"), std::string::npos) << message;
}

// The one check of an output against the job's inputs serves `copy` and `process` too.
TEST_F(ExportMissionTest, CopyAndProcessRefuseToWriteOverTheirInputs) {
  MakeMission(128, 128, {{0, 0}, {1, 1}});
  const std::string video_bytes = ReadText(video_);
  const Status copied = CopyMission(path_, (dir_ / "." / "flight.saker").string(), true);
  EXPECT_EQ(copied.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(copied.message().find("an input of this job"), std::string::npos) << copied.message();
  ProcessOptions options;
  options.replace = true;
  const auto processed = ProcessVideo(video_.string(), video_.string(), options);
  EXPECT_EQ(processed.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(processed.status().message().find("an input of this job"), std::string::npos)
      << processed.status().message();
  EXPECT_EQ(ReadText(video_), video_bytes);
}

// Decompression bombs among the tiles (issue 29, item 1).
// A mission with a one-tile pyramid whose tile holds `tile`.
std::string MissionWithTile(const fs::path& dir, const std::vector<uint8_t>& tile) {
  const std::string path = (dir / "mission.saker").string();
  auto store = mission::MissionStore::Create(path);
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  mission::Mission m = mission::testing_support::MakeFullMission();
  m.pyramid->tile_size = 256;
  m.pyramid->levels = 1;
  m.pyramid->width = 256;
  m.pyramid->height = 200;
  EXPECT_TRUE((*store)->Save(m).ok());
  EXPECT_TRUE((*store)->WriteTiles({{0, 0, 0, tile}}).ok());
  return path;
}

StatusOr<std::vector<ExportedFile>> Export(const std::string& path, const ExportRequest& request) {
  auto store = mission::MissionStore::Open(path, mission::OpenMode::kReadOnly);
  if (!store.ok()) return store.status();
  SAKER_ASSIGN_OR_RETURN(const mission::Mission m, (*store)->Load());
  return ExportMission(m, **store, request);
}

// A 100-byte tile whose PNG header claims 40000 x 40000 pixels aborted `export --png` with an
// uncaught cv::Exception from the tile decode; a tile of another size than the pyramid's (a
// zero-filled 16384^2 one) was decoded whole. Both are bad data, named with the file and tile.
TEST(ExportMissionTileTest, DecompressionBombTilesAreRefusedNamingTheTile) {
  const fs::path dir = saker::testing::MakeTempDir("saker-export-bomb");
  std::vector<uint8_t> big;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat::zeros(1024, 1024, CV_8UC4), big));
  for (const std::vector<uint8_t>& tile : {saker::testing::PngBomb(40000, 40000), big}) {
    const std::string path = MissionWithTile(dir, tile);
    ExportRequest request;
    request.png = (dir / "activity.png").string();
    const auto exported = Export(path, request);
    ASSERT_FALSE(exported.ok());
    EXPECT_EQ(exported.status().code(), StatusCode::kInvalidData);
    EXPECT_NE(exported.status().message().find(path + ": tile 0/0/0"), std::string::npos)
        << exported.status().message();
    EXPECT_FALSE(fs::exists(request.png));
    request = {};
    request.geotiff = (dir / "mosaic.tif").string();
    const auto geotiff = Export(path, request);
    ASSERT_FALSE(geotiff.ok());
    EXPECT_NE(geotiff.status().message().find("tile 0/0/0"), std::string::npos)
        << geotiff.status().message();
    fs::remove(path);
  }
}

TEST(ExportMissionTileTest, AGoodTileExports) {
  const fs::path dir = saker::testing::MakeTempDir("saker-export-tile");
  std::vector<uint8_t> tile;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(256, 256, CV_8UC4, cv::Scalar(9, 9, 9, 255)), tile));
  ExportRequest request;
  request.png = (dir / "activity.png").string();
  const auto exported = Export(MissionWithTile(dir, tile), request);
  ASSERT_TRUE(exported.ok()) << exported.status().ToString();
  EXPECT_TRUE(fs::exists(request.png));
}

}  // namespace
}  // namespace saker::pipeline
