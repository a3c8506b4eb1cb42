#include "core/pipeline/export_mission.h"

#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/png_bomb.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace saker::pipeline {
namespace {

namespace fs = std::filesystem;

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
TEST(ExportMissionTest, DecompressionBombTilesAreRefusedNamingTheTile) {
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

TEST(ExportMissionTest, AGoodTileExports) {
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
