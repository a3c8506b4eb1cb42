#include "core/util/durable_file.h"

#include "tests/testing/test_data.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace saker {
namespace {

namespace fs = std::filesystem;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The names in `dir`, sorted.
std::vector<std::string> Names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

TEST(DurableFileTest, ContentsReplaceTheFileAndLeaveNoTemporary) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "notes.txt";
  ASSERT_TRUE(ReplaceFileContents(path.string(), "first\n").ok());
  EXPECT_EQ(ReadText(path), "first\n");
  ASSERT_TRUE(ReplaceFileContents(path.string(), "second").ok());
  EXPECT_EQ(ReadText(path), "second");
  EXPECT_EQ(Names(dir), std::vector<std::string>{"notes.txt"});
}

TEST(DurableFileTest, StreamWriterWritesTheWholeFile) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "numbers.csv";
  ASSERT_TRUE(ReplaceFileFromStream(path.string(), [](std::ostream& out) {
                for (int i = 0; i < 1000; ++i) out << i << "\n";
                return Status::Ok();
              }).ok());
  std::ifstream in(path);
  int value = -1, count = 0;
  while (in >> value) EXPECT_EQ(value, count++);
  EXPECT_EQ(count, 1000);
  EXPECT_EQ(Names(dir), std::vector<std::string>{"numbers.csv"});
}

TEST(DurableFileTest, TemporaryIsHiddenBesideTheTargetWithItsExtension) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "map.png";
  FileReplacement a(path.string());
  FileReplacement b(path.string());
  const fs::path temporary(a.temporary());
  EXPECT_EQ(temporary.parent_path(), dir);
  EXPECT_EQ(temporary.filename().string().rfind(".map.png.part-" + std::to_string(::getpid()), 0),
            0u)
      << temporary;
  EXPECT_EQ(temporary.extension(), ".png");
  EXPECT_NE(a.temporary(), b.temporary());  // two replacements of one file never collide
  EXPECT_EQ(a.target(), path.string());
  // A bare name gets a temporary in the current folder.
  FileReplacement bare("out.json");
  EXPECT_EQ(fs::path(bare.temporary()).parent_path(), fs::path("."));
}

TEST(DurableFileTest, PathWriterServesWritersThatNeedAPath) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "picture.tif";
  std::string seen;
  ASSERT_TRUE(ReplaceFile(path.string(), [&](const std::string& temporary) {
                seen = temporary;
                WriteText(temporary, "pixels");
                return Status::Ok();
              }).ok());
  EXPECT_NE(seen, path.string());
  EXPECT_FALSE(fs::exists(seen));
  EXPECT_EQ(ReadText(path), "pixels");
}

TEST(DurableFileTest, AFailedWriterKeepsTheOldFileAndRemovesTheTemporary) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "data.json";
  WriteText(path, "old");
  const Status status = ReplaceFile(path.string(), [&](const std::string& temporary) {
    WriteText(temporary, "half of the n");
    WriteText(temporary + "-wal", "log");  // not a declared side file: stays
    return IoError(path.string() + ": disk gone");
  });
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message(), path.string() + ": disk gone");
  EXPECT_EQ(ReadText(path), "old");
  const std::vector<std::string> names = Names(dir);
  ASSERT_EQ(names.size(), 2u);
  EXPECT_EQ(names[1], "data.json");
  EXPECT_NE(names[0].find("-wal"), std::string::npos);
}

TEST(DurableFileTest, SideFilesAreRemovedAfterFailureAndCommit) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "m.saker";
  const ReplaceOptions options{.side_suffixes = {"-wal", "-shm"}};
  auto write = [](const std::string& temporary) {
    WriteText(temporary, "db");
    WriteText(temporary + "-wal", "log");
    WriteText(temporary + "-shm", "index");
    return Status::Ok();
  };
  EXPECT_FALSE(ReplaceFile(
                   path.string(),
                   [&](const std::string& temporary) {
                     (void)write(temporary);
                     return IoError("no");
                   },
                   options)
                   .ok());
  EXPECT_TRUE(Names(dir).empty());
  ASSERT_TRUE(ReplaceFile(path.string(), write, options).ok());
  EXPECT_EQ(Names(dir), std::vector<std::string>{"m.saker"});
}

TEST(DurableFileTest, AnExceptionInTheWriterRemovesTheTemporary) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "a.txt";
  EXPECT_THROW((void)ReplaceFile(path.string(),
                                 [](const std::string& temporary) -> Status {
                                   WriteText(temporary, "partial");
                                   throw std::runtime_error("library failure");
                                 }),
               std::runtime_error);
  EXPECT_TRUE(Names(dir).empty());
}

