#include "core/pipeline/process.h"

#include "core/mission/mission_store.h"
#include "core/pipeline/evaluate.h"
#include "core/pipeline/export_mission.h"
#include "core/sim/simulator.h"
#include "tests/testing/small_loop.h"
#include "tests/testing/test_data.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <thread>

namespace saker::pipeline {
namespace {

// A small revisiting flight (tests/testing/small_loop.h), simulated once for the suite.
class ProcessTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(testing::MakeTempDir("saker-process"));
    const sim::SimulationOptions options = saker::testing::SmallLoopOptions(*dir_ / "loop.ts");
    const auto summary = sim::Simulate(options);
    ASSERT_TRUE(summary.ok()) << summary.status().ToString();
    truth_path_ = new std::filesystem::path(options.TruthPath());
  }
  static void TearDownTestSuite() {
    delete dir_;
    delete truth_path_;
  }
  static std::string Video() { return (*dir_ / "loop.ts").string(); }

  static std::filesystem::path* dir_;
  static std::filesystem::path* truth_path_;
};
std::filesystem::path* ProcessTest::dir_ = nullptr;
std::filesystem::path* ProcessTest::truth_path_ = nullptr;

TEST_F(ProcessTest, ProcessesIntoAMissionThatReopensWithTheTruthsActivity) {
  const std::string path = (*dir_ / "full.saker").string();
  std::vector<std::string> commits;
  ProcessOptions options;
  options.saker_version = "test";
  options.on_commit = [&](const std::string& stage) { commits.push_back(stage); };
  // The preview a viewer shows while the front end runs: every key frame, as it is made.
  std::vector<frontend::KeyFramePreview> previews;
  options.front_end.on_key_frame = [&](const frontend::KeyFramePreview& preview) {
    EXPECT_TRUE(commits == std::vector<std::string>{"source"}) << "a preview after the front end";
    previews.push_back(preview);
  };
  const auto summary = ProcessVideo(Video(), path, options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  std::cout << summary->ToText();
  EXPECT_EQ(commits,
            (std::vector<std::string>{"source", "front end", "mosaic", "activity", "tiles"}));
  ASSERT_EQ(int64_t(previews.size()), summary->key_frames);
  for (size_t i = 1; i < previews.size(); ++i) {
    EXPECT_GT(previews[i].image.frame_index, previews[i - 1].image.frame_index);
    EXPECT_FALSE(previews[i].image.grey.empty());
  }
  // The first video frame is the preview's frame; the camera flies on, so later key frames
  // are placed away from it.
  if (previews.front().image.frame_index == 0) {
    EXPECT_TRUE(previews.front().preview_from_frame.isApprox(Eigen::Matrix3d::Identity()));
  }
  EXPECT_GT(previews.back().preview_from_frame.col(2).head<2>().norm(), 50.0);
  EXPECT_TRUE(summary->geo_referenced);

  // Reopened read-only: everything the run produced, nothing reprocessed.
  const auto store = mission::MissionStore::Open(path);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  const auto m = (*store)->Load();
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_TRUE(m->progress.front_end && m->progress.mosaic && m->progress.activity &&
              m->progress.tiles);
  EXPECT_FALSE(m->progress.cancelled);
  EXPECT_EQ(int64_t(m->frames.size()), summary->frames);
  EXPECT_EQ(int64_t(m->key_frames.size()), summary->key_frames);
  EXPECT_EQ(int64_t(m->tracks.size()), summary->tracks);
  EXPECT_GT(summary->tracks, 3);
  ASSERT_TRUE(m->pyramid.has_value());
  EXPECT_EQ(*(*store)->CountTiles(), summary->tiles);
  EXPECT_EQ(m->source.path, std::filesystem::absolute(Video()).string());
  EXPECT_EQ(*mission::FingerprintFile(Video()), m->source.fingerprint);

  // The activity against the truth: speed, visit and picking (docs/activity.md has the demo's).
  const auto truth = sim::ReadTruth(*truth_path_);
  ASSERT_TRUE(truth.ok());
  const auto accuracy = EvaluateActivity(*m, *truth, options.activity.visit_gap_s);
  ASSERT_TRUE(accuracy.ok()) << accuracy.status().ToString();
  std::cout << ActivityAccuracyToText(*accuracy);
  EXPECT_GE(accuracy->matched, 3);
  EXPECT_LT(accuracy->speed_median_error_mps, 1.0);
  EXPECT_LT(accuracy->direction_median_error_deg, 15.0);
  EXPECT_GE(accuracy->visit_agreement, 0.8);
  // The loop revisits the town: some tracks are seen on the second pass, so the agreement above
  // covers second visits too.
  int max_visit = 0;
  for (const mission::ActivityTrack& t : m->tracks) max_visit = std::max(max_visit, t.visit);
  EXPECT_GE(max_visit, 2);
  EXPECT_GE(accuracy->pick_accuracy, 0.5);
}

TEST_F(ProcessTest, CancelKeepsTheStagesThatCompleted) {
  const std::string path = (*dir_ / "cancelled.saker").string();
  JobContext job;
  ProcessOptions options;
  options.on_commit = [&](const std::string& stage) {
    if (stage == "front end") job.RequestCancel();
  };
  const auto summary = ProcessVideo(Video(), path, options, &job);
  ASSERT_FALSE(summary.ok());
  EXPECT_EQ(summary.status().code(), StatusCode::kCancelled);
  EXPECT_NE(summary.status().message().find(path), std::string::npos);
  const auto store = mission::MissionStore::Open(path);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  const auto m = (*store)->Load();
  ASSERT_TRUE(m.ok()) << m.status().ToString();
  EXPECT_TRUE(m->progress.front_end);
  EXPECT_FALSE(m->progress.mosaic);
  EXPECT_TRUE(m->progress.cancelled);
  EXPECT_FALSE(m->frames.empty());
}

// Save As: a complete copy, tiles included; never over the source or over a file that is not a
// mission.
TEST_F(ProcessTest, CopyMissionCopiesEverythingAndRefusesToOverwriteOtherFiles) {
  const std::string source = (*dir_ / "to-copy.saker").string();
  ProcessOptions options;
  options.saker_version = "test";
  ASSERT_TRUE(ProcessVideo(Video(), source, options).ok());
  const std::string copy = (*dir_ / "copy.saker").string();
  ASSERT_TRUE(CopyMission(source, copy, false).ok());
  const auto a = mission::MissionStore::Open(source);
  const auto b = mission::MissionStore::Open(copy);
  ASSERT_TRUE(a.ok() && b.ok());
  const auto ma = (*a)->Load();
  const auto mb = (*b)->Load();
  ASSERT_TRUE(ma.ok() && mb.ok());
  EXPECT_EQ(ma->frames.size(), mb->frames.size());
  EXPECT_EQ(ma->key_frames.size(), mb->key_frames.size());
  EXPECT_EQ(ma->tracks.size(), mb->tracks.size());
  EXPECT_EQ(ma->source.fingerprint, mb->source.fingerprint);
  EXPECT_EQ(*(*a)->CountTiles(), *(*b)->CountTiles());
  EXPECT_EQ(*(*a)->ReadTile(0, 0, 0), *(*b)->ReadTile(0, 0, 0));

  EXPECT_EQ(CopyMission(source, copy, false).code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(CopyMission(source, copy, true).ok());
  EXPECT_EQ(CopyMission(source, source, true).code(), StatusCode::kInvalidArgument);
  const std::filesystem::path notes = *dir_ / "notes.saker";
  std::ofstream(notes) << "not a mission\n";
  const Status refused = CopyMission(source, notes.string(), true);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.message().find("notes.saker"), std::string::npos) << refused.message();
  std::ifstream kept(notes);
  std::string line;
  std::getline(kept, line);
  EXPECT_EQ(line, "not a mission");
  for (const auto& entry : std::filesystem::directory_iterator(*dir_)) {
    EXPECT_EQ(entry.path().string().find(".part-"), std::string::npos) << entry.path();
  }
}

TEST_F(ProcessTest, NotAVideoLeavesNoMission) {
  const std::filesystem::path text = *dir_ / "notes.ts";
  std::ofstream(text) << "this is not a video\n";
  const std::string path = (*dir_ / "never.saker").string();
  const auto summary = ProcessVideo(text.string(), path, {});
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("notes.ts"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path));
}

