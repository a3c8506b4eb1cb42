#include "core/mission/mission_store.h"

#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/test_data.h"

#include <Eigen/Geometry>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace saker::mission {
namespace {

namespace fs = std::filesystem;
using testing_support::MakeFullMission;
using testing_support::MissionsEqual;

std::vector<uint8_t> ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

using saker::testing::RandomBytes;
using saker::testing::WriteFileBytes;

// Runs SQL on a database directly, as another tool (or an attacker) would.
void ExecSql(const fs::path& path, const std::string& sql) {
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr),
            SQLITE_OK);
  char* error = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &error);
  const std::string message = error != nullptr ? error : "";
  sqlite3_free(error);
  sqlite3_close(db);
  ASSERT_EQ(rc, SQLITE_OK) << sql << ": " << message;
}

std::unique_ptr<MissionStore> CreateOrDie(const fs::path& path, bool replace = false) {
  auto store = MissionStore::Create(path.string(), replace);
  EXPECT_TRUE(store.ok()) << store.status().ToString();
  return store.ok() ? std::move(store).value() : nullptr;
}

// A saved mission file, closed (so its write-ahead log is folded in and removed).
void WriteMissionFile(const fs::path& path, const Mission& mission) {
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  const Status saved = store->Save(mission);
  ASSERT_TRUE(saved.ok()) << saved.ToString();
}

StatusOr<Mission> LoadFile(const fs::path& path) {
  auto store = MissionStore::Open(path.string());
  if (!store.ok()) return store.status();
  return (*store)->Load();
}

#define EXPECT_SAME_MISSION(a, b)                    \
  do {                                               \
    std::string why_;                                \
    EXPECT_TRUE(MissionsEqual(a, b, &why_)) << why_; \
  } while (false)

class MissionStoreTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = saker::testing::MakeTempDir("saker-mission-store"); }
  fs::path File(const std::string& name) const { return dir_ / name; }

  fs::path dir_;
};

// ---------------------------------------------------------------------------------------------
// Round trips.

TEST_F(MissionStoreTest, CreatedFileHoldsAnEmptyMission) {
  const fs::path path = File("empty.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  EXPECT_EQ(store->path(), path.string());
  EXPECT_EQ(store->mode(), OpenMode::kReadWrite);
  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, Mission{});
  EXPECT_EQ(loaded->schema_version, kSchemaVersion);
}

TEST_F(MissionStoreTest, RoundTripKeepsEveryField) {
  const Mission original = MakeFullMission();
  const fs::path path = File("full.saker");
  {
    auto store = CreateOrDie(path);
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->Save(original).ok());
    // The writer reads its own commit...
    auto loaded = store->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_SAME_MISSION(*loaded, original);
  }
  // ...and so does a fresh reader of the closed file.
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, original);
}

// A mission of schema 1 (before the frames' stream positions): read as it is, upgraded in place
// when opened for writing, and then saves and loads everything.
TEST_F(MissionStoreTest, SchemaOneFileIsReadAndUpgradedForWriting) {
  const fs::path path = File("v1.saker");
  const Mission full = MakeFullMission();
  WriteMissionFile(path, full);
  ExecSql(path,
          "DROP TABLE overlays; DROP TABLE checkpoint; ALTER TABLE tracks DROP COLUMN confidence; "
          "ALTER TABLE frames DROP COLUMN pts; ALTER TABLE frames DROP COLUMN key_frame; "
          "ALTER TABLE frames DROP COLUMN sky_y0; ALTER TABLE frames DROP COLUMN sky_slope; "
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 1 WHERE key = 'schema_version'; PRAGMA user_version = 1");
  {
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, 1);
    ASSERT_EQ(m->frames.size(), full.frames.size());
    for (const FrameRecord& f : m->frames) EXPECT_FALSE(f.pts.has_value());
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)->Save(full).ok());
  }
  auto store = MissionStore::Open(path.string());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  auto m = (*store)->Load();
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->schema_version, kSchemaVersion);
  EXPECT_SAME_MISSION(*m, full);
}

// Schema 2 (before checkpoints): read with no checkpoint, upgraded when opened for writing, and
// then keeps checkpoints.
TEST_F(MissionStoreTest, SchemaTwoFileHasNoCheckpointUntilUpgraded) {
  const fs::path path = File("v2.saker");
  const Mission full = MakeFullMission();
  WriteMissionFile(path, full);
  ExecSql(path,
          "DROP TABLE overlays; DROP TABLE checkpoint; ALTER TABLE tracks DROP COLUMN confidence; "
          "ALTER TABLE frames DROP COLUMN sky_y0; ALTER TABLE frames DROP COLUMN sky_slope; "
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 2 WHERE key = 'schema_version'; PRAGMA user_version = 2");
  {
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto records = (*store)->ReadCheckpoint();
    ASSERT_TRUE(records.ok()) << records.status().ToString();
    EXPECT_TRUE(records->empty());
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, 2);
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)->WriteCheckpoint({{"state", 0, {1, 2, 3}}}).ok());
  }
  auto store = MissionStore::Open(path.string());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  auto records = (*store)->ReadCheckpoint();
  ASSERT_TRUE(records.ok()) << records.status().ToString();
  ASSERT_EQ(records->size(), 1u);
  EXPECT_EQ((*records)[0].bytes, (std::vector<uint8_t>{1, 2, 3}));
  auto m = (*store)->Load();
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->schema_version, kSchemaVersion);
  // Upgraded, not saved again: the tracks' confidence is unknown (schema 4 adds it empty), and
  // there is no overlay mask (schema 5 adds the table empty) nor sky line (schema 6 adds the
  // columns empty), and every track point was seen (schema 8 adds the flag as 0).
  Mission upgraded = full;
  for (ActivityTrack& t : upgraded.tracks) {
    t.confidence.reset();
    for (TrackPoint& p : t.points) p.interpolated = false;
  }
  upgraded.overlays.clear();
  for (FrameRecord& f : upgraded.frames) f.sky_line.reset();
  EXPECT_SAME_MISSION(*m, upgraded);
}

// Schema 3 (before the tracks' confidence): read with every confidence unknown (the evidence it
// needs was not kept), upgraded in place when opened for writing, and then keeps confidences.
TEST_F(MissionStoreTest, SchemaThreeFileHasUnknownConfidenceUntilUpgraded) {
  const fs::path path = File("v3.saker");
  const Mission full = MakeFullMission();
  WriteMissionFile(path, full);
  ExecSql(path,
          "DROP TABLE overlays; ALTER TABLE tracks DROP COLUMN confidence; "
          "ALTER TABLE frames DROP COLUMN sky_y0; ALTER TABLE frames DROP COLUMN sky_slope; "
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 3 WHERE key = 'schema_version'; PRAGMA user_version = 3");
  {
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, 3);
    ASSERT_EQ(m->tracks.size(), full.tracks.size());
    for (const ActivityTrack& t : m->tracks) EXPECT_FALSE(t.confidence.has_value());
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, kSchemaVersion);
    for (const ActivityTrack& t : m->tracks) EXPECT_FALSE(t.confidence.has_value());
    ASSERT_TRUE((*store)->Save(full).ok());
  }
  auto m = LoadFile(path);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_EQ(m->schema_version, kSchemaVersion);
  EXPECT_SAME_MISSION(*m, full);
}

// Schema 4 (before the overlay masks): read with none, upgraded in place when opened for writing
// (the table added empty), and then keeps them.
TEST_F(MissionStoreTest, SchemaFourFileHasNoOverlayMaskUntilSaved) {
  const fs::path path = File("v4.saker");
  const Mission full = MakeFullMission();
  ASSERT_FALSE(full.overlays.empty());
  WriteMissionFile(path, full);
  ExecSql(path,
          "DROP TABLE overlays; "
          "ALTER TABLE frames DROP COLUMN sky_y0; ALTER TABLE frames DROP COLUMN sky_slope; "
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 4 WHERE key = 'schema_version'; PRAGMA user_version = 4");
  {
    auto m = LoadFile(path);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, 4);
    EXPECT_TRUE(m->overlays.empty());
    EXPECT_EQ(m->tracks.size(), full.tracks.size());
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, kSchemaVersion);
    EXPECT_TRUE(m->overlays.empty());
    ASSERT_TRUE((*store)->Save(full).ok());
  }
  auto m = LoadFile(path);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_SAME_MISSION(*m, full);
}