TEST(DurableFileTest, AnUnwritableFolderIsAnErrorNamingTheFile) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  // A folder that is a file (unwritable even for root) and a missing folder.
  WriteText(dir / "file", "x");
  for (const fs::path& path : {dir / "file" / "out.json", dir / "missing" / "out.json"}) {
    const Status status = ReplaceFileContents(path.string(), "{}");
    EXPECT_EQ(status.code(), StatusCode::kIoError) << path;
    EXPECT_EQ(status.message().rfind(path.string() + ": cannot create the file", 0), 0u)
        << status.message();
  }
  EXPECT_EQ(Names(dir), std::vector<std::string>{"file"});
  if (::geteuid() != 0) {
    const fs::path locked = dir / "locked";
    fs::create_directory(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    const Status status = ReplaceFileContents((locked / "out.json").string(), "{}");
    fs::permissions(locked, fs::perms::owner_all);
    EXPECT_EQ(status.code(), StatusCode::kIoError);
    EXPECT_NE(status.message().find((locked / "out.json").string()), std::string::npos);
    EXPECT_TRUE(fs::is_empty(locked));
  }
}

TEST(DurableFileTest, AFailedRenameNamesTheTargetAndRemovesTheTemporary) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  // A folder with content at the target: a file cannot be renamed over it.
  const fs::path path = dir / "taken";
  fs::create_directory(path);
  WriteText(path / "inside", "x");
  const Status status = ReplaceFileContents(path.string(), "new");
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message().rfind(path.string() + ": cannot move ", 0), 0u) << status.message();
  EXPECT_EQ(Names(dir), std::vector<std::string>{"taken"});
  EXPECT_EQ(ReadText(path / "inside"), "x");
}

TEST(DurableFileTest, AWriterThatMakesNoFileFailsTheCommit) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "nothing.txt";
  const Status status = ReplaceFile(path.string(), [](const std::string&) { return Status::Ok(); });
  EXPECT_EQ(status.code(), StatusCode::kIoError);
  EXPECT_EQ(status.message().rfind(path.string() + ": ", 0), 0u) << status.message();
  EXPECT_TRUE(Names(dir).empty());
}

TEST(DurableFileTest, WithoutOverwriteAFileThatAppearedIsKept) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "entry";
  FileReplacement replacement(path.string(), {.overwrite = false});
  WriteText(replacement.temporary(), "mine");
  WriteText(path, "theirs");  // another process was quicker
  const Status status = replacement.Commit();
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), path.string() + ": a file appeared there meanwhile");
  EXPECT_EQ(ReadText(path), "theirs");
  EXPECT_EQ(Names(dir), std::vector<std::string>{"entry"});
  // With the place free it goes in.
  fs::remove(path);
  FileReplacement second(path.string(), {.overwrite = false});
  WriteText(second.temporary(), "mine");
  ASSERT_TRUE(second.Commit().ok());
  EXPECT_EQ(ReadText(path), "mine");
}

TEST(DurableFileTest, AFolderCanBeBuiltAndMovedIntoPlace) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path path = dir / "cache-entry";
  FileReplacement replacement(path.string(), {.overwrite = false});
  const fs::path temporary = replacement.temporary();
  fs::create_directories(temporary / "sub");
  WriteText(temporary / "video.ts", "frames");
  WriteText(temporary / "sub" / "truth.json", "{}");
  ASSERT_TRUE(replacement.Commit().ok());
  EXPECT_EQ(ReadText(path / "video.ts"), "frames");
  EXPECT_EQ(ReadText(path / "sub" / "truth.json"), "{}");
  EXPECT_EQ(Names(dir), std::vector<std::string>{"cache-entry"});
  // A discarded folder goes with its content.
  {
    FileReplacement discarded((dir / "other").string());
    fs::create_directories(fs::path(discarded.temporary()) / "deep");
    WriteText(fs::path(discarded.temporary()) / "deep" / "f", "x");
  }
  EXPECT_EQ(Names(dir), std::vector<std::string>{"cache-entry"});
}

TEST(DurableFileTest, SyncPathReportsAMissingFile) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  EXPECT_TRUE(SyncPath(dir.string()).ok());
  WriteText(dir / "f", "x");
  EXPECT_TRUE(SyncPath((dir / "f").string()).ok());
  const Status missing = SyncPath((dir / "g").string());
  EXPECT_EQ(missing.code(), StatusCode::kIoError);
  EXPECT_NE(missing.message().find((dir / "g").string()), std::string::npos);
}

// Item 6 of issue 29: `--csv /dev/full` (as root) replaced the device node with a regular file and
// reported success, and a FIFO or /dev/stdout was replaced likewise. A target that is no file is
// written into, never renamed over.
TEST(DurableFileTest, AFifoIsWrittenIntoNotReplaced) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // The reader, as `cat pipe` would be, opened first so the writer does not wait for one.
  const auto written_through = [&](const fs::path& target, const std::string& text) {
    const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
    EXPECT_GE(reader, 0);
    const Status status = ReplaceFileContents(target.string(), text);
    EXPECT_TRUE(status.ok()) << status.ToString();
    std::string got(256, '\0');
    const ssize_t n = ::read(reader, got.data(), got.size());
    ::close(reader);
    got.resize(static_cast<size_t>(std::max<ssize_t>(n, 0)));
    return got;
  };
  EXPECT_EQ(written_through(fifo, "through the pipe\n"), "through the pipe\n");
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(Names(dir), std::vector<std::string>{"pipe"});
  // Through a link too: the link and the FIFO stay.
  fs::create_symlink(fifo, dir / "link");
  EXPECT_EQ(written_through(dir / "link", "again"), "again");
  EXPECT_TRUE(fs::is_symlink(dir / "link"));
  EXPECT_TRUE(fs::is_fifo(fifo));
}

