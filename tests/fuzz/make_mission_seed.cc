// Writes a small but complete mission file (every table filled, every link kind, tracks with and
// without points, a few tiles, decompression bomb tiles, and a checkpoint whose key frame image is
// a bomb) as a seed for fuzz_mission: `make_mission_seed OUT.saker`. Built from the mission tests'
// fixture, so the seed follows the schema as it evolves.

#include "core/mission/mission_store.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/png_bomb.h"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
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

int main(int argc, char** argv) {
  using namespace saker::mission;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.saker\n", argv[0]);
    return 2;
  }
  const std::string path = argv[1];
  auto store = MissionStore::Create(path, /*replace=*/true);
  if (!store.ok()) {
    std::fprintf(stderr, "%s\n", store.status().ToString().c_str());
    return 1;
  }
  Mission mission = testing_support::MakeFullMission();
  if (!mission.pyramid) mission.pyramid = PyramidInfo{};
  mission.pyramid->levels = 2;
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
