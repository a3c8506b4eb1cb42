// Opening a saved mission: its video found at the recorded path, at a remembered place or beside
// the mission; a changed or missing video named; an interrupted job's checkpoint and key frames.

#include "core/pipeline/open_mission.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <filesystem>
#include <fstream>
#include <string>

namespace saker::pipeline {
namespace {

namespace fs = std::filesystem;

void WriteBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

class OpenMissionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = saker::testing::MakeTempDir("saker-open-mission");
    fs::create_directories(dir_ / "recorded");
    fs::create_directories(dir_ / "missions");
    video_ = dir_ / "recorded" / "flight.ts";
    WriteBytes(video_, std::string(5000, 'v'));
    mission_path_ = (dir_ / "missions" / "flight.saker").string();
    mission::Mission m;
    m.source.path = video_.string();
    StatusOr<std::string> fingerprint = mission::FingerprintFile(video_.string());
    ASSERT_TRUE(fingerprint.ok()) << fingerprint.status().ToString();
    m.source.fingerprint = *fingerprint;
    m.source.width = 64;
    m.source.height = 48;
    auto store = mission::MissionStore::Create(mission_path_);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    ASSERT_TRUE((*store)->Save(m, 0).ok());
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  fs::path video_;
  std::string mission_path_;
};

TEST_F(OpenMissionTest, FindsTheVideoWhereItWasProcessed) {
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(opened->video.state, VideoLocation::State::kFound);
  EXPECT_EQ(opened->video.path, video_.string());
  EXPECT_EQ(opened->mission.source.width, 64);
  EXPECT_FALSE(opened->checkpoint.has_value());
  EXPECT_EQ(opened->tiles, 0);
}

TEST_F(OpenMissionTest, FindsAMovedVideoBesideTheMissionOrWhereItWasLocated) {
  const fs::path beside = dir_ / "missions" / "flight.ts";
  fs::rename(video_, beside);
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(opened->video.state, VideoLocation::State::kFound);
  EXPECT_EQ(opened->video.path, beside.string());

  const fs::path elsewhere = dir_ / "archive.ts";
  fs::rename(beside, elsewhere);
  OpenMissionOptions options;
  std::string asked;
  options.remembered_video = [&](const std::string& fingerprint) {
    asked = fingerprint;
    return std::optional<std::string>(elsewhere.string());
  };
  opened = OpenMission(mission_path_, options);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(opened->video.state, VideoLocation::State::kFound);
  EXPECT_EQ(opened->video.path, elsewhere.string());
  EXPECT_EQ(asked, opened->mission.source.fingerprint);
}

TEST_F(OpenMissionTest, NamesAChangedOrMissingVideo) {
  WriteBytes(video_, std::string(5000, 'w'));  // same name and size, other content
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(opened->video.state, VideoLocation::State::kChanged);
  EXPECT_EQ(opened->video.path, video_.string());

  fs::remove(video_);
  opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_EQ(opened->video.state, VideoLocation::State::kMissing);
  EXPECT_EQ(opened->video.path, video_.string());
  ASSERT_EQ(opened->video.looked_at.size(), 2u);  // where it was, beside the mission
  EXPECT_EQ(opened->video.looked_at[1], (dir_ / "missions" / "flight.ts").string());
}

TEST_F(OpenMissionTest, AnInterruptedJobsKeyFramesStandInForTheMosaic) {
  {
    auto store = mission::MissionStore::Open(mission_path_, mission::OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    frontend::FrontEndCheckpoint c;
    c.through_frame = 0;
    frontend::FrameResult f;
    c.frames.push_back(f);
    track::KeyFrame kf;
    c.key_frames.push_back(kf);
    frontend::KeyFramePreview preview;
    preview.image.grey = cv::Mat(12, 16, CV_8UC1, cv::Scalar(90));
    preview.image.scale = 4;
    c.key_frame_images.push_back(preview);
    CheckpointWriter writer(store->get());
    ASSERT_TRUE(writer.Write(c).ok());
  }
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  ASSERT_TRUE(opened->checkpoint.has_value());
  EXPECT_EQ(opened->checkpoint->through_frame, 0);
  ASSERT_EQ(opened->previews.size(), 1u);
  EXPECT_EQ(opened->previews[0].image.grey.cols, 16);

  OpenMissionOptions options;
  options.read_previews = false;
  opened = OpenMission(mission_path_, options);
  ASSERT_TRUE(opened.ok());
  EXPECT_TRUE(opened->previews.empty());
  EXPECT_TRUE(opened->checkpoint.has_value());
}

TEST_F(OpenMissionTest, ANonMissionIsAnErrorNamingTheFile) {
  const fs::path bogus = dir_ / "bogus.saker";
  WriteBytes(bogus, "not a mission at all");
  StatusOr<OpenedMission> opened = OpenMission(bogus.string());
  ASSERT_FALSE(opened.ok());
  EXPECT_NE(opened.status().message().find(bogus.string()), std::string::npos)
      << opened.status().message();
}

// `saker-cli info` and the GUI only read: no -wal, -shm or lock file is left beside the mission.
TEST_F(OpenMissionTest, LeavesNothingBesideTheMissionItReads) {
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  for (const char* suffix : {"-wal", "-shm", "-journal", ".lock"}) {
    EXPECT_FALSE(fs::exists(mission_path_ + suffix)) << mission_path_ + suffix << " left behind";
  }
}

TEST_F(OpenMissionTest, SaysWhetherTheMissionCanBeWritten) {
  StatusOr<OpenedMission> opened = OpenMission(mission_path_);
  ASSERT_TRUE(opened.ok()) << opened.status().ToString();
  EXPECT_FALSE(opened->read_only);
  // Read-only storage itself is tested in mission/MissionAccessTest, as a user who may not write.
}

}  // namespace
}  // namespace saker::pipeline
