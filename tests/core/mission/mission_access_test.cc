// Who may open a mission file, and where: one writer at a time (a lock that names the process
// that writes, that readers ignore and that a killed writer does not leave behind), missions on
// storage the user cannot write, one-off reads that leave nothing beside the file, and paths
// longer than SQLite opens, refused naming the limit.

#include "core/mission/mission_store.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>

namespace saker::mission {
namespace {

namespace fs = std::filesystem;
using testing_support::MakeFullMission;

class MissionAccessTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = saker::testing::MakeTempDir("saker-mission-access"); }
  void TearDown() override {
    std::error_code ignored;
    fs::permissions(dir_ / "ro", fs::perms::owner_all, ignored);
    fs::remove_all(dir_, ignored);
  }
  fs::path File(const std::string& name) const { return dir_ / name; }

  // A closed mission at `path` holding MakeFullMission() (its log folded in and removed).
  static void WriteMission(const fs::path& path) {
    auto store = MissionStore::Create(path.string());
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    const Status saved = (*store)->Save(MakeFullMission());
    ASSERT_TRUE(saved.ok()) << saved.ToString();
  }
  static bool HasSideFiles(const fs::path& path) {
    return fs::exists(path.string() + "-wal") || fs::exists(path.string() + "-shm") ||
           fs::exists(path.string() + ".lock");
  }

  fs::path dir_;
};

// ---------------------------------------------------------------------------------------------
// One writer.

TEST_F(MissionAccessTest, ASecondWriterIsRefusedNamingTheProcessWhileReadersGoOn) {
  const fs::path path = File("one.saker");
  auto first = MissionStore::Create(path.string());
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  ASSERT_TRUE((*first)->Save(MakeFullMission()).ok());
  const std::string in_use = "in use by process " + std::to_string(::getpid());

  // `process --replace` and `process --resume` while the first job writes.
  const auto replacing = MissionStore::Create(path.string(), /*replace=*/true);
  ASSERT_FALSE(replacing.ok()) << "a second job replaced the mission the first one writes";
  EXPECT_EQ(replacing.status().code(), StatusCode::kIoError);
  EXPECT_NE(replacing.status().message().find(in_use), std::string::npos)
      << replacing.status().message();
  EXPECT_NE(replacing.status().message().find(path.string()), std::string::npos);
  const auto resuming = MissionStore::Open(path.string(), OpenMode::kReadWrite);
  ASSERT_FALSE(resuming.ok());
  EXPECT_NE(resuming.status().message().find(in_use), std::string::npos);
  EXPECT_FALSE(MissionStore::FoldLog(path.string()).ok());

  // Viewers read what the writer committed, in the file the writer writes.
  for (OpenMode mode : {OpenMode::kReadOnly, OpenMode::kSnapshot}) {
    auto reader = MissionStore::Open(path.string(), mode);
    ASSERT_TRUE(reader.ok()) << reader.status().ToString();
    StatusOr<Mission> loaded = (*reader)->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(loaded->frames.size(), MakeFullMission().frames.size());
  }
  ASSERT_TRUE((*first)->Save(Mission{}, kSaveFrames).ok());  // still its file

  // Once the writer is done the next one goes ahead, and no lock file is left.
  first->reset();
  EXPECT_FALSE(fs::exists(path.string() + ".lock"));
  auto next = MissionStore::Create(path.string(), /*replace=*/true);
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  next->reset();
  EXPECT_FALSE(fs::exists(path.string() + ".lock"));
}

TEST_F(MissionAccessTest, AWriterKilledWithItsLockBlocksNobodyAfterwards) {
  const fs::path path = File("killed.saker");
  WriteMission(path);
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(ready[0]);
    auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
    const char byte = store.ok() ? 'y' : 'n';
    if (::write(ready[1], &byte, 1) != 1) ::_exit(1);
    ::pause();  // killed here, holding the lock
    ::_exit(0);
  }
  ::close(ready[1]);
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  ::close(ready[0]);
  ASSERT_EQ(byte, 'y') << "the child could not open the mission for writing";

  const auto refused = MissionStore::Open(path.string(), OpenMode::kReadWrite);
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_FALSE(refused.ok()) << "opened for writing while another process writes";
  EXPECT_NE(refused.status().message().find("in use by process " + std::to_string(child)),
            std::string::npos)
      << refused.status().message();
  ASSERT_TRUE(fs::exists(path.string() + ".lock"));  // left by the kill, naming a dead process
  auto store = MissionStore::Create(path.string(), /*replace=*/true);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
}

// ---------------------------------------------------------------------------------------------
// Reading without writing.

