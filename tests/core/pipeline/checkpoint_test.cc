// The checkpoint records in the mission file: a hand-made checkpoint round trips field by field,
// and damaged records (cut short, bytes changed, absurd counts) are refused with the file named,
// never read past their end.

#include "core/pipeline/checkpoint.h"

#include "core/track/picture.h"
#include "tests/testing/png_bomb.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sqlite3.h>

#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace saker::pipeline {
namespace {

namespace fs = std::filesystem;

track::TargetTrack Target(int64_t id, int64_t first_frame, int frames) {
  track::TargetTrack t;
  t.id = static_cast<track::TargetTrackId>(id);
  t.confirmed = true;
  t.max_features = 3;
  t.image_velocity = {1.5, -0.25};
  for (int i = 0; i < frames; ++i) {
    track::TargetObservation o;
    o.frame = first_frame + i;
    o.position = {10.0 + i, 20.0 - 0.5 * i};
    o.box_min = o.position - Eigen::Vector2d(4, 3);
    o.box_max = o.position + Eigen::Vector2d(4, 3);
    o.velocity = {0.5, 0.125};
    o.change = static_cast<track::ChangeEvidence>(i % 3);
    for (int f = 0; f <= i % 3; ++f)
      o.features.push_back(static_cast<track::FeatureTrackId>(100 * id + f));
    t.observations.push_back(o);
  }
  return t;
}

// Frames 0..9, key frames at 0, 4 and 9 with images, two links, a break, targets of every kind.
frontend::FrontEndCheckpoint MakeCheckpoint() {
  frontend::FrontEndCheckpoint c;
  c.through_frame = 9;
  c.change_through_frame = 1;
  c.state = {1, 0, 0, 0, 255, 7, 0, 42};  // the front end's own bytes, kept as they are
  for (int i = 0; i < 10; ++i) {
    frontend::FrameResult f;
    f.index = i;
    f.time_s = 0.04 * i;
    f.pts = 3600 * i;
    f.key_frame = i % 5 == 0;
    f.homography_ok = i > 0;
    f.current_from_previous = Eigen::Matrix3d::Identity();
    f.current_from_previous(0, 2) = 0.1 * i;
    f.covariance = track::HomographyCovariance::Identity() * (1e-6 * (i + 1));
    f.tracked = 300 + i;
    f.inliers = 200 + i;
    f.moving = i;
    if (i % 3 == 1) f.sky_line = track::HorizonLine{427, 100.5 + i, 0.01 * i};
    c.frames.push_back(f);
  }
  for (int k = 0; k < 3; ++k) {
    track::KeyFrame key;
    key.id = static_cast<track::KeyFrameId>(k);
    key.frame_index = k == 2 ? 9 : 4 * k;
    key.segment = 0;
    for (int p = 0; p < 5; ++p) {
      key.points.emplace_back(static_cast<track::FeatureTrackId>(k * 10 + p),
                              Eigen::Vector2d(p, 2.0 * p));
    }
    c.key_frames.push_back(key);
    frontend::KeyFramePreview preview;
    preview.image.id = key.id;
    preview.image.frame_index = key.frame_index;
    preview.image.scale = 2;
    preview.image.grey = cv::Mat(18, 32, CV_8UC1);
    cv::RNG rng(static_cast<uint64_t>(k + 1));  // the same pixels every time
    rng.fill(preview.image.grey, cv::RNG::UNIFORM, 0, 256);
    if (k == 1) {  // a colour picture among grey ones
      preview.image.chroma = cv::Mat(9, 16, CV_8UC2);
      rng.fill(preview.image.chroma, cv::RNG::UNIFORM, 0, 256);
      preview.image.coding = {YuvMatrix::kBt709, true};
    }
    preview.preview_from_frame(0, 2) = 7.5 * k;
    c.key_frame_images.push_back(preview);
  }
  for (int l = 0; l < 2; ++l) {
    track::SequentialLink link;
    link.from = static_cast<track::KeyFrameId>(l);
    link.to = static_cast<track::KeyFrameId>(l + 1);
    link.to_from_from(1, 2) = -3.0 * (l + 1);
    link.covariance = track::HomographyCovariance::Identity() * 1e-5;
    link.chained = l == 1;
    link.correspondences.push_back({static_cast<track::FeatureTrackId>(4), {1, 2}, {3, 4}});
    c.links.push_back(link);
  }
  c.breaks.push_back({3, "a cloud"});
  c.targets = {Target(1, 0, 4), Target(2, 2, 5)};
  c.change_targets = {Target(3, 1, 3)};
  c.open_targets = {Target(4, 5, 5)};
  c.open_change_targets = {Target(5, 7, 3)};
  return c;
}

void ExpectSameTargets(const std::vector<track::TargetTrack>& a,
                       const std::vector<track::TargetTrack>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t t = 0; t < a.size(); ++t) {
    EXPECT_EQ(a[t].id, b[t].id);
    EXPECT_EQ(a[t].confirmed, b[t].confirmed);
    EXPECT_EQ(a[t].max_features, b[t].max_features);
    EXPECT_EQ(a[t].image_velocity, b[t].image_velocity);
    ASSERT_EQ(a[t].observations.size(), b[t].observations.size());
    for (size_t i = 0; i < a[t].observations.size(); ++i) {
      const track::TargetObservation& x = a[t].observations[i];
      const track::TargetObservation& y = b[t].observations[i];
      EXPECT_TRUE(x.frame == y.frame && x.position == y.position && x.box_min == y.box_min &&
                  x.box_max == y.box_max && x.velocity == y.velocity && x.change == y.change &&
                  x.features == y.features)
          << "target " << t << " observation " << i;
    }
  }
}

class CheckpointTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = saker::testing::MakeTempDir("saker-checkpoint");
    path_ = (dir_ / "mission.saker").string();
    auto store = mission::MissionStore::Create(path_);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    CheckpointWriter writer(store->get());
    ASSERT_TRUE(writer.Write(MakeCheckpoint()).ok());
  }
  StatusOr<std::optional<frontend::FrontEndCheckpoint>> Read() const {
    auto store = mission::MissionStore::Open(path_);
    if (!store.ok()) return store.status();
    return ReadCheckpoint(**store);
  }
  // Replaces the data of one record, as another tool (or a damaged disk) would.
  void SetRecord(const std::string& kind, int64_t key, const std::vector<uint8_t>& bytes) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path_.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* stmt = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(db, "UPDATE checkpoint SET data = ?1 WHERE kind = ?2 AND key = ?3",
                                 -1, &stmt, nullptr),
              SQLITE_OK);
    static const uint8_t kEmpty = 0;
    sqlite3_bind_blob(stmt, 1, bytes.empty() ? &kEmpty : bytes.data(),
                      static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
    sqlite3_bind_text(stmt, 2, kind.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_int64(stmt, 3, key);
    EXPECT_EQ(sqlite3_step(stmt), SQLITE_DONE);
    EXPECT_EQ(sqlite3_changes(db), 1) << kind << " " << key;
    sqlite3_finalize(stmt);
    sqlite3_close(db);
  }
  void Exec(const char* sql) {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path_.c_str(), &db), SQLITE_OK);
    EXPECT_EQ(sqlite3_exec(db, sql, nullptr, nullptr, nullptr), SQLITE_OK) << sql;
    sqlite3_close(db);
  }
  std::vector<uint8_t> GetRecord(const std::string& kind, int64_t key) const {
    auto store = mission::MissionStore::Open(path_);
    EXPECT_TRUE(store.ok());
    auto records = (*store)->ReadCheckpoint();
    EXPECT_TRUE(records.ok());
    for (const mission::CheckpointRecord& r : *records) {
      if (r.kind == kind && r.key == key) return r.bytes;
    }
    ADD_FAILURE() << "no record " << kind << " " << key;
    return {};
  }

  fs::path dir_;
  std::string path_;
};

