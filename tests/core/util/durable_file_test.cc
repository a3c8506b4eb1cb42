#include "core/util/durable_file.h"

#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
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

}  // namespace
}  // namespace saker