TEST(DurableFileTest, AnOpenDescriptorGetsTheBytes) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  // A writer that needs a path works too: the content is built in a temporary, then sent.
  const Status status =
      ReplaceFile("/dev/fd/" + std::to_string(fds[1]), [](const std::string& temporary) {
        std::ofstream(temporary, std::ios::binary) << "to the descriptor";
        return Status::Ok();
      });
  ASSERT_TRUE(status.ok()) << status.ToString();
  ::close(fds[1]);
  std::string text(64, '\0');
  const ssize_t n = ::read(fds[0], text.data(), text.size());
  ::close(fds[0]);
  ASSERT_GT(n, 0);
  text.resize(static_cast<size_t>(n));
  EXPECT_EQ(text, "to the descriptor");
}

TEST(DurableFileTest, AFullDeviceIsAnErrorAndStaysADevice) {
  if (::geteuid() != 0) GTEST_SKIP() << "only root can make a device node (CI runs as root)";
  // A private /dev/full (character device 1, 7): the test never risks the machine's own.
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const fs::path full = dir / "full";
  if (::mknod(full.c_str(), S_IFCHR | 0666, ::makedev(1, 7)) != 0) {
    GTEST_SKIP() << "cannot make a device node here: " << std::strerror(errno);
  }
  const Status status = ReplaceFileContents(full.string(), "nowhere to go");
  EXPECT_EQ(status.code(), StatusCode::kIoError) << status.ToString();
  EXPECT_EQ(status.message().rfind(full.string() + ": ", 0), 0u) << status.message();
  EXPECT_NE(status.message().find(std::strerror(ENOSPC)), std::string::npos) << status.message();
  EXPECT_TRUE(fs::is_character_file(full));
  EXPECT_EQ(Names(dir), std::vector<std::string>{"full"});
}

TEST(DurableFileTest, ALinkToAFileIsKeptAndTheFileReplaced) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  WriteText(dir / "real.csv", "old");
  fs::create_symlink("real.csv", dir / "latest.csv");
  ASSERT_TRUE(ReplaceFileContents((dir / "latest.csv").string(), "new").ok());
  EXPECT_TRUE(fs::is_symlink(dir / "latest.csv"));
  EXPECT_EQ(ReadText(dir / "real.csv"), "new");
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"latest.csv", "real.csv"}));
}

// Item 5 of issue 29: the check every job makes before writing over what it reads.
TEST(DurableFileTest, AnInputIsRecognisedByDeviceAndInodeWhateverItsName) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  WriteText(dir / "mission.saker", "m");
  fs::create_hard_link(dir / "mission.saker", dir / "hard.saker");
  fs::create_symlink(dir / "mission.saker", dir / "soft.saker");
  const std::vector<std::string> inputs = {(dir / "video.ts").string(),  // absent: skipped
                                           (dir / "mission.saker").string()};
  for (const fs::path& output : {dir / "mission.saker", dir / "hard.saker", dir / "soft.saker",
                                 dir / "." / "mission.saker"}) {
    const Status status = CheckNotAnInput(output.string(), inputs);
    EXPECT_EQ(status.code(), StatusCode::kInvalidArgument) << output;
    EXPECT_EQ(status.message().rfind(output.string() + ": is ", 0), 0u) << status.message();
  }
  EXPECT_TRUE(CheckNotAnInput((dir / "new.csv").string(), inputs).ok());
  WriteText(dir / "other.csv", "o");
  EXPECT_TRUE(CheckNotAnInput((dir / "other.csv").string(), inputs).ok());
}

// A job killed outright (SIGKILL) cannot remove its temporary: the next replacement of the same
// file does, and leaves a live process's alone.
TEST(DurableFileTest, ADeadProcesssTemporaryIsRemovedByTheNextReplacement) {
  const fs::path dir = testing::MakeTempDir("saker-durable");
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  ASSERT_GT(child, 0);
  ::waitpid(child, nullptr, 0);
  const std::string dead = ".mosaic.tif.part-" + std::to_string(child) + "-0.tif";
  const std::string live = ".mosaic.tif.part-" + std::to_string(::getppid()) + "-0.tif";
  WriteText(dir / dead, "left by a killed export");
  WriteText(dir / live, "being written");
  ASSERT_TRUE(ReplaceFileContents((dir / "mosaic.tif").string(), "tiff").ok());
  EXPECT_EQ(Names(dir), (std::vector<std::string>{live, "mosaic.tif"}));
}

}  // namespace
}  // namespace saker
