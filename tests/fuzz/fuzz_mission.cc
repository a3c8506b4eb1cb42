// libFuzzer harness for the mission loader (core/mission). A `.saker` file is written into a
// private temporary directory (on /dev/shm when available, to spare the disk) and opened with
// MissionStore::Open, read-only and then read-write (which may upgrade a version 1 file in
// place), loading everything the store offers: the header, frames, key frames, links, tracks and
// their points, and the tiles of the pyramid the header declares, decoded as the GUI and the
// exports decode them (tiles::DecodeTile, whose PNG size is checked before decoding), and an
// unfinished job's checkpoint with its key frame images (pipeline::ReadCheckpoint).
//
// The input is used two ways:
//   - an input that starts with the SQLite header ("SQLite format 3\0") is the file itself:
//     byte-level damage, mostly caught by the header checks and by SQLite;
//   - any other input is an edit script applied with SQLite to a complete mission (the mission
//     tests' fixture, built once): each edit sets one cell of one table (chosen by index among the
//     file's tables and columns) to NULL, an integer, a real, a text or a blob from the input,
//     or deletes or duplicates a row. These are the files a bad tool or a partial write could
//     leave: valid SQLite whose values are of the wrong type, size or range, which is what
//     Load's own checks are for.
//
// Every error must be a Status naming the file; a Load of a file that opened must never crash,
// hang or allocate without bound, whatever the tables hold.

#include "core/mission/mission.h"
#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "core/tiles/pyramid.h"
#include "tests/core/mission/mission_fixtures.h"
#include "tests/testing/png_bomb.h"

#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <system_error>
#include <vector>

namespace {

using namespace saker;
namespace fs = std::filesystem;

[[noreturn]] void Fail(const char* what) {
  std::fprintf(stderr, "fuzz_mission: broken promise: %s\n", what);
  std::abort();
}

const fs::path& WorkDir() {
  static const fs::path dir = [] {
    std::error_code error;
    fs::path base =
        fs::is_directory("/dev/shm", error) ? fs::path("/dev/shm") : fs::temp_directory_path();
    fs::path made = base / ("saker-fuzz-mission-" + std::to_string(::getpid()));
    fs::create_directories(made, error);
    if (error) Fail("cannot create the temporary directory");
    std::atexit([] {
      std::error_code ignored;
      fs::remove_all(WorkDir(), ignored);
    });
    return made;
  }();
  return dir;
}

void RemoveFiles(const fs::path& path) {
  std::error_code ignored;
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) {
    fs::remove(path.string() + suffix, ignored);
  }
}

void ExpectNamesFile(const Status& status, const std::string& path) {
  if (status.ok()) return;
  if (status.message().find(path) == std::string::npos) {
    std::fprintf(stderr, "error without the file name: %s\n", status.ToString().c_str());
    Fail("an error does not name the file");
  }
}

void LoadEverything(const mission::MissionStore& store, const std::string& path) {
  auto loaded = store.Load();
  ExpectNamesFile(loaded.status(), path);
  auto count = store.CountTiles();
  ExpectNamesFile(count.status(), path);
  // A few tiles of each declared level (the store has no listing; the viewer asks like this),
  // decoded: a decompression bomb must be refused from its header, never allocated.
  if (loaded.ok() && loaded->pyramid) {
    const int levels = std::clamp(loaded->pyramid->levels, 0, 4);
    for (int level = 0; level < levels; ++level) {
      for (int y = 0; y < 2; ++y) {
        for (int x = 0; x < 2; ++x) {
          const auto tile = store.ReadTile(level, x, y);
          ExpectNamesFile(tile.status(), path);
          if (tile.ok() && tile->has_value()) {
            static_cast<void>(tiles::DecodeTile(**tile, loaded->pyramid->tile_size));
          }
        }
      }
    }
  }
  ExpectNamesFile(store.ReadTile(0, 0, 0).status(), path);
  ExpectNamesFile(store.ReadTile(-1, 0, 0).status(), path);
  // An unfinished job's checkpoint records (their content is pipeline/checkpoint's, tested in
  // tests/core/pipeline/checkpoint_test.cc).
  ExpectNamesFile(store.ReadCheckpoint().status(), path);
  ExpectNamesFile(pipeline::ReadCheckpoint(store).status(), path);
}

void WriteFile(const fs::path& path, const uint8_t* data, size_t size) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) Fail("cannot write the input file");
}

// The complete mission the edit scripts start from, as file bytes, and its tables and columns.
struct EditBase {
  std::vector<uint8_t> bytes;
  std::vector<std::pair<std::string, std::vector<std::string>>> tables;
};

