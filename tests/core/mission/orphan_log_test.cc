// A write-ahead log left without its database (a writer killed with uncommitted checkpoints, then
// the .saker file deleted by hand) must never be replayed onto a new mission created at that path.
// Found by saker-bench-crash: a new mission reopened with another run's state.

#include "core/mission/mission_store.h"
#include "core/pipeline/export_mission.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace saker::mission {
namespace {

namespace fs = std::filesystem;
using testing_support::MakeFullMission;
using testing_support::MissionsEqual;

std::string IntegrityCheck(const std::string& path) {
  sqlite3* db = nullptr;
  std::string answer = "cannot open";
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* statement = nullptr;
    if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &statement, nullptr) == SQLITE_OK &&
        sqlite3_step(statement) == SQLITE_ROW) {
      answer = reinterpret_cast<const char*>(sqlite3_column_text(statement, 0));
    }
    sqlite3_finalize(statement);
  }
  sqlite3_close(db);
  return answer;
}

// A writer creates `path`, saves `mission` and is killed: its commits stay in the log.
void KilledWriter(const std::string& path, const Mission& mission) {
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto store = MissionStore::Create(path, /*replace=*/true);
    if (!store.ok() || !(*store)->Save(mission).ok()) ::_exit(2);
    ::kill(::getpid(), SIGKILL);
    ::_exit(3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the writer failed: exit code " << WEXITSTATUS(status);
  ASSERT_TRUE(fs::exists(path + "-wal"));
  ASSERT_GT(fs::file_size(path + "-wal"), 0u);
}

TEST(OrphanLogTest, ANewMissionIgnoresTheLogOfADeletedOne) {
  const fs::path dir = saker::testing::MakeTempDir("saker-orphan-log");
  const std::string path = (dir / "flight.saker").string();
  ASSERT_NO_FATAL_FAILURE(KilledWriter(path, MakeFullMission()));
  {
    auto killed = MissionStore::Open(path);
    ASSERT_TRUE(killed.ok()) << killed.status().ToString();
    auto mission = (*killed)->Load();
    ASSERT_TRUE(mission.ok());
    ASSERT_FALSE(mission->frames.empty());  // the log holds the committed save
  }
  // Someone deletes the mission file alone; its log stays behind.
  fs::remove(path);
  ASSERT_TRUE(fs::exists(path + "-wal"));

  auto created = MissionStore::Create(path);
  ASSERT_TRUE(created.ok()) << created.status().ToString();
  created->reset();
  auto reopened = MissionStore::Open(path);
  ASSERT_TRUE(reopened.ok()) << reopened.status().ToString();
  auto mission = (*reopened)->Load();
  ASSERT_TRUE(mission.ok()) << mission.status().ToString();
  std::string why;
  EXPECT_TRUE(MissionsEqual(*mission, Mission{}, &why)) << "the new mission is not empty: " << why;
  reopened->reset();
  EXPECT_EQ(IntegrityCheck(path), "ok");
  fs::remove_all(dir);
}

// Save As over a mission whose writer was killed (its log still holds commits), and over the
// orphaned log of a deleted one: the copy is the mission copied, nothing of the old log.
TEST(OrphanLogTest, SaveAsIgnoresTheLogOfTheMissionItReplaces) {
  const fs::path dir = saker::testing::MakeTempDir("saker-orphan-copy");
  const std::string source = (dir / "source.saker").string();
  Mission small;
  small.saker_version = "copied";
  {
    auto store = MissionStore::Create(source);
    ASSERT_TRUE(store.ok());
    ASSERT_TRUE((*store)->Save(small).ok());
  }
  const std::string target = (dir / "target.saker").string();
  for (const bool delete_first : {false, true}) {
    SCOPED_TRACE(delete_first ? "orphaned log" : "killed writer's mission");
    ASSERT_NO_FATAL_FAILURE(KilledWriter(target, MakeFullMission()));
    if (delete_first) fs::remove(target);
    ASSERT_TRUE(pipeline::CopyMission(source, target, /*replace=*/true).ok());
    auto copy = MissionStore::Open(target);
    ASSERT_TRUE(copy.ok()) << copy.status().ToString();
    auto mission = (*copy)->Load();
    ASSERT_TRUE(mission.ok()) << mission.status().ToString();
    std::string why;
    EXPECT_TRUE(MissionsEqual(*mission, small, &why)) << why;
    copy->reset();
    EXPECT_EQ(IntegrityCheck(target), "ok");
  }
  fs::remove_all(dir);
}

// Temporary files of killed jobs beside a mission are removed by the next Create or Save As at
// that path; those of a live process (it may be building one now) are kept.
TEST(OrphanLogTest, TemporariesOfDeadJobsAreRemoved) {
  const fs::path dir = saker::testing::MakeTempDir("saker-stale-temp");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) ::_exit(0);
  ASSERT_EQ(::waitpid(child, nullptr, 0), child);
  const std::string dead = std::to_string(child), live = std::to_string(::getpid());
  const std::vector<std::string> stale = {
      ".m.saker.new-" + dead + "-0", ".m.saker.new-" + dead + "-0-wal", "m.saker.part-" + dead,
      "m.saker.part-" + dead + "-shm", ".m.saker.part-" + dead + ".new-" + dead + "-3",
      // A FileReplacement's (Create's, CopyMission's) and Create's within CopyMission's.
      ".m.saker.part-" + dead + "-1.saker", ".m.saker.part-" + dead + "-1.saker-wal",
      "..m.saker.part-" + dead + "-1.saker.part-" + dead + "-2.saker"};
  const std::vector<std::string> kept = {".m.saker.new-" + live + "-7", "m.saker.part-" + live,
                                         ".m.saker.part-" + live + "-4.saker",
                                         "other.saker.part-" + dead, "m.saker.part-notes"};
  for (const auto& names : {stale, kept}) {
    for (const std::string& name : names) {
      std::FILE* file = std::fopen((dir / name).c_str(), "w");
      ASSERT_NE(file, nullptr) << name;
      std::fclose(file);
    }
  }
  ASSERT_TRUE(MissionStore::Create((dir / "m.saker").string()).ok());
  for (const std::string& name : stale) EXPECT_FALSE(fs::exists(dir / name)) << name;
  for (const std::string& name : kept) EXPECT_TRUE(fs::exists(dir / name)) << name;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace saker::mission
