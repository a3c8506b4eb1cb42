// Writes a small but complete mission file (every table filled, every link kind, tracks with and
// without points, a few tiles) as a seed for fuzz_mission: `make_mission_seed OUT.saker`.
// Built from the mission tests' fixture, so the seed follows the schema as it evolves.

#include "core/mission/mission_store.h"
#include "tests/core/mission/mission_fixtures.h"

#include <cstdio>
#include <filesystem>

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
                                  {1, 0, 0, {6, 7, 8, 9}}});
  }
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