// Schema 5 (before the sky lines): read without them, upgraded in place when opened for writing
// (the columns added, empty), and then keeps them.
TEST_F(MissionStoreTest, SchemaFiveFileHasNoSkyLineUntilSaved) {
  const fs::path path = File("v5.saker");
  const Mission full = MakeFullMission();
  ASSERT_TRUE(std::any_of(full.frames.begin(), full.frames.end(),
                          [](const FrameRecord& f) { return f.sky_line.has_value(); }));
  WriteMissionFile(path, full);
  ExecSql(path,
          "ALTER TABLE frames DROP COLUMN sky_y0; ALTER TABLE frames DROP COLUMN sky_slope; "
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 5 WHERE key = 'schema_version'; PRAGMA user_version = 5");
  const auto no_sky = [](const Mission& m) {
    return std::none_of(m.frames.begin(), m.frames.end(),
                        [](const FrameRecord& f) { return f.sky_line.has_value(); });
  };
  {
    auto m = LoadFile(path);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, 5);
    EXPECT_TRUE(no_sky(*m));
    EXPECT_EQ(m->overlays.size(), full.overlays.size());
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto m = (*store)->Load();
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ(m->schema_version, kSchemaVersion);
    EXPECT_TRUE(no_sky(*m));
    ASSERT_TRUE((*store)->Save(full).ok());
  }
  auto m = LoadFile(path);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_SAME_MISSION(*m, full);
}

// A sky line that is not a line across the frame is refused on saving and on loading, naming the
// frame.
TEST_F(MissionStoreTest, ABadSkyLineIsRefused) {
  Mission bad = MakeFullMission();
  bad.frames[1].sky_line = SkyLine{100, std::numeric_limits<double>::quiet_NaN()};
  auto store = CreateOrDie(File("bad_sky.saker"));
  ASSERT_NE(store, nullptr);
  const Status saved = store->Save(bad);
  ASSERT_FALSE(saved.ok());
  EXPECT_NE(saved.message().find("frame " + std::to_string(bad.frames[1].index)), std::string::npos)
      << saved.ToString();
  store.reset();

  const fs::path path = File("steep_sky.saker");
  WriteMissionFile(path, MakeFullMission());
  ExecSql(path,
          "UPDATE frames SET sky_y0 = 10, sky_slope = 1e6 WHERE frame_index = (SELECT frame_index "
          "FROM frames ORDER BY frame_index LIMIT 1 OFFSET 1)");
  const auto loaded = LoadFile(path);
  ASSERT_FALSE(loaded.ok());
  EXPECT_NE(loaded.status().message().find("sky"), std::string::npos) << loaded.status().ToString();
  ExecSql(path,
          "UPDATE frames SET sky_y0 = 10, sky_slope = NULL WHERE frame_index = (SELECT frame_index "
          "FROM frames ORDER BY frame_index LIMIT 1 OFFSET 1)");
  EXPECT_FALSE(LoadFile(path).ok());
}

// A mask is found by frame (OverlayAt), and its cells by pixel, the cell's edges exactly.
TEST(OverlayRecordTest, LookupByFrameAndPixel) {
  const Mission full = MakeFullMission();
  ASSERT_EQ(full.overlays.size(), 2u);
  EXPECT_EQ(OverlayAt(full.overlays, 0), nullptr);
  EXPECT_EQ(OverlayAt(full.overlays, 1), &full.overlays[0]);
  EXPECT_EQ(OverlayAt(full.overlays, 5), &full.overlays[0]);
  EXPECT_EQ(OverlayAt(full.overlays, 6), nullptr);
  EXPECT_EQ(OverlayAt(full.overlays, 9), &full.overlays[1]);
  EXPECT_EQ(OverlayAt(full.overlays, 1000000007), &full.overlays[1]);
  EXPECT_EQ(OverlayAt(full.overlays, 1000000008), nullptr);

  OverlayRecord o;
  o.cell_px = 8;
  o.cols = 3;
  o.rows = 2;
  o.cells = {0, 1, 0, 0, 0, 1};
  EXPECT_TRUE(o.Problem().empty()) << o.Problem();
  // Cell (1, 0) covers pixels 8..15 by 0..7, whose centres are at integers.
  EXPECT_TRUE(o.Contains({7.5, -0.5}));
  EXPECT_TRUE(o.Contains({15.49, 7.49}));
  EXPECT_FALSE(o.Contains({7.49, 0}));
  EXPECT_FALSE(o.Contains({15.5, 0}));
  EXPECT_FALSE(o.Contains({8, 7.5}));
  EXPECT_TRUE(o.Contains({23.49, 15.49}));
  EXPECT_FALSE(o.Contains({23.5, 15}));  // beyond the grid
  EXPECT_FALSE(o.Contains({-1, 0}));
  EXPECT_FALSE(o.Contains({std::nan(""), 0}));
  EXPECT_DOUBLE_EQ(o.Coverage(), 2.0 / 6.0);
  o.cells.pop_back();
  EXPECT_NE(o.Problem().find("5 cells for a grid of 3x2"), std::string::npos) << o.Problem();
}

// Save refuses overlay masks the file's rules forbid, naming the mask, and the file keeps what it
// had.
TEST_F(MissionStoreTest, SaveRefusesBrokenOverlayMasks) {
  const fs::path path = File("overlays.saker");
  const Mission full = MakeFullMission();
  WriteMissionFile(path, full);
  const auto refused = [&](const Mission& bad, const std::string& expected) {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    const Status saved = (*store)->Save(bad);
    EXPECT_FALSE(saved.ok());
    EXPECT_NE(saved.message().find(expected), std::string::npos) << saved.ToString();
  };
  Mission overlapping = full;
  overlapping.overlays[1].first_frame = 5;
  refused(overlapping, "overlay mask 1 starts at frame 5, within the previous one (to frame 5)");
  Mission value = full;
  value.overlays[0].cells[3] = 2;
  refused(value, "overlay mask 0: a cell is neither 0 nor 1");
  Mission grid = full;
  grid.overlays[0].cell_px = 0;
  refused(grid, "overlay mask 0: cell size 0 px is outside [1, 1024]");
  auto m = LoadFile(path);
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_SAME_MISSION(*m, full);
}

TEST_F(MissionStoreTest, CheckpointRecordsAppendReplaceAndClear) {
  const fs::path path = File("checkpoint.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->Save(MakeFullMission()).ok());
  ASSERT_TRUE(store
                  ->WriteCheckpoint({{"frame", 2, RandomBytes(300, 1)},
                                     {"frame", 0, RandomBytes(10, 2)},
                                     {"state", 0, {7}},
                                     {"frame", 1, {}}})
                  .ok());
  // Appending more of one kind, replacing one record, and all of another kind.
  ASSERT_TRUE(store
                  ->WriteCheckpoint({{"frame", 3, RandomBytes(5, 3)},
                                     {"frame", 0, RandomBytes(12, 4)},
                                     {"state", 1, {9, 9}}},
                                    {"state"})
                  .ok());
  auto records = MissionStore::Open(path.string())->get()->ReadCheckpoint();
  ASSERT_TRUE(records.ok()) << records.status().ToString();
  ASSERT_EQ(records->size(), 5u);
  const std::vector<std::pair<std::string, int64_t>> expected = {
      {"frame", 0}, {"frame", 1}, {"frame", 2}, {"frame", 3}, {"state", 1}};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ((*records)[i].kind, expected[i].first);
    EXPECT_EQ((*records)[i].key, expected[i].second);
  }
  EXPECT_EQ((*records)[0].bytes, RandomBytes(12, 4));
  EXPECT_TRUE((*records)[1].bytes.empty());
  EXPECT_EQ((*records)[2].bytes, RandomBytes(300, 1));
  EXPECT_EQ((*records)[4].bytes, (std::vector<uint8_t>{9, 9}));

  // The mission itself is untouched by checkpoints.
  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, MakeFullMission());

  // Clearing gives the pages of a large checkpoint back to the file system.
  std::vector<CheckpointRecord> large;
  for (int i = 0; i < 40; ++i)
    large.push_back({"image", i, RandomBytes(100000, static_cast<uint32_t>(i))});
  ASSERT_TRUE(store->WriteCheckpoint(large).ok());
  store.reset();
  const auto size_with = fs::file_size(path);
  store = MissionStore::Open(path.string(), OpenMode::kReadWrite).value();
  ASSERT_TRUE(store->ClearCheckpoint().ok());
  store.reset();
  EXPECT_LT(fs::file_size(path) + 3'000'000, size_with);
  records = MissionStore::Open(path.string())->get()->ReadCheckpoint();
  ASSERT_TRUE(records.ok());
  EXPECT_TRUE(records->empty());
}