TEST_F(CheckpointTest, EveryFieldRoundTrips) {
  const frontend::FrontEndCheckpoint c = MakeCheckpoint();
  const auto read = Read();
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_TRUE(read->has_value());
  const frontend::FrontEndCheckpoint& r = **read;
  EXPECT_EQ(r.through_frame, c.through_frame);
  EXPECT_EQ(r.complete, c.complete);
  EXPECT_EQ(r.change_through_frame, c.change_through_frame);
  EXPECT_EQ(r.state, c.state);
  ASSERT_EQ(r.frames.size(), c.frames.size());
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const frontend::FrameResult& a = r.frames[i];
    const frontend::FrameResult& b = c.frames[i];
    EXPECT_TRUE(a.index == b.index && a.time_s == b.time_s && a.pts == b.pts &&
                a.key_frame == b.key_frame && a.homography_ok == b.homography_ok &&
                a.current_from_previous == b.current_from_previous &&
                a.covariance == b.covariance && a.tracked == b.tracked && a.inliers == b.inliers &&
                a.moving == b.moving && a.sky_line.has_value() == b.sky_line.has_value())
        << "frame " << i;
    if (a.sky_line && b.sky_line) {
      EXPECT_EQ(a.sky_line->YAt(0), b.sky_line->YAt(0)) << "frame " << i;
      EXPECT_EQ(a.sky_line->slope, b.sky_line->slope) << "frame " << i;
    }
  }
  ASSERT_EQ(r.key_frames.size(), c.key_frames.size());
  for (size_t k = 0; k < c.key_frames.size(); ++k) {
    EXPECT_EQ(r.key_frames[k].id, c.key_frames[k].id);
    EXPECT_EQ(r.key_frames[k].frame_index, c.key_frames[k].frame_index);
    EXPECT_EQ(r.key_frames[k].points, c.key_frames[k].points);
    const frontend::KeyFramePreview& a = r.key_frame_images[k];
    const frontend::KeyFramePreview& b = c.key_frame_images[k];
    EXPECT_EQ(a.image.scale, b.image.scale);
    EXPECT_EQ(a.preview_from_frame, b.preview_from_frame);
    ASSERT_EQ(a.image.grey.size(), b.image.grey.size());
    EXPECT_EQ(cv::norm(a.image.grey, b.image.grey, cv::NORM_INF), 0);
    ASSERT_EQ(a.image.chroma.size(), b.image.chroma.size()) << "key frame " << k;
    ASSERT_EQ(a.image.chroma.type(), b.image.chroma.type()) << "key frame " << k;
    if (!b.image.chroma.empty()) {
      EXPECT_EQ(cv::norm(a.image.chroma, b.image.chroma, cv::NORM_INF), 0);
      EXPECT_EQ(a.image.coding, b.image.coding);
    }
  }
  ASSERT_EQ(r.links.size(), c.links.size());
  for (size_t l = 0; l < c.links.size(); ++l) {
    EXPECT_EQ(r.links[l].to_from_from, c.links[l].to_from_from);
    EXPECT_EQ(r.links[l].chained, c.links[l].chained);
    ASSERT_EQ(r.links[l].correspondences.size(), 1u);
    EXPECT_EQ(r.links[l].correspondences[0].target, c.links[l].correspondences[0].target);
  }
  ASSERT_EQ(r.breaks.size(), 1u);
  EXPECT_EQ(r.breaks[0].reason, "a cloud");
  ExpectSameTargets(r.targets, c.targets);
  ExpectSameTargets(r.change_targets, c.change_targets);
  ExpectSameTargets(r.open_targets, c.open_targets);
  ExpectSameTargets(r.open_change_targets, c.open_change_targets);

  auto store = mission::MissionStore::Open(path_);
  ASSERT_TRUE(store.ok());
  const auto state = ReadCheckpointState(**store);
  ASSERT_TRUE(state.ok() && state->has_value());
  EXPECT_EQ((*state)->through_frame, 9);
  EXPECT_EQ((*state)->key_frames, 3);
  EXPECT_FALSE((*state)->complete);
}

// Every record cut short at every length, and bytes changed at random: refused (or, for a change
// that keeps the layout valid, read), never read past the end; the message names the file.
TEST_F(CheckpointTest, DamagedRecordsAreRefusedNamingTheFile) {
  const std::vector<std::pair<std::string, int64_t>> records = {
      {"state", 0}, {"frame", 3},  {"key_frame", 1},     {"key_frame_image", 2}, {"link", 1},
      {"break", 0}, {"target", 1}, {"change_target", 0}, {"open_target", 0}};
  std::mt19937 random(7);
  int refused = 0, read_anyway = 0;
  for (const auto& record : records) {
    // Named copies, not structured bindings: a lambda may capture those only since C++20.
    const std::string& kind = record.first;
    const int64_t key = record.second;
    const std::vector<uint8_t> good = GetRecord(kind, key);
    ASSERT_FALSE(good.empty());
    const auto check = [&](const std::vector<uint8_t>& bad, const std::string& what) {
      SetRecord(kind, key, bad);
      const auto read = Read();
      if (read.ok()) {
        ++read_anyway;
        return;
      }
      ++refused;
      EXPECT_TRUE(read.status().code() == StatusCode::kInvalidData ||
                  read.status().code() == StatusCode::kUnsupported)
          << kind << " " << what << ": " << read.status().ToString();
      EXPECT_NE(read.status().message().find("mission.saker: checkpoint"), std::string::npos)
          << read.status().message();
    };
    const size_t step = std::max<size_t>(1, good.size() / 40);
    for (size_t n = 0; n < good.size(); n += step) {
      check(std::vector<uint8_t>(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(n)),
            "cut to " + std::to_string(n));
    }
    std::vector<uint8_t> longer = good;
    longer.push_back(0);
    check(longer, "one byte too many");
    for (int i = 0; i < 20; ++i) {
      std::vector<uint8_t> changed = good;
      changed[std::uniform_int_distribution<size_t>(0, changed.size() - 1)(random)] ^=
          uint8_t(1 + std::uniform_int_distribution<int>(0, 254)(random));
      check(changed, "changed");
    }
    SetRecord(kind, key, good);
  }
  std::cout << refused << " damaged records refused, " << read_anyway
            << " read (the change kept the layout valid)\n";
  EXPECT_GT(refused, 300);

  // A count that claims more items than the record holds is refused before anything is made.
  std::vector<uint8_t> link = GetRecord("link", 0);
  const size_t count_at = 4 + 4 + 1 + 9 * 8 + 64 * 8;
  ASSERT_GT(link.size(), count_at + 8);
  const uint64_t huge = static_cast<uint64_t>(1) << 60;
  std::memcpy(link.data() + count_at, &huge, sizeof(huge));
  SetRecord("link", 0, link);
  const auto read = Read();
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.status().message().find("record link 0 is truncated or malformed"),
            std::string::npos)
      << read.status().message();
}