TEST_F(MissionAccessTest, ASnapshotReadLeavesNothingBesideTheMission) {
  const fs::path path = File("snapshot.saker");
  WriteMission(path);
  ASSERT_FALSE(HasSideFiles(path));
  {
    auto store = MissionStore::Open(path.string(), OpenMode::kSnapshot);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    StatusOr<Mission> loaded = (*store)->Load();
    ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
    EXPECT_EQ(loaded->tracks.size(), MakeFullMission().tracks.size());
    EXPECT_TRUE((*store)->CountTiles().ok());
    EXPECT_FALSE(HasSideFiles(path));
    EXPECT_EQ((*store)->Save(Mission{}).code(), StatusCode::kInvalidArgument);
  }
  EXPECT_FALSE(HasSideFiles(path));
}

// Opens `path` read-only as a user who may read but not write it (the process's own user
// unless root, else "nobody" in a child), and returns what went wrong ("" when the mission read
// and was reported read-only).
std::string ReadAsReader(const fs::path& path) {
  const auto read = [&]() -> std::string {
    if (MissionStore::IsWritable(path.string())) return "reported writable";
    for (OpenMode mode : {OpenMode::kReadOnly, OpenMode::kSnapshot}) {
      auto store = MissionStore::Open(path.string(), mode);
      if (!store.ok()) return store.status().ToString();
      StatusOr<Mission> loaded = (*store)->Load();
      if (!loaded.ok()) return loaded.status().ToString();
      if (loaded->frames.size() != MakeFullMission().frames.size()) return "wrong frames";
    }
    if (MissionStore::Open(path.string(), OpenMode::kReadWrite).ok()) return "opened to write";
    return "";
  };
  if (::geteuid() != 0) return read();
  int pipe_fds[2];
  if (::pipe(pipe_fds) != 0) return "no pipe";
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(pipe_fds[0]);
    const std::string problem = (::setgid(65534) == 0 && ::setuid(65534) == 0)
                                    ? read()
                                    : std::string("cannot become nobody");
    const ssize_t written = ::write(pipe_fds[1], problem.data(), problem.size());
    ::_exit(written == static_cast<ssize_t>(problem.size()) ? 0 : 1);
  }
  ::close(pipe_fds[1]);
  std::string problem;
  char buffer[512];
  ssize_t n;
  while ((n = ::read(pipe_fds[0], buffer, sizeof(buffer))) > 0) problem.append(buffer, n);
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  return problem;
}

TEST_F(MissionAccessTest, AMissionTheUserCannotWriteOpensReadOnly) {
  const fs::path folder = File("ro");
  fs::create_directories(folder);
  const fs::path path = folder / "flight.saker";
  WriteMission(path);
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                            fs::perms::others_read | fs::perms::others_exec);
  fs::permissions(folder, fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                              fs::perms::group_exec | fs::perms::others_read |
                              fs::perms::others_exec);
  fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  EXPECT_EQ(ReadAsReader(path), "");
  EXPECT_FALSE(HasSideFiles(path));
}

// ---------------------------------------------------------------------------------------------
// Long paths.

TEST_F(MissionAccessTest, ANameTooLongIsRefusedNamingTheLimitAndOneAtTheLimitWorks) {
  const fs::path too_long = File(std::string(240, 'n') + ".saker");
  const auto refused = MissionStore::Create(too_long.string());
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument) << refused.status().message();
  std::smatch limit;
  const std::string message = refused.status().message();
  ASSERT_TRUE(std::regex_search(message, limit, std::regex("at most ([0-9]+) bytes"))) << message;
  EXPECT_FALSE(fs::exists(too_long));
  // One byte under the limit named (the temporary's name carries a counter, which may gain a
  // digit between the two calls).
  const size_t longest = std::stoul(limit[1].str()) - 1;
  ASSERT_GT(longest, 200u);
  const fs::path path = File(std::string(longest - 6, 'n') + ".saker");
  WriteMission(path);
  auto store = MissionStore::Open(path.string(), OpenMode::kReadWrite);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  EXPECT_TRUE((*store)->Load().ok());
}

TEST_F(MissionAccessTest, APathTooLongIsRefusedNamingTheLimit) {
  const fs::path folder =
      dir_ / std::string(200, 'a') / std::string(200, 'b') / std::string(100, 'c');
  fs::create_directories(folder);
  const fs::path path = folder / "flight.saker";
  const auto created = MissionStore::Create(path.string());
  ASSERT_FALSE(created.ok());
  EXPECT_EQ(created.status().code(), StatusCode::kInvalidArgument) << created.status().message();
  EXPECT_NE(created.status().message().find("SQLite opens a mission's path of at most"),
            std::string::npos)
      << created.status().message();
  // A mission moved there opens no better; the message says why.
  WriteMission(File("short.saker"));
  fs::rename(File("short.saker"), path);
  const auto opened = MissionStore::Open(path.string());
  ASSERT_FALSE(opened.ok());
  EXPECT_EQ(opened.status().code(), StatusCode::kInvalidArgument) << opened.status().message();
  EXPECT_NE(opened.status().message().find("bytes"), std::string::npos);
}

}  // namespace
}  // namespace saker::mission