TEST_F(MissionStoreTest, CheckpointOfTheWrongTypesIsInvalidDataAndReadOnlyRefusesWrites) {
  const fs::path path = File("bad-checkpoint.saker");
  WriteMissionFile(path, MakeFullMission());
  ExecSql(path, "INSERT INTO checkpoint (kind, key, data) VALUES ('state', 0, 'text')");
  auto store = MissionStore::Open(path.string());
  ASSERT_TRUE(store.ok());
  auto records = (*store)->ReadCheckpoint();
  ASSERT_FALSE(records.ok());
  EXPECT_EQ(records.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(records.status().message().find("bad-checkpoint.saker: table checkpoint"),
            std::string::npos)
      << records.status().message();
  EXPECT_EQ((*store)->WriteCheckpoint({{"state", 0, {}}}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ((*store)->ClearCheckpoint().code(), StatusCode::kInvalidArgument);
}

TEST_F(MissionStoreTest, ComparisonHelperSeesSmallDifferences) {
  // The round trips above are only as strong as the comparison.
  const Mission a = MakeFullMission();
  std::string why;
  ASSERT_TRUE(MissionsEqual(a, a, &why)) << why;
  Mission b = a;
  b.key_frames[2].covariance(7, 6) += 1e-12;
  EXPECT_FALSE(MissionsEqual(a, b, &why));
  b = a;
  b.frames[4].sensor.reset();
  EXPECT_FALSE(MissionsEqual(a, b, &why));
  b = a;
  b.tracks[2].points[1].box_max.y() = -b.tracks[2].points[1].box_max.y();
  EXPECT_FALSE(MissionsEqual(a, b, &why));
  b = a;
  b.progress.cancelled = false;
  EXPECT_FALSE(MissionsEqual(a, b, &why));
}

TEST_F(MissionStoreTest, SecondMissionWithOtherOptionalsRoundTrips) {
  // Not geo-referenced, no pyramid, other progress flags, empty strings.
  Mission m = MakeFullMission();
  m.map = MapFrame{};
  m.pyramid.reset();
  m.progress = Progress{};
  m.progress.activity = true;
  m.options_json.clear();
  m.source.fingerprint.clear();
  m.links.clear();
  m.findings.reset();  // a mission from before they were kept
  const fs::path path = File("other.saker");
  WriteMissionFile(path, m);
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, m);
}

TEST_F(MissionStoreTest, NanAndInfinitePassThrough) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  Mission m = MakeFullMission();
  m.frames[0].time_s = nan;                   // a REAL column (stored as NULL)
  (*m.frames[0].map_from_frame)(1, 2) = nan;  // inside a blob
  m.key_frames[0].covariance(3, 3) = inf;
  m.tracks[0].points[0].map.x() = -inf;
  m.tracks[0].speed = nan;
  m.pyramid->step_x = nan;  // a meta value
  const fs::path path = File("nan.saker");
  WriteMissionFile(path, m);
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, m);
  EXPECT_TRUE(std::isnan(loaded->frames[0].time_s));
}

TEST_F(MissionStoreTest, FramesComeBackSortedByIndex) {
  Mission m = MakeFullMission();
  const Mission sorted = m;
  std::reverse(m.frames.begin(), m.frames.end());
  const fs::path path = File("sorted.saker");
  WriteMissionFile(path, m);
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, sorted);
}

TEST_F(MissionStoreTest, PartialSaveKeepsTheOtherParts) {
  const fs::path path = File("partial.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  const Mission first = MakeFullMission();
  ASSERT_TRUE(store->Save(first).ok());

  Mission second = MakeFullMission();
  second.saker_version = "second";
  second.progress.activity = true;
  second.frames.resize(2);
  second.key_frames.resize(1);
  second.links.resize(1);
  second.tracks.resize(1);
  second.tracks[0].id = 77;
  ASSERT_TRUE(store->Save(second, kSaveTracks).ok());

  // The header and the tracks are the second mission's; frames and graph the first one's.
  Mission expected = first;
  expected.saker_version = second.saker_version;
  expected.progress = second.progress;
  expected.tracks = second.tracks;
  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, expected);

  // Frames only, then the graph only.
  ASSERT_TRUE(store->Save(second, kSaveFrames).ok());
  expected.frames = second.frames;
  loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, expected);
  ASSERT_TRUE(store->Save(second, kSaveGraph).ok());
  loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, second);

  // The header alone.
  Mission header_only = second;
  header_only.saker_version = "third";
  header_only.frames.clear();
  ASSERT_TRUE(store->Save(header_only, 0).ok());
  loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_EQ(loaded->saker_version, "third");
  EXPECT_EQ(loaded->frames.size(), second.frames.size());
}

// The analyst's reviews and bookmarks: saved alone (SaveReviews), kept by the processing job's
// saves (which never name them), copied by a save that names them, read back exactly.
TEST_F(MissionStoreTest, ReviewsAndBookmarksRoundTripAndSurviveTheJobsSaves) {
  const fs::path path = File("reviews.saker");
  Mission m = MakeFullMission();
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->Save(m).ok());
  ASSERT_GE(m.tracks.size(), 1u);
  m.reviews = {{m.tracks[0].id, Verdict::kFalse, TargetLabel::kNone, ""},
               {m.tracks[0].id + 5, Verdict::kConfirmed, TargetLabel::kPerson,
                "walks to the car park — \"blue jacket\"\nsecond line"}};
  m.bookmarks = {{1, 12.5, {100.25, -40}, "gate"}, {4, 30, {0, 0}, ""}};
  ASSERT_TRUE(store->SaveReviews(m).ok());
  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, m);
  EXPECT_TRUE(IsMarkedFalse(*loaded, m.tracks[0].id));
  ASSERT_NE(ReviewOf(*loaded, m.tracks[0].id + 5), nullptr);
  EXPECT_EQ(ReviewOf(*loaded, m.tracks[0].id + 5)->label, TargetLabel::kPerson);
  EXPECT_EQ(ReviewOf(*loaded, m.tracks[0].id + 1), nullptr);

  // A job's save (tracks again, no reviews in its mission) keeps them.
  Mission job = m;
  job.reviews.clear();
  job.bookmarks.clear();
  ASSERT_TRUE(store->Save(job).ok());
  loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_EQ(loaded->reviews.size(), 2u);
  EXPECT_EQ(loaded->bookmarks.size(), 2u);
  // A save that names them replaces them.
  ASSERT_TRUE(store->Save(job, kSaveAll | kSaveReviews).ok());
  loaded = store->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_TRUE(loaded->reviews.empty());
  EXPECT_TRUE(loaded->bookmarks.empty());
}

