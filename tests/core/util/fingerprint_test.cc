#include "core/util/fingerprint.h"

#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>
#include <regex>
#include <string>
#include <vector>

namespace saker {
namespace {

namespace fs = std::filesystem;

using testing::RandomBytes;
using testing::WriteFileBytes;

class FingerprintTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = saker::testing::MakeTempDir("saker-fingerprint"); }
  fs::path File(const std::string& name) const { return dir_ / name; }

  fs::path dir_;
};

// The published FNV-1a 64 test vectors, and hashing in pieces.
TEST(Fnv1aTest, MatchesTheReferenceVectors) {
  EXPECT_EQ(Fnv1a("", 0), kFnv1aOffset);
  EXPECT_EQ(Fnv1a("a", 1), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a("foobar", 6), 0x85944171f73967e8ull);
  EXPECT_EQ(Fnv1a("bar", 3, Fnv1a("foo", 3)), Fnv1a("foobar", 6));
}

TEST_F(FingerprintTest, FingerprintRecognisesTheSameContent) {
  const size_t size = 3 * 1024 * 1024 + 512 * 1024;  // 3.5 MiB: the sampled MiBs leave gaps
  const std::vector<uint8_t> bytes = RandomBytes(size, 5);
  WriteFileBytes(File("a.ts"), bytes);
  WriteFileBytes(File("b.ts"), bytes);
  auto a = FingerprintFile(File("a.ts").string());
  auto b = FingerprintFile(File("b.ts").string());
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  EXPECT_EQ(*a, *b);
  EXPECT_TRUE(std::regex_match(*a, std::regex("v1:" + std::to_string(size) + ":[0-9a-f]{16}")))
      << *a;

  // One byte in the first, middle or last MiB changes it.
  for (size_t offset : {static_cast<size_t>(1000), size / 2, size - 1}) {
    std::vector<uint8_t> changed = bytes;
    changed[offset] ^= 0x01;
    WriteFileBytes(File("c.ts"), changed);
    auto c = FingerprintFile(File("c.ts").string());
    ASSERT_TRUE(c.ok());
    EXPECT_NE(*c, *a) << "offset " << offset;
  }
  // So does the size.
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  WriteFileBytes(File("d.ts"), longer);
  EXPECT_NE(FingerprintFile(File("d.ts").string()).value(), *a);
  // Bytes outside the sampled MiBs are not read: that is the point of a fingerprint.
  std::vector<uint8_t> unsampled = bytes;
  unsampled[1024 * 1024 + 100] ^= 0xff;
  WriteFileBytes(File("e.ts"), unsampled);
  EXPECT_EQ(FingerprintFile(File("e.ts").string()).value(), *a);
}

TEST_F(FingerprintTest, FingerprintOfSmallAndMissingFiles) {
  WriteFileBytes(File("small.ts"), {1, 2, 3});
  WriteFileBytes(File("small2.ts"), {1, 2, 4});
  WriteFileBytes(File("empty.ts"), {});
  auto small = FingerprintFile(File("small.ts").string());
  auto small2 = FingerprintFile(File("small2.ts").string());
  auto empty = FingerprintFile(File("empty.ts").string());
  ASSERT_TRUE(small.ok() && small2.ok() && empty.ok());
  EXPECT_NE(*small, *small2);
  EXPECT_EQ(small->rfind("v1:3:", 0), 0u) << *small;
  EXPECT_EQ(empty->rfind("v1:0:", 0), 0u) << *empty;

  const std::string missing = File("missing.ts").string();
  auto status = FingerprintFile(missing);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.status().code(), StatusCode::kNotFound);
  EXPECT_NE(status.status().message().find(missing), std::string::npos);
  EXPECT_EQ(FingerprintFile(dir_.string()).status().code(), StatusCode::kIoError);
}

// Issue 29 item 11: a FIFO where a video was looked for (the mission's folder, when the video
// moved) blocked opening it for ever. It is refused at once, naming it.
TEST_F(FingerprintTest, AFifoIsRefusedNotWaitedOn) {
  const fs::path fifo = File("flight.ts");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto fingerprint = std::async(std::launch::async, [&] { return FingerprintFile(fifo.string()); });
  if (fingerprint.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    ADD_FAILURE() << "still waiting on the FIFO after 10 s";
    std::ofstream(fifo).close();  // a writer that closes at once unblocks it
  }
  const StatusOr<std::string> result = fingerprint.get();
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.status().message(), fifo.string() + ": not a regular file");
}

}  // namespace
}  // namespace saker