// A key frame image record whose PNG header claims 40000 x 40000 pixels (a 100-byte
// decompression bomb) aborted `process --resume` with an uncaught cv::Exception. It is
// InvalidData naming the file and the record, refused from the header before anything is decoded.
TEST_F(CheckpointTest, DecompressionBombKeyFrameImageIsRefusedNamingTheRecord) {
  std::vector<uint8_t> record = GetRecord("key_frame_image", 2);
  const size_t png_at = 4 + 8 + 8 + 9 * 8;  // id, frame, scale, placement, then the PNG's size
  ASSERT_GT(record.size(), png_at + 8);
  record.resize(png_at);
  const std::vector<uint8_t> bomb = saker::testing::PngBomb(40000, 40000);
  const uint64_t size = bomb.size();
  record.resize(png_at + sizeof(size));
  std::memcpy(record.data() + png_at, &size, sizeof(size));
  record.insert(record.end(), bomb.begin(), bomb.end());
  SetRecord("key_frame_image", 2, record);
  const auto read = Read();
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(read.status().message().find("mission.saker: checkpoint record key_frame_image 2"),
            std::string::npos)
      << read.status().message();
  EXPECT_NE(read.status().message().find("40000x40000"), std::string::npos)
      << read.status().message();
}

// A colour key frame's chroma must be half its grey's size: another size is refused naming the
// record, and so is an unknown colour matrix; a record without chroma (an older Saker's) is grey.
TEST_F(CheckpointTest, ColourOfAKeyFrameImageIsChecked) {
  const std::vector<uint8_t> colour = GetRecord("key_frame_image", 1);
  const size_t png_at = 4 + 8 + 8 + 9 * 8;  // id, frame, scale, placement, then the PNG's size
  uint64_t png_size = 0;
  ASSERT_GT(colour.size(), png_at + sizeof(png_size));
  std::memcpy(&png_size, colour.data() + png_at, sizeof(png_size));
  const size_t chroma_at = png_at + sizeof(png_size) + png_size;  // matrix, range, PNG
  ASSERT_GT(colour.size(), chroma_at + 2);

  std::vector<uint8_t> wrong_size(colour.begin(),
                                  colour.begin() + static_cast<std::ptrdiff_t>(chroma_at + 2));
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(9, 30, CV_8UC1, cv::Scalar(128)), png));
  const uint64_t size = png.size();
  wrong_size.resize(wrong_size.size() + sizeof(size));
  std::memcpy(wrong_size.data() + chroma_at + 2, &size, sizeof(size));
  wrong_size.insert(wrong_size.end(), png.begin(), png.end());
  SetRecord("key_frame_image", 1, wrong_size);
  auto read = Read();
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(read.status().message().find("checkpoint record key_frame_image 1"), std::string::npos)
      << read.status().message();

  std::vector<uint8_t> bad_matrix = colour;
  bad_matrix[chroma_at] = 7;
  SetRecord("key_frame_image", 1, bad_matrix);
  EXPECT_EQ(Read().status().code(), StatusCode::kInvalidData);

  SetRecord("key_frame_image", 1,
            std::vector<uint8_t>(colour.begin(),
                                 colour.begin() + static_cast<std::ptrdiff_t>(chroma_at)));
  read = Read();
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_TRUE(read->has_value());
  ASSERT_GT((*read)->key_frame_images.size(), 1u);
  EXPECT_FALSE(track::IsColour((*read)->key_frame_images[1].image));
  EXPECT_FALSE((*read)->key_frame_images[1].image.grey.empty());
}

TEST_F(CheckpointTest, RecordsThatDoNotFitTogetherAreRefused) {
  // A frame missing from the middle: the rest no longer fits.
  Exec("DELETE FROM checkpoint WHERE kind = 'frame' AND key = 5");
  auto read = Read();
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(read.status().message().find("mission.saker: checkpoint"), std::string::npos)
      << read.status().message();
  // An unknown kind (a newer Saker's) is named.
  Exec("INSERT INTO checkpoint VALUES ('hologram', 0, x'00')");
  read = Read();
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.status().message().find("unknown record kind 'hologram'"), std::string::npos)
      << read.status().message();
}

}  // namespace
}  // namespace saker::pipeline