TEST_F(MissionStoreTest, SaveReviewsRefusesWhatTheFileCannotHold) {
  const fs::path path = File("bad-reviews.saker");
  Mission m = MakeFullMission();
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  ASSERT_TRUE(store->Save(m).ok());
  m.reviews = {{3, Verdict::kConfirmed, TargetLabel::kVehicle, "kept"}};
  ASSERT_TRUE(store->SaveReviews(m).ok());
  const auto refused = [&](const Mission& bad, const std::string& words) {
    const Status status = store->SaveReviews(bad);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << words;
    EXPECT_NE(status.message().find(words), std::string::npos) << status.message();
    EXPECT_NE(status.message().find(path.string()), std::string::npos) << status.message();
    auto loaded = store->Load();
    ASSERT_TRUE(loaded.ok());
    ASSERT_EQ(loaded->reviews.size(), 1u) << "the file keeps what it had";
    EXPECT_EQ(loaded->reviews[0].note, "kept");
  };
  Mission bad = m;
  bad.reviews = {{5, Verdict::kFalse, TargetLabel::kNone, ""}, {5, Verdict::kNone, {}, "x"}};
  refused(bad, "out of order or repeated");
  bad = m;
  bad.reviews[0].note = std::string(kMaxNoteBytes + 1, 'a');
  refused(bad, "more than 10000");
  bad = m;
  bad.reviews[0].verdict = static_cast<Verdict>(9);
  refused(bad, "unknown verdict");
  bad = m;
  bad.bookmarks = {{1, std::nan(""), {0, 0}, ""}};
  refused(bad, "not a finite number");
  bad = m;
  bad.bookmarks = {{0, 1, {0, 0}, ""}};
  refused(bad, "not positive");
  // A note that long written by another tool is refused on loading, naming the table.
  ExecSql(path, "UPDATE track_reviews SET note = '" + std::string(kMaxNoteBytes + 1, 'b') + "'");
  const auto loaded = store->Load();
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(loaded.status().message().find("track_reviews"), std::string::npos)
      << loaded.status().message();
  // A read-only store does not write them.
  auto reader = MissionStore::Open(path.string());
  ASSERT_TRUE(reader.ok());
  EXPECT_EQ((*reader)->SaveReviews(m).code(), StatusCode::kInvalidArgument);
}

// A mission of schema 6 (before reviews): read with none, upgraded when opened for writing.
TEST_F(MissionStoreTest, SchemaSixFileHasNoReviewsUntilUpgraded) {
  const fs::path path = File("v6.saker");
  Mission m = MakeFullMission();
  WriteMissionFile(path, m);
  ExecSql(path,
          "DROP TABLE track_reviews; DROP TABLE bookmarks; "
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 6 WHERE key = 'schema_version'; PRAGMA user_version = 6");
  {
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto loaded = (*store)->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(loaded->schema_version, 6);
    EXPECT_TRUE(loaded->reviews.empty());
  }
  auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  m.reviews = {{1, Verdict::kFalse, TargetLabel::kOther, "a shadow"}};
  ASSERT_TRUE((*store)->SaveReviews(m).ok());
  auto loaded = (*store)->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_EQ(loaded->schema_version, kSchemaVersion);
  ASSERT_EQ(loaded->reviews.size(), 1u);
  EXPECT_EQ(loaded->reviews[0].note, "a shadow");
}

// A mission of schema 7 (before interpolated track points): every point read as seen; upgraded
// when opened for writing, after which the flags are kept.
TEST_F(MissionStoreTest, SchemaSevenFileHasOnlySeenPointsUntilUpgraded) {
  const fs::path path = File("v7.saker");
  const Mission full = MakeFullMission();
  WriteMissionFile(path, full);
  ExecSql(path,
          "ALTER TABLE track_points DROP COLUMN interpolated; "
          "UPDATE meta SET value = 7 WHERE key = 'schema_version'; PRAGMA user_version = 7");
  {
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto loaded = store.value()->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(loaded->schema_version, 7);
    ASSERT_EQ(loaded->tracks.size(), full.tracks.size());
    for (const ActivityTrack& t : loaded->tracks) {
      for (const TrackPoint& p : t.points) EXPECT_FALSE(p.interpolated);
    }
  }
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)->Save(full).ok());
  }
  auto store = MissionStore::Open(path.string());
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  auto loaded = (*store)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_EQ(loaded->schema_version, kSchemaVersion);
  EXPECT_SAME_MISSION(*loaded, full);
}

TEST_F(MissionStoreTest, SaveRefusesWhatTheFileCannotHoldAndKeepsTheFile) {
  const fs::path path = File("refuse.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  const Mission good = MakeFullMission();
  ASSERT_TRUE(store->Save(good).ok());

  Mission duplicate = good;
  duplicate.frames[3].index = duplicate.frames[1].index;
  Mission origin_without_geo = good;
  origin_without_geo.map.geo_referenced = false;
  Mission geo_without_origin = good;
  geo_without_origin.map.origin.reset();
  Mission bad_kind = good;
  bad_kind.links[1].kind = static_cast<LinkKind>(17);
  Mission bad_pyramid = good;
  bad_pyramid.pyramid->levels = 1000;
  Mission bad_findings = good;
  bad_findings.findings->noise_change_grey = -1;
  for (const Mission* bad : {&duplicate, &origin_without_geo, &geo_without_origin, &bad_kind,
                             &bad_pyramid, &bad_findings}) {
    const Status status = store->Save(*bad);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << status.ToString();
    EXPECT_NE(status.message().find(path.string()), std::string::npos) << status.message();
  }
  EXPECT_EQ(store->Save(good, 16u).code(), StatusCode::kInvalidArgument);
  // A duplicate frame index does not matter when frames are not saved.
  EXPECT_TRUE(store->Save(duplicate, kSaveTracks).ok());

  auto loaded = store->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, good);
}

TEST_F(MissionStoreTest, LargeMissionRoundTrip) {
  // 100 000 frames, 2 000 key frames and links, 500 tracks of 200 points. The times are printed
  // for the record (docs/mission-file.md), not asserted.
  Mission m;
  m.saker_version = "large";
  m.map.geo_referenced = true;
  m.map.origin = geo::Wgs84{50, 8, 200};
  m.frames.resize(100000);
  for (size_t i = 0; i < m.frames.size(); ++i) {
    FrameRecord& f = m.frames[i];
    f.index = static_cast<int64_t>(i);
    f.time_s = static_cast<double>(i) / 25.0;
    f.utc_us = 1700000000000000 + 40000 * static_cast<int64_t>(i);
    f.map_from_frame = testing_support::PatternMatrix<Eigen::Matrix3d>(static_cast<double>(i));
    f.metadata_corners = std::array<Eigen::Vector2d, 4>{
        Eigen::Vector2d(i, 1), Eigen::Vector2d(i, 2), Eigen::Vector2d(i, 3), Eigen::Vector2d(i, 4)};
    f.sensor = geo::Wgs84{50 + 1e-6 * static_cast<double>(i), 8, 1500};
  }
  for (int i = 0; i < 2000; ++i) {
    KeyFrameRecord k;
    k.id = i;
    k.frame_index = 50 * i;
    k.map_from_frame = testing_support::PatternMatrix<Eigen::Matrix3d>(i);
    k.covariance = testing_support::PatternMatrix<Covariance8>(i);
    m.key_frames.push_back(k);
    LinkRecord l;
    l.from = i;
    l.to = (i + 1) % 2000;
    l.kind = i % 10 == 0 ? LinkKind::kGeometric : LinkKind::kSequential;
    l.covariance = k.covariance;
    m.links.push_back(l);
  }
  for (int i = 0; i < 500; ++i) {
    ActivityTrack t;
    t.id = i;
    for (int j = 0; j < 200; ++j) {
      TrackPoint p;
      p.frame = 100 * i + j;
      p.time_s = p.frame / 25.0;
      p.image = Eigen::Vector2d(j, i);
      p.map = Eigen::Vector2d(j * 0.5, i * 0.5);
      t.points.push_back(p);
    }
    m.tracks.push_back(t);
  }
  const fs::path path = File("large.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  ASSERT_TRUE(store->Save(m).ok());
  const auto t1 = Clock::now();
  ASSERT_TRUE(store->Save(m).ok());  // replacing what is there
  const auto t2 = Clock::now();
  auto loaded = store->Load();
  const auto t3 = Clock::now();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, m);
  auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  std::cout << "[ timing   ] save (new) " << ms(t1 - t0) << " ms, save (replace) " << ms(t2 - t1)
            << " ms, load " << ms(t3 - t2) << " ms, file " << fs::file_size(path) / 1e6 << " MB\n";
}

