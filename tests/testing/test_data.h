#pragma once

// Access to the real third-party test files (../shared/data in the
// development tree). They are never copied into the repository: tests find
// them through SAKER_TEST_DATA and skip, saying why, when they are absent.

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace saker::testing {

// The data folder: $SAKER_TEST_DATA if set, otherwise the default baked in at
// configure time (../shared/data beside the source tree), or nullopt when
// neither exists.
std::optional<std::filesystem::path> TestDataDir();

// Full path of `relative` inside the data folder, or nullopt when the folder
// or the file is missing.
std::optional<std::filesystem::path> FindTestData(const std::string& relative);

// Whole file as bytes; fails the test (not skip) when the file is unreadable.
std::vector<unsigned char> ReadFileBytes(const std::filesystem::path& path);

// Writes `bytes` as the whole file; fails the test when it cannot.
void WriteFileBytes(const std::filesystem::path& path, const std::vector<unsigned char>& bytes);

// `n` bytes from std::mt19937 seeded with `seed`: the same bytes for a seed everywhere.
std::vector<unsigned char> RandomBytes(size_t n, uint32_t seed);

// A fresh empty directory under the system temp dir, removed (with its
// contents) when the test process exits normally.
std::filesystem::path MakeTempDir(const std::string& prefix);

}  // namespace saker::testing

// Declares `var` as the std::filesystem::path of a data file, or skips the
// current test with a message naming the file and the variable to set.
#define SAKER_REQUIRE_TEST_DATA(var, relative)                                           \
  std::filesystem::path var;                                                             \
  do {                                                                                   \
    auto saker_found_ = ::saker::testing::FindTestData(relative);                        \
    if (!saker_found_) {                                                                 \
      GTEST_SKIP() << "test data file '" << (relative)                                   \
                   << "' not found; set SAKER_TEST_DATA to the shared data folder (see " \
                      "README.md, 'Test data')";                                         \
    }                                                                                    \
    var = *saker_found_;                                                                 \
  } while (false)