const EditBase& Base() {
  static const EditBase base = [] {
    EditBase made;
    const fs::path path = WorkDir() / "base.saker";
    RemoveFiles(path);
    {
      auto store = mission::MissionStore::Create(path.string());
      if (!store.ok()) Fail("cannot create the base mission");
      mission::Mission m = mission::testing_support::MakeFullMission();
      if (!(*store)->Save(m).ok()) Fail("cannot save the base mission");
      // Tiles the edits can swap: bytes that are no image, and decompression bombs.
      if (!(*store)
               ->WriteTiles({{0, 0, 0, {1, 2, 3}},
                             {1, 0, 0, {4}},
                             {0, 1, 0, saker::testing::PngBomb(40000, 40000)},
                             {0, 0, 1, saker::testing::PngBomb(16384, 16384)}})
               .ok()) {
        Fail("cannot write the base tiles");
      }
    }  // closing checkpoints the write-ahead log into the file
    sqlite3* db = nullptr;
    if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
      Fail("cannot read the base mission");
    }
    sqlite3_stmt* tables = nullptr;
    sqlite3_prepare_v2(db, "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name", -1,
                       &tables, nullptr);
    while (sqlite3_step(tables) == SQLITE_ROW) {
      made.tables.push_back({reinterpret_cast<const char*>(sqlite3_column_text(tables, 0)), {}});
    }
    sqlite3_finalize(tables);
    for (auto& [table, columns] : made.tables) {
      sqlite3_stmt* info = nullptr;
      sqlite3_prepare_v2(db, ("PRAGMA table_info(\"" + table + "\")").c_str(), -1, &info, nullptr);
      while (sqlite3_step(info) == SQLITE_ROW) {
        columns.push_back(reinterpret_cast<const char*>(sqlite3_column_text(info, 1)));
      }
      sqlite3_finalize(info);
    }
    sqlite3_close(db);
    std::ifstream in(path, std::ios::binary);
    made.bytes.assign(std::istreambuf_iterator<char>(in), {});
    RemoveFiles(path);
    if (made.tables.empty() || made.bytes.empty()) Fail("the base mission is empty");
    return made;
  }();
  return base;
}

// Reads the edit script and applies it to the mission at `path` (errors of single edits, such as
// a constraint failure, are ignored: the next edit goes on).
void ApplyEdits(const uint8_t* data, size_t size, const fs::path& path) {
  const EditBase& base = Base();
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    sqlite3_close(db);
    return;
  }
  size_t pos = 0;
  auto next = [&]() -> uint8_t { return pos < size ? data[pos++] : 0; };
  for (int edit = 0; edit < 16 && pos < size; ++edit) {
    const uint8_t op = next();
    const auto& [table, columns] = base.tables[next() % base.tables.size()];
    const std::string& column = columns[next() % columns.size()];
    const std::string row =
        "(SELECT rowid FROM \"" + table + "\" LIMIT 1 OFFSET " + std::to_string(next() % 8) + ")";
    std::string sql;
    switch (op % 8) {
      case 6:
        sql = "DELETE FROM \"" + table + "\" WHERE rowid = " + row;
        break;
      case 7:
        sql = "INSERT INTO \"" + table + "\" SELECT * FROM \"" + table + "\" WHERE rowid = " + row;
        break;
      default:
        sql = "UPDATE \"" + table + "\" SET \"" + column + "\" = ?1 WHERE rowid = " + row;
        break;
    }
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      sqlite3_finalize(stmt);
      continue;
    }
    uint8_t bytes[8] = {};
    switch (op % 8) {
      case 0:
        sqlite3_bind_null(stmt, 1);
        break;
      case 1: {
        for (uint8_t& b : bytes) b = next();
        int64_t v = 0;
        std::memcpy(&v, bytes, sizeof(v));
        sqlite3_bind_int64(stmt, 1, v);
        break;
      }
      case 2: {
        for (uint8_t& b : bytes) b = next();
        double v = 0;
        std::memcpy(&v, bytes, sizeof(v));
        sqlite3_bind_double(stmt, 1, v);
        break;
      }
      case 3:
      case 4: {
        const size_t length = std::min<size_t>(next(), size - std::min(pos, size));
        if (op % 8 == 3) {
          sqlite3_bind_text(stmt, 1, reinterpret_cast<const char*>(data + pos),
                            static_cast<int>(length), SQLITE_TRANSIENT);
        } else {
          sqlite3_bind_blob(stmt, 1, data + pos, static_cast<int>(length), SQLITE_TRANSIENT);
        }
        pos += length;
        break;
      }
      case 5:  // a small integer, the usual kind of wrong count or index
        sqlite3_bind_int64(stmt, 1, static_cast<int8_t>(next()));
        break;
      default:
        break;
    }
    sqlite3_step(stmt);
    sqlite3_finalize(stmt);
  }
  sqlite3_close(db);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // libFuzzer ends with _Exit (no atexit handlers), so the directory is removed after every
  // input and made again before the next.
  std::error_code ignored;
  fs::create_directories(WorkDir(), ignored);
  const fs::path path = WorkDir() / "input.saker";
  RemoveFiles(path);
  static constexpr char kSqliteHeader[] = "SQLite format 3";  // 16 bytes with the NUL
  if (size >= sizeof(kSqliteHeader) &&
      std::memcmp(data, kSqliteHeader, sizeof(kSqliteHeader)) == 0) {
    WriteFile(path, data, size);
  } else {
    const EditBase& base = Base();
    WriteFile(path, base.bytes.data(), base.bytes.size());
    ApplyEdits(data, size, path);
  }
  const std::string name = path.string();
  for (mission::OpenMode mode : {mission::OpenMode::kReadOnly, mission::OpenMode::kReadWrite}) {
    auto store = mission::MissionStore::Open(name, mode);
    ExpectNamesFile(store.status(), name);
    if (!store.ok()) break;
    LoadEverything(**store, name);
  }
  RemoveFiles(path);
  fs::remove(WorkDir(), ignored);
  return 0;
}