// ---------------------------------------------------------------------------------------------
// Tiles.

TEST_F(MissionStoreTest, TilesRoundTripReplaceClearAndCount) {
  const fs::path path = File("tiles.saker");
  auto store = CreateOrDie(path);
  ASSERT_NE(store, nullptr);
  auto count = store->CountTiles();
  ASSERT_TRUE(count.ok());
  EXPECT_EQ(*count, 0);

  std::vector<EncodedTile> tiles;
  for (int level = 0; level < 3; ++level) {
    for (int x = 0; x < 3; ++x) {
      for (int y = 0; y < 2; ++y) {
        tiles.push_back({level, x, y,
                         RandomBytes(static_cast<size_t>(100 + 1000 * level + 10 * x + y),
                                     static_cast<uint32_t>(level * 100 + x * 10 + y))});
      }
    }
  }
  tiles.push_back({5, 7, 9, {}});  // an empty tile is stored as such
  ASSERT_TRUE(store->WriteTiles(tiles).ok());
  count = store->CountTiles();
  ASSERT_TRUE(count.ok());
  EXPECT_EQ(*count, static_cast<int64_t>(tiles.size()));
  for (const EncodedTile& tile : tiles) {
    auto read = store->ReadTile(tile.level, tile.x, tile.y);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ASSERT_TRUE(read->has_value());
    EXPECT_EQ(**read, tile.bytes);
  }
  auto absent = store->ReadTile(1, 3, 0);
  ASSERT_TRUE(absent.ok());
  EXPECT_FALSE(absent->has_value());
  absent = store->ReadTile(-1, 0, 0);
  ASSERT_TRUE(absent.ok());
  EXPECT_FALSE(absent->has_value());

  // Same key: replaced, not added.
  const std::vector<uint8_t> replacement = RandomBytes(333, 99);
  ASSERT_TRUE(store->WriteTiles({{1, 2, 1, replacement}}).ok());
  count = store->CountTiles();
  ASSERT_TRUE(count.ok());
  EXPECT_EQ(*count, static_cast<int64_t>(tiles.size()));
  auto read = store->ReadTile(1, 2, 1);
  ASSERT_TRUE(read.ok() && read->has_value());
  EXPECT_EQ(**read, replacement);

  // Tiles do not disturb the mission, and another reader sees them.
  ASSERT_TRUE(store->Save(MakeFullMission()).ok());
  {
    auto reader = MissionStore::Open(path.string());
    ASSERT_TRUE(reader.ok()) << reader.status().ToString();
    auto other = (*reader)->ReadTile(2, 2, 1);
    ASSERT_TRUE(other.ok() && other->has_value());
    EXPECT_EQ(**other, tiles[2 * 6 + 2 * 2 + 1].bytes);
  }

  EXPECT_EQ(store->WriteTiles({{0, -1, 0, {1}}}).code(), StatusCode::kInvalidArgument);
  ASSERT_TRUE(store->ClearTiles().ok());
  count = store->CountTiles();
  ASSERT_TRUE(count.ok());
  EXPECT_EQ(*count, 0);
  read = store->ReadTile(0, 0, 0);
  ASSERT_TRUE(read.ok());
  EXPECT_FALSE(read->has_value());
  auto mission = store->Load();
  ASSERT_TRUE(mission.ok());
  EXPECT_SAME_MISSION(*mission, MakeFullMission());
}

// ---------------------------------------------------------------------------------------------
// Create.

bool HasLeftovers(const fs::path& dir) {
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().filename().string().find(".part-") != std::string::npos) return true;
  }
  return false;
}

TEST_F(MissionStoreTest, CreateNeverOverwritesAForeignFile) {
  const fs::path path = File("notes.saker");
  const std::vector<uint8_t> bytes = RandomBytes(5000, 7);
  WriteFileBytes(path, bytes);
  for (bool replace : {false, true}) {
    auto store = MissionStore::Create(path.string(), replace);
    ASSERT_FALSE(store.ok());
    EXPECT_NE(store.status().message().find(path.string()), std::string::npos)
        << store.status().message();
    EXPECT_EQ(ReadBytes(path), bytes);
  }
  // Text and a zero-byte file are foreign too.
  const fs::path text = File("text.saker");
  const std::string words = "not a mission\n";
  WriteFileBytes(text, std::vector<uint8_t>(words.begin(), words.end()));
  EXPECT_FALSE(MissionStore::Create(text.string(), true).ok());
  EXPECT_EQ(ReadBytes(text), std::vector<uint8_t>(words.begin(), words.end()));
  const fs::path empty = File("empty.saker");
  WriteFileBytes(empty, {});
  EXPECT_FALSE(MissionStore::Create(empty.string(), true).ok());
  EXPECT_EQ(fs::file_size(empty), 0u);
  EXPECT_FALSE(HasLeftovers(dir_));
}

TEST_F(MissionStoreTest, CreateRefusesAnExistingMissionWithoutReplace) {
  const fs::path path = File("keep.saker");
  WriteMissionFile(path, MakeFullMission());
  const std::vector<uint8_t> before = ReadBytes(path);
  auto store = MissionStore::Create(path.string());
  ASSERT_FALSE(store.ok());
  EXPECT_EQ(store.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(store.status().message().find(path.string()), std::string::npos);
  EXPECT_EQ(ReadBytes(path), before);
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, MakeFullMission());
}

TEST_F(MissionStoreTest, CreateReplacesAMissionWhenAsked) {
  const fs::path path = File("replace.saker");
  WriteMissionFile(path, MakeFullMission());
  {
    auto store = MissionStore::Create(path.string(), /*replace=*/true);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto loaded = (*store)->Load();
    ASSERT_TRUE(loaded.ok());
    EXPECT_SAME_MISSION(*loaded, Mission{});
    EXPECT_EQ((*store)->CountTiles().value(), 0);
  }
  auto loaded = LoadFile(path);
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, Mission{});
  EXPECT_FALSE(HasLeftovers(dir_));
}

TEST_F(MissionStoreTest, CreateReplacesAMissionWithAnUncheckpointedLog) {
  // A writer still holds the old mission's last save in its write-ahead log when the file is
  // copied: the copy's log must not be replayed onto the replacement.
  const fs::path path = File("logged.saker");
  {
    auto writer = CreateOrDie(File("source.saker"));
    ASSERT_NE(writer, nullptr);
    ASSERT_TRUE(writer->Save(MakeFullMission()).ok());
    ASSERT_TRUE(fs::exists(File("source.saker-wal")));
    ASSERT_GT(fs::file_size(File("source.saker-wal")), 0u);
    fs::copy_file(File("source.saker"), path);
    fs::copy_file(File("source.saker-wal"), File("logged.saker-wal"));
  }
  auto before = LoadFile(path);
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  EXPECT_SAME_MISSION(*before, MakeFullMission());
  {
    auto store = MissionStore::Create(path.string(), /*replace=*/true);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
  }
  auto after = LoadFile(path);
  ASSERT_TRUE(after.ok()) << after.status().ToString();
  EXPECT_SAME_MISSION(*after, Mission{});
}

