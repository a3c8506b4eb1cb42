// Writes a small but complete mission file (every table filled, every link kind, tracks with and
// without points, a few tiles, decompression bomb tiles, and a checkpoint whose key frame image is
// a bomb) as a seed for fuzz_mission: `make_mission_seed OUT.saker [ANTIMERIDIAN.saker]`; the
// second, when named, is the same mission flown over the antimeridian (its map origin and sensor
// positions either side of 180 degrees). Built from the mission tests' fixture, so the seed
// follows the schema as it evolves. Beside it, the same mission declaring absurd mosaic sizes over
// its few tiles (OUT-absurd-<side>.saker, side 100,000 and 1,000,000 pixels: issue 29 item 10,
// where such a file kept `export --geotiff` busy for hours).

#include "core/mission/mission_store.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/png_bomb.h"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace {

template <typename T>
void Put(T value, std::vector<uint8_t>* out) {
  const size_t at = out->size();
  out->resize(at + sizeof(T));
  std::memcpy(out->data() + at, &value, sizeof(T));
}

// An unfinished job's checkpoint as pipeline/checkpoint.cc writes it (docs/mission-file.md): the
// state, and key frame 0's image, whose PNG header claims 40000 x 40000 pixels.
std::vector<saker::mission::CheckpointRecord> BombCheckpoint() {
  std::vector<uint8_t> state;
  Put<uint32_t>(1, &state);  // version
  Put<int64_t>(0, &state);   // through frame
  Put<uint8_t>(0, &state);   // not complete
  Put<int64_t>(-1, &state);  // change detection through frame
  std::vector<uint8_t> image;
  Put<int32_t>(0, &image);                                                  // key frame id
  Put<int64_t>(0, &image);                                                  // frame
  Put<double>(2.0, &image);                                                 // scale
  for (int i = 0; i < 9; ++i) Put<double>(i % 4 == 0 ? 1.0 : 0.0, &image);  // identity
  const std::vector<uint8_t> bomb = saker::testing::PngBomb(40000, 40000);
  Put<uint64_t>(bomb.size(), &image);
  image.insert(image.end(), bomb.begin(), bomb.end());
  return {{"state", 0, state}, {"key_frame_image", 0, image}};
}

}  // namespace

namespace {

using namespace saker::mission;

// The fixture flown over the antimeridian: the origin on it, the sensor positions either side.
Mission AtTheAntimeridian(Mission mission) {
  mission.map.origin = saker::geo::Wgs84{51.15, 179.9999, 100.0};
  double longitude = 179.9990;
  for (FrameRecord& f : mission.frames) {
    if (f.sensor) f.sensor = saker::geo::Wgs84{51.15, longitude, 400.0};
    longitude += 0.0004;
    if (longitude > 180.0) longitude -= 360.0;
  }
  return mission;
}

// `mission` with a pyramid of `side` x `side` pixels (0: the mission's own) and three tiles.
int WriteSeed(const std::string& path, Mission mission, int side) {
  auto store = MissionStore::Create(path, /*replace=*/true);
  if (!store.ok()) {
    std::fprintf(stderr, "%s\n", store.status().ToString().c_str());
    return 1;
  }
  if (!mission.pyramid) mission.pyramid = PyramidInfo{};
  mission.pyramid->levels = 2;
  if (side > 0) {
    mission.pyramid->width = side;
    mission.pyramid->height = side;
    while ((static_cast<int64_t>(mission.pyramid->tile_size) << (mission.pyramid->levels - 1)) <
           side) {
      ++mission.pyramid->levels;
    }
  }
  saker::Status saved = (*store)->Save(mission);
  if (saved.ok()) {
    saved = (*store)->WriteTiles({{0, 0, 0, {0x89, 'P', 'N', 'G', 1, 2, 3}},
                                  {0, 1, 0, {0xFF, 0xD8, 0xFF, 4, 5}},
                                  {0, 0, 1, saker::testing::PngBomb(40000, 40000)},
                                  {0, 1, 1, saker::testing::PngBomb(16384, 16384)},
                                  {1, 0, 0, {6, 7, 8, 9}}});
  }
  if (saved.ok()) saved = (*store)->WriteCheckpoint(BombCheckpoint());
  if (!saved.ok()) {
    std::fprintf(stderr, "%s\n", saved.ToString().c_str());
    return 1;
  }
  store->reset();  // closes the connection and checkpoints the write-ahead log into the file
  std::error_code ignored;
  std::filesystem::remove(path + "-wal", ignored);
  std::filesystem::remove(path + "-shm", ignored);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2 && argc != 3) {
    std::fprintf(stderr, "usage: %s OUT.saker [ANTIMERIDIAN.saker]\n", argv[0]);
    return 2;
  }
  const Mission mission = saker::mission::testing_support::MakeFullMission();
  const std::filesystem::path path = argv[1];
  int failed = WriteSeed(path.string(), mission, 0);
  for (const int side : {100'000, 1'000'000}) {
    std::filesystem::path absurd = path;
    absurd.replace_filename(path.stem().string() + "-absurd-" + std::to_string(side) + ".saker");
    failed = std::max(failed, WriteSeed(absurd.string(), mission, side));
  }
  if (argc == 3) failed = std::max(failed, WriteSeed(argv[2], AtTheAntimeridian(mission), 0));
  return failed;
}
