#include "tests/testing/test_data.h"

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

namespace saker::testing {

std::optional<std::filesystem::path> TestDataDir() {
  namespace fs = std::filesystem;
  if (const char* env = std::getenv("SAKER_TEST_DATA"); env != nullptr && *env != '\0') {
    if (fs::is_directory(env)) return fs::path(env);
    return std::nullopt;
  }
  const fs::path fallback = SAKER_DEFAULT_TEST_DATA_DIR;
  if (fs::is_directory(fallback)) return fallback;
  return std::nullopt;
}

std::optional<std::filesystem::path> FindTestData(const std::string& relative) {
  auto dir = TestDataDir();
  if (!dir) return std::nullopt;
  auto path = *dir / relative;
  if (!std::filesystem::is_regular_file(path)) return std::nullopt;
  return path;
}

std::vector<unsigned char> ReadFileBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void WriteFileBytes(const std::filesystem::path& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  EXPECT_TRUE(out.good()) << "cannot write " << path;
}

std::vector<unsigned char> RandomBytes(size_t n, uint32_t seed) {
  std::mt19937 engine(seed);
  std::vector<unsigned char> bytes(n);
  for (unsigned char& b : bytes) b = static_cast<unsigned char>(engine());
  return bytes;
}

namespace {

// Directories made by MakeTempDir, removed when the test process exits.
class TempDirRegistry {
 public:
  ~TempDirRegistry() {
    for (const auto& dir : dirs_) {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  }
  void Add(const std::filesystem::path& dir) { dirs_.push_back(dir); }

 private:
  std::vector<std::filesystem::path> dirs_;
};

TempDirRegistry& Registry() {
  static TempDirRegistry registry;
  return registry;
}

}  // namespace

std::filesystem::path MakeTempDir(const std::string& prefix) {
  namespace fs = std::filesystem;
  std::random_device rd;
  for (int attempt = 0; attempt < 100; ++attempt) {
    auto dir = fs::temp_directory_path() / (prefix + "-" + std::to_string(rd()));
    std::error_code ec;
    if (fs::create_directory(dir, ec)) {
      Registry().Add(dir);
      return dir;
    }
  }
  ADD_FAILURE() << "cannot create a temp directory for " << prefix;
  return fs::temp_directory_path();
}

}  // namespace saker::testing