TEST_F(MissionStoreTest, CreateNeverReplacesANewerOrCorruptMission) {
  const fs::path newer = File("newer.saker");
  WriteMissionFile(newer, MakeFullMission());
  ExecSql(newer, "UPDATE meta SET value = 9 WHERE key = 'schema_version'; PRAGMA user_version = 9");
  const fs::path corrupt = File("corrupt.saker");
  WriteMissionFile(corrupt, MakeFullMission());
  std::vector<uint8_t> bytes = ReadBytes(corrupt);
  bytes.resize(bytes.size() / 2);
  WriteFileBytes(corrupt, bytes);
  for (const fs::path& path : {newer, corrupt}) {
    const std::vector<uint8_t> before = ReadBytes(path);
    auto store = MissionStore::Create(path.string(), /*replace=*/true);
    ASSERT_FALSE(store.ok()) << path;
    EXPECT_NE(store.status().message().find(path.string()), std::string::npos);
    EXPECT_EQ(ReadBytes(path), before) << path;
  }
  EXPECT_EQ(MissionStore::Create(newer.string(), true).status().code(), StatusCode::kUnsupported);
  EXPECT_FALSE(HasLeftovers(dir_));
}

TEST_F(MissionStoreTest, CreateFailsInAMissingDirectory) {
  auto store = MissionStore::Create((dir_ / "no" / "such" / "dir.saker").string());
  EXPECT_FALSE(store.ok());
}

// ---------------------------------------------------------------------------------------------
// Open errors.

struct BadFile {
  std::string name;
  StatusCode code;
};

TEST_F(MissionStoreTest, OpenRefusesBadFilesWithoutTouchingThem) {
  std::vector<BadFile> cases;
  // Missing.
  cases.push_back({"missing.saker", StatusCode::kNotFound});
  // Zero bytes.
  WriteFileBytes(File("zero.saker"), {});
  cases.push_back({"zero.saker", StatusCode::kInvalidData});
  // A real mission cut to half its size.
  {
    Mission big = MakeFullMission();
    for (int i = 0; i < 2000; ++i) {
      FrameRecord f = big.frames[0];
      f.index = 2000000000 + i;
      big.frames.push_back(f);
    }
    WriteMissionFile(File("whole.saker"), big);
    std::vector<uint8_t> bytes = ReadBytes(File("whole.saker"));
    ASSERT_GT(bytes.size(), 100000u);
    bytes.resize(bytes.size() / 2);
    WriteFileBytes(File("truncated.saker"), bytes);
    cases.push_back({"truncated.saker", StatusCode::kInvalidData});
    // The same with its first page intact but the rest overwritten.
    bytes = ReadBytes(File("whole.saker"));
    const std::vector<uint8_t> noise = RandomBytes(bytes.size(), 11);
    std::copy(noise.begin() + 4096, noise.end(), bytes.begin() + 4096);
    WriteFileBytes(File("scrambled.saker"), bytes);
    cases.push_back({"scrambled.saker", StatusCode::kInvalidData});
  }
  // Random bytes; random bytes after a valid SQLite magic.
  WriteFileBytes(File("random.saker"), RandomBytes(8192, 3));
  cases.push_back({"random.saker", StatusCode::kInvalidData});
  {
    std::vector<uint8_t> bytes = RandomBytes(8192, 4);
    const char magic[] = "SQLite format 3";
    std::copy(magic, magic + sizeof(magic), bytes.begin());
    WriteFileBytes(File("magic.saker"), bytes);
    cases.push_back({"magic.saker", StatusCode::kInvalidData});
  }
  // SQLite databases that are not missions.
  ExecSql(File("other.db"), "CREATE TABLE t (x); INSERT INTO t VALUES (42)");
  cases.push_back({"other.db", StatusCode::kInvalidData});
  ExecSql(File("same_id.db"), "PRAGMA application_id = " + std::to_string(kMissionApplicationId) +
                                  "; CREATE TABLE t (x)");
  cases.push_back({"same_id.db", StatusCode::kInvalidData});
  ExecSql(File("no_version.db"),
          "PRAGMA application_id = " + std::to_string(kMissionApplicationId) +
              "; CREATE TABLE meta (key TEXT PRIMARY KEY, value)");
  cases.push_back({"no_version.db", StatusCode::kInvalidData});
  // A mission missing one of its tables.
  WriteMissionFile(File("no_links.saker"), MakeFullMission());
  ExecSql(File("no_links.saker"), "DROP TABLE links");
  cases.push_back({"no_links.saker", StatusCode::kInvalidData});
  WriteMissionFile(File("no_overlays.saker"), MakeFullMission());
  ExecSql(File("no_overlays.saker"), "DROP TABLE overlays");
  cases.push_back({"no_overlays.saker", StatusCode::kInvalidData});
  // Newer schema, in meta only and in both places.
  WriteMissionFile(File("newer.saker"), MakeFullMission());
  ExecSql(File("newer.saker"), "UPDATE meta SET value = 9 WHERE key = 'schema_version'");
  cases.push_back({"newer.saker", StatusCode::kUnsupported});
  WriteMissionFile(File("newer2.saker"), MakeFullMission());
  ExecSql(File("newer2.saker"),
          "UPDATE meta SET value = 9 WHERE key = 'schema_version'; PRAGMA user_version = 9");
  cases.push_back({"newer2.saker", StatusCode::kUnsupported});

  for (const BadFile& c : cases) {
    const fs::path path = File(c.name);
    const bool exists = fs::exists(path);
    const std::vector<uint8_t> before = exists ? ReadBytes(path) : std::vector<uint8_t>{};
    for (OpenMode mode : {OpenMode::kReadOnly, OpenMode::kReadWrite}) {
      SCOPED_TRACE(c.name + (mode == OpenMode::kReadOnly ? " read-only" : " read-write"));
      auto store = MissionStore::Open(path.string(), mode);
      ASSERT_FALSE(store.ok());
      EXPECT_EQ(store.status().code(), c.code) << store.status().ToString();
      EXPECT_NE(store.status().message().find(path.string()), std::string::npos)
          << store.status().message();
      if (exists) {
        EXPECT_EQ(ReadBytes(path), before);
      } else {
        EXPECT_FALSE(fs::exists(path));
      }
    }
  }
  auto newer = MissionStore::Open(File("newer.saker").string());
  EXPECT_NE(newer.status().message().find("written by a newer Saker: schema 9, this version "
                                          "reads up to " +
                                          std::to_string(kSchemaVersion)),
            std::string::npos)
      << newer.status().message();
}

// ---------------------------------------------------------------------------------------------
// Hostile content: Open succeeds (it only identifies the file), Load refuses.

struct Tamper {
  std::string sql;
  std::string table;  // named in the message
};