// kill -9 of `saker-cli process` at random moments: the mission, when there is one, always
// reopens in a committed state.
TEST_F(ProcessTest, KillNineDuringProcessingLeavesAReadableMission) {
  std::mt19937_64 random(20261121);
  int runs = 0, failures = 0, with_file = 0;
  for (int run = 0; run < 8; ++run) {
    const std::string path = (*dir_ / ("killed-" + std::to_string(run) + ".saker")).string();
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      const int null = ::open("/dev/null", O_WRONLY);
      dup2(null, STDOUT_FILENO);
      dup2(null, STDERR_FILENO);
      execl(SAKER_CLI_PATH, SAKER_CLI_PATH, "process", Video().c_str(), "-o", path.c_str(), "-q",
            static_cast<char*>(nullptr));
      _exit(127);
    }
    // Spread over the whole job (a few seconds for this clip), front end to tiles.
    std::this_thread::sleep_for(
        std::chrono::milliseconds(std::uniform_int_distribution<int>(50, 6000)(random)));
    kill(child, SIGKILL);
    int status = 0;
    waitpid(child, &status, 0);
    ++runs;
    if (!std::filesystem::exists(path)) continue;
    ++with_file;
    const auto store = mission::MissionStore::Open(path);
    const auto m = store.ok() ? (*store)->Load() : StatusOr<mission::Mission>(store.status());
    if (!m.ok()) {
      ++failures;
      ADD_FAILURE() << "run " << run << ": " << m.status().ToString();
    }
  }
  std::cout << runs << " runs killed, " << with_file << " left a mission file, " << failures
            << " failed to reopen\n";
  EXPECT_EQ(failures, 0);
  EXPECT_GT(with_file, 0);
}

}  // namespace
}  // namespace saker::pipeline