TEST_F(MissionStoreTest, LoadRefusesInconsistentContent) {
  const fs::path base = File("base.saker");
  WriteMissionFile(base, MakeFullMission());
  const std::vector<Tamper> cases = {
      {"UPDATE key_frames SET map_from_frame = x'00' WHERE ordinal = 1", "key_frames"},
      {"UPDATE key_frames SET covariance = 'text'", "key_frames"},
      {"UPDATE key_frames SET id = 5000000000 WHERE ordinal = 2", "key_frames"},
      {"UPDATE key_frames SET node = 2", "key_frames"},
      {"UPDATE links SET kind = 'telepathic' WHERE ordinal = 2", "links"},
      {"UPDATE overlays SET cells = zeroblob(3) WHERE ordinal = 0", "overlays"},
      {"UPDATE overlays SET cells = 'text' WHERE ordinal = 1", "overlays"},
      {"UPDATE overlays SET first_frame = 4 WHERE ordinal = 1", "overlays"},
      {"UPDATE overlays SET last_frame = 0 WHERE ordinal = 0", "overlays"},
      {"UPDATE overlays SET cols = 100000 WHERE ordinal = 0", "overlays"},
      {"UPDATE overlays SET cell_px = -8 WHERE ordinal = 1", "overlays"},
      {"DELETE FROM overlays WHERE ordinal = 0", "overlays"},
      {"UPDATE links SET kind = 42", "links"},
      {"DELETE FROM links WHERE ordinal = 1", "links"},
      {"UPDATE links SET covariance = zeroblob(511)", "links"},
      {"UPDATE frames SET utc_us = 'soon' WHERE frame_index = 0", "frames"},
      {"UPDATE frames SET metadata_corners = zeroblob(72) WHERE frame_index = 0", "frames"},
      {"UPDATE frames SET map_from_frame = 'abc' WHERE frame_index = 0", "frames"},
      {"UPDATE frames SET time_s = x'0102' WHERE frame_index = 1", "frames"},
      {"DELETE FROM track_points WHERE track_ordinal = 0 AND ordinal = 3", "track_points"},
      {"UPDATE tracks SET point_count = 6 WHERE ordinal = 0", "track_points"},
      {"UPDATE tracks SET point_count = 1 WHERE ordinal = 0", "track_points"},
      {"UPDATE track_points SET track_ordinal = 7 WHERE track_ordinal = 2 AND ordinal = 0",
       "track_points"},
      {"UPDATE tracks SET ordinal = 5 WHERE ordinal = 2", "tracks"},
      {"UPDATE tracks SET visit = 1.5", "tracks"},
      {"UPDATE tracks SET confidence = 1.5 WHERE ordinal = 1", "tracks"},
      {"UPDATE tracks SET confidence = 'high' WHERE ordinal = 0", "tracks"},
      {"UPDATE meta SET value = 7 WHERE key = 'progress_mosaic'", "meta"},
      {"UPDATE meta SET value = 'yes' WHERE key = 'map_geo_referenced'", "meta"},
      {"DELETE FROM meta WHERE key = 'pyramid_step_x'", "meta"},
      {"DELETE FROM meta WHERE key = 'saker_version'", "meta"},
      {"DELETE FROM meta WHERE key LIKE 'map_origin%'", "meta"},
      {"UPDATE meta SET value = 99999 WHERE key = 'pyramid_levels'", "meta"},
      {"UPDATE meta SET value = x'00' WHERE key = 'options_json'", "meta"},
      {"DELETE FROM source", "source"},
      {"INSERT INTO source (id, path, fingerprint, size_bytes, width, height, frame_count) "
       "VALUES (2, '', '', 0, 0, 0, 0)",
       "source"},
      {"UPDATE source SET width = 1e12", "source"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const Tamper& c = cases[i];
    SCOPED_TRACE(c.sql);
    const fs::path path = File("tampered" + std::to_string(i) + ".saker");
    fs::copy_file(base, path);
    // Bypass the schema's own CHECK and foreign key constraints, as a hostile writer would.
    ExecSql(path, "PRAGMA ignore_check_constraints = ON; " + c.sql);
    const std::vector<uint8_t> before = ReadBytes(path);
    auto store = MissionStore::Open(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto loaded = (*store)->Load();
    ASSERT_FALSE(loaded.ok());
    EXPECT_EQ(loaded.status().code(), StatusCode::kInvalidData) << loaded.status().ToString();
    EXPECT_NE(loaded.status().message().find(path.string()), std::string::npos)
        << loaded.status().message();
    EXPECT_NE(loaded.status().message().find("table " + c.table), std::string::npos)
        << loaded.status().message();
    store = Status(StatusCode::kCancelled, "closed");
    EXPECT_EQ(ReadBytes(path), before);
  }
}

TEST_F(MissionStoreTest, ReadTileRefusesATileThatIsNotABlob) {
  const fs::path path = File("text_tile.saker");
  {
    auto store = CreateOrDie(path);
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->WriteTiles({{0, 0, 0, {1, 2, 3}}}).ok());
  }
  ExecSql(path, "UPDATE tiles SET data = 'png?'");
  auto store = MissionStore::Open(path.string());
  ASSERT_TRUE(store.ok());
  auto tile = (*store)->ReadTile(0, 0, 0);
  ASSERT_FALSE(tile.ok());
  EXPECT_EQ(tile.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(tile.status().message().find("tiles"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Modes and concurrency.

TEST_F(MissionStoreTest, ReadOnlyStoreRefusesWrites) {
  const fs::path path = File("ro.saker");
  WriteMissionFile(path, MakeFullMission());
  const std::vector<uint8_t> before = ReadBytes(path);
  auto store = MissionStore::Open(path.string(), OpenMode::kReadOnly);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  EXPECT_EQ((*store)->mode(), OpenMode::kReadOnly);
  Mission other;
  other.saker_version = "other";
  EXPECT_EQ((*store)->Save(other).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ((*store)->WriteTiles({{0, 0, 0, {1, 2, 3}}}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ((*store)->ClearTiles().code(), StatusCode::kInvalidArgument);
  auto loaded = (*store)->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, MakeFullMission());
  store = Status(StatusCode::kCancelled, "closed");
  EXPECT_EQ(ReadBytes(path), before);
}

TEST_F(MissionStoreTest, ReaderLoadsWhileAWriterIsOpen) {
  const fs::path path = File("shared.saker");
  auto writer = CreateOrDie(path);
  ASSERT_NE(writer, nullptr);
  const Mission first = MakeFullMission();
  ASSERT_TRUE(writer->Save(first).ok());
  ASSERT_TRUE(writer->WriteTiles({{0, 0, 0, {9, 8, 7}}}).ok());

  auto reader = MissionStore::Open(path.string(), OpenMode::kReadOnly);
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  auto loaded = (*reader)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, first);

  // The writer goes on; the open reader sees each commit.
  Mission second = first;
  second.saker_version = "second";
  second.tracks.pop_back();
  ASSERT_TRUE(writer->Save(second).ok());
  loaded = (*reader)->Load();
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  EXPECT_SAME_MISSION(*loaded, second);
  auto tile = (*reader)->ReadTile(0, 0, 0);
  ASSERT_TRUE(tile.ok() && tile->has_value());
  EXPECT_EQ(**tile, (std::vector<uint8_t>{9, 8, 7}));

  // A second writer is refused while the first one is open (its lock,
  // mission/MissionAccessTest), and takes over the writing once it is closed.
  EXPECT_EQ(MissionStore::Open(path.string(), OpenMode::kReadWrite).status().code(),
            StatusCode::kIoError);
  writer.reset();
  auto writer2 = MissionStore::Open(path.string(), OpenMode::kReadWrite);
  ASSERT_TRUE(writer2.ok()) << writer2.status().ToString();
  ASSERT_TRUE((*writer2)->Save(first).ok());
  loaded = (*reader)->Load();
  ASSERT_TRUE(loaded.ok());
  EXPECT_SAME_MISSION(*loaded, first);
}

// A mission whose every table encodes `generation`, so a mix of two saves is visible.
Mission GenerationMission(int64_t generation) {
  Mission m;
  m.saker_version = "generation " + std::to_string(generation);
  m.options_json = "{\"generation\": " + std::to_string(generation) + "}";
  m.source.frame_count = generation;
  m.map.geo_referenced = generation % 2 == 1;
  if (m.map.geo_referenced) m.map.origin = geo::Wgs84{static_cast<double>(generation), 1, 2};
  const int frames = 300 + static_cast<int>(generation * 37 % 400);
  for (int i = 0; i < frames; ++i) {
    FrameRecord f;
    f.index = i;
    f.time_s = static_cast<double>(generation);
    f.utc_us = generation;
    f.map_from_frame = Eigen::Matrix3d::Constant(static_cast<double>(generation));
    m.frames.push_back(f);
  }
  const int key_frames = 40 + static_cast<int>(generation % 30);
  for (int i = 0; i < key_frames; ++i) {
    KeyFrameRecord k;
    k.id = static_cast<int32_t>(generation);
    k.segment = i;
    k.covariance = Covariance8::Constant(static_cast<double>(generation));
    m.key_frames.push_back(k);
    LinkRecord l;
    l.correspondences = static_cast<int32_t>(generation);
    m.links.push_back(l);
  }
  const int tracks = 10 + static_cast<int>(generation % 7);
  for (int i = 0; i < tracks; ++i) {
    ActivityTrack t;
    t.id = generation;
    t.points.resize(static_cast<size_t>(30 + i));
    for (TrackPoint& p : t.points) p.frame = generation;
    m.tracks.push_back(t);
  }
  PyramidInfo pyramid;
  pyramid.levels = static_cast<int>(generation % 20);
  m.pyramid = pyramid;
  m.progress.mosaic = generation % 3 == 0;
  return m;
}

// The generation a loaded mission was saved as, or -1 when it is not exactly one generation.
int64_t GenerationOf(const Mission& m, std::string* why) {
  int64_t generation = -1;
  if (std::sscanf(m.saker_version.c_str(), "generation %" SCNd64, &generation) != 1) {
    *why = "no generation in saker_version '" + m.saker_version + "'";
    return -1;
  }
  if (!MissionsEqual(m, GenerationMission(generation), why)) return -1;
  return generation;
}

TEST_F(MissionStoreTest, ConcurrentLoadsSeeWholeSaves) {
  const fs::path path = File("concurrent.saker");
  {
    auto store = CreateOrDie(path);
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->Save(GenerationMission(0)).ok());
  }
  std::atomic<bool> stop{false};
  std::atomic<int64_t> committed{0};
  std::string writer_error;
  std::thread writer([&] {
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    if (!store.ok()) {
      writer_error = store.status().ToString();
      return;
    }
    for (int64_t g = 1; !stop; ++g) {
      const Status saved = (*store)->Save(GenerationMission(g));
      if (!saved.ok()) {
        writer_error = saved.ToString();
        return;
      }
      committed = g;
    }
  });
  // Stops and joins the writer however this test ends (an ASSERT returns early).
  struct JoinOnExit {
    std::atomic<bool>* stop;
    std::thread* thread;
    ~JoinOnExit() {
      *stop = true;
      if (thread->joinable()) thread->join();
    }
  } join_on_exit{&stop, &writer};
  auto reader = MissionStore::Open(path.string());
  ASSERT_TRUE(reader.ok()) << reader.status().ToString();
  int64_t last = 0;
  int distinct = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(1500);
  while (std::chrono::steady_clock::now() < deadline && distinct < 30) {
    const int64_t before = committed;
    auto loaded = (*reader)->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    std::string why;
    const int64_t g = GenerationOf(*loaded, &why);
    ASSERT_GE(g, 0) << why;
    EXPECT_GE(g, before);  // never older than a commit that finished before the load
    EXPECT_GE(g, last);
    if (g != last) ++distinct;
    last = g;
  }
  stop = true;
  writer.join();
  EXPECT_EQ(writer_error, "");
  EXPECT_GT(distinct, 1);
}

TEST_F(MissionStoreTest, KillNineLeavesTheLastCommittedSave) {
  using Clock = std::chrono::steady_clock;
  const fs::path path = File("killed.saker");
  int64_t save_us = 0;  // one save's duration, so the kills land inside the save loop
  {
    auto store = CreateOrDie(path);
    ASSERT_NE(store, nullptr);
    ASSERT_TRUE(store->Save(GenerationMission(0)).ok());
    const auto start = Clock::now();
    for (int i = 0; i < 3; ++i) ASSERT_TRUE(store->Save(GenerationMission(0)).ok());
    save_us =
        std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start).count() / 3;
  }  // closed: no connection crosses fork()
  std::mt19937 random(20240607);
  int64_t generation = 0;
  int progressed = 0;
  const int kRounds = 25;
  for (int round = 0; round < kRounds; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    int fds[2];
    ASSERT_EQ(::pipe(fds), 0);
    const int64_t first = generation + 1;
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      // Only the store, the pipe and _exit here: the child shares the parent's memory image.
      ::close(fds[0]);
      auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
      if (!store.ok()) ::_exit(2);
      const int64_t ready = -1;
      if (::write(fds[1], &ready, sizeof(ready)) != static_cast<ssize_t>(sizeof(ready))) ::_exit(4);
      for (int64_t g = first;; ++g) {
        if (!(*store)->Save(GenerationMission(g)).ok()) ::_exit(3);
        if (::write(fds[1], &g, sizeof(g)) != static_cast<ssize_t>(sizeof(g))) ::_exit(4);
      }
    }
    ::close(fds[1]);
    int64_t g = 0;
    const bool ready = ::read(fds[0], &g, sizeof(g)) == static_cast<ssize_t>(sizeof(g)) && g == -1;
    // Somewhere in the first few saves: sometimes before the first commit, mostly after (the
    // first save after a kill also recovers the log, so it takes longer).
    if (ready) {
      std::this_thread::sleep_for(std::chrono::microseconds(random() % (10 * save_us + 1)));
    }
    if (ready && round % 3 == 0) {
      // A reader in this process while the child writes.
      auto during = LoadFile(path);
      EXPECT_TRUE(during.ok()) << during.status().ToString();
      std::string why;
      if (during.ok()) {
        EXPECT_GE(GenerationOf(*during, &why), generation) << why;
      }
    }
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    int wait_status = 0;
    ASSERT_EQ(::waitpid(child, &wait_status, 0), child);
    ASSERT_TRUE(ready && WIFSIGNALED(wait_status))
        << "the child failed with exit code " << WEXITSTATUS(wait_status);
    int64_t reported = -1;
    while (::read(fds[0], &g, sizeof(g)) == static_cast<ssize_t>(sizeof(g))) reported = g;
    ::close(fds[0]);

    auto loaded = LoadFile(path);
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    std::string why;
    const int64_t found = GenerationOf(*loaded, &why);
    ASSERT_GE(found, 0) << "a mix of generations: " << why;
    // At least what the child reported (or the previous round's), at most one more.
    EXPECT_GE(found, std::max(reported, generation));
    EXPECT_LE(found, reported >= 0 ? reported + 1 : first);
    if (found > generation) ++progressed;
    generation = found;
  }
  // The children did commit: the kills landed between and inside saves, not before them.
  EXPECT_GT(progressed, 0);
  std::cout << "[ kill -9  ] " << kRounds << " rounds (one save " << save_us << " us), "
            << progressed << " with commits, " << generation << " generations\n";
}

}  // namespace
}  // namespace saker::mission

namespace saker::mission {
namespace {

// The frames whose picture saw a map point: inside the frame, in front of the camera, whatever
// the overall sign of the homography.
TEST(FramesSeeingTest, InsideTheFrameAndInFrontOnly) {
  Mission m;
  m.source.width = 100;
  m.source.height = 50;
  const auto frame = [](int64_t index, std::optional<Eigen::Matrix3d> h) {
    FrameRecord f;
    f.index = index;
    f.map_from_frame = h;
    return f;
  };
  Eigen::Matrix3d shifted = Eigen::Matrix3d::Identity();
  shifted(0, 2) = 80;  // frame 1 covers map x 80..180
  Eigen::Matrix3d oblique = Eigen::Matrix3d::Identity();
  oblique(2, 1) = 0.05;  // w = 1 + 0.05 y: the horizon at y = -20
  m.frames = {frame(0, Eigen::Matrix3d::Identity()), frame(1, shifted), frame(2, std::nullopt),
              frame(3, -Eigen::Matrix3d::Identity()), frame(4, oblique)};
  EXPECT_EQ(FramesSeeing(m, {10, 10}), (std::vector<size_t>{0, 3, 4}));
  EXPECT_EQ(FramesSeeing(m, {90, 10}), (std::vector<size_t>{0, 1, 3}));
  EXPECT_EQ(FramesSeeing(m, {90, 10}, 2), (std::vector<size_t>{0, 1}));
  EXPECT_TRUE(FramesSeeing(m, {500, 10}).empty());
  EXPECT_TRUE(FramesSeeing(m, {std::nan(""), 10}).empty());
  // Behind the oblique camera: the point maps back with w < 0 onto its own pixels' range.
  const Eigen::Vector3d behind = oblique * Eigen::Vector3d(10, -40, 1);  // w = -1
  EXPECT_LT(behind.z(), 0);
  const std::vector<size_t> seen = FramesSeeing(m, behind.hnormalized());
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 4u), 0);
}

}  // namespace
}  // namespace saker::mission
