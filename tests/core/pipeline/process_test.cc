#include "core/pipeline/process.h"

#include "core/eval/video_evaluation.h"
#include "core/mission/mission_store.h"
#include "core/pipeline/checkpoint.h"
#include "core/pipeline/export_mission.h"
#include "core/sim/simulator.h"
#include "core/video/video_reader.h"
#include "tests/testing/sanitizers.h"
#include "tests/testing/small_loop.h"
#include "tests/testing/test_data.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
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
  const int64_t opened = video::InputsOpened();
  const auto summary = ProcessVideo(Video(), path, options);
  ASSERT_TRUE(summary.ok()) << summary.status().ToString();
  std::cout << summary->ToText();
  // One reader gives the source record and the front end's frames and metadata.
  EXPECT_EQ(video::InputsOpened() - opened, 1) << "the job opens its video once";
  EXPECT_EQ(commits,
            (std::vector<std::string>{"source", "front end", "mosaic", "activity", "tiles"}));
  ASSERT_EQ(static_cast<int64_t>(previews.size()), summary->key_frames);
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
  EXPECT_EQ(static_cast<int64_t>(m->frames.size()), summary->frames);
  EXPECT_EQ(static_cast<int64_t>(m->key_frames.size()), summary->key_frames);
  EXPECT_EQ(static_cast<int64_t>(m->tracks.size()), summary->tracks);
  EXPECT_GT(summary->tracks, 3);
  ASSERT_TRUE(m->pyramid.has_value());
  EXPECT_EQ(*(*store)->CountTiles(), summary->tiles);
  EXPECT_EQ(m->source.path, std::filesystem::absolute(Video()).string());
  EXPECT_EQ(*mission::FingerprintFile(Video()), m->source.fingerprint);

  // The activity against the truth: speed, visit and picking (docs/activity.md has the demo's).
  const auto truth = sim::ReadTruth(*truth_path_);
  ASSERT_TRUE(truth.ok());
  const auto accuracy = eval::EvaluateActivity(*m, *truth, options.activity.visit_gap_s);
  ASSERT_TRUE(accuracy.ok()) << accuracy.status().ToString();
  std::cout << eval::ActivityAccuracyToText(*accuracy);
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

// The front end's checkpoints go through the mission file unchanged: read back, they are what
// the front end handed out, merged.
TEST_F(ProcessTest, CheckpointsRoundTripThroughTheMissionFile) {
  SAKER_SKIP_UNDER_TSAN("ProcessesIntoAMissionThatReopensWithTheTruthsActivity");
  const std::string path = (*dir_ / "checkpoint.saker").string();
  auto store = mission::MissionStore::Create(path);
  ASSERT_TRUE(store.ok()) << store.status().ToString();
  CheckpointWriter writer(store->get());
  frontend::FrontEndCheckpoint merged;
  frontend::FrontEndOptions options;
  options.checkpoint_interval_s = 0;
  int deliveries = 0;
  options.on_checkpoint = [&](const frontend::FrontEndCheckpoint& c) -> Status {
    ++deliveries;
    merged.Append(c);
    SAKER_RETURN_IF_ERROR(writer.Write(c));
    // What the file holds is always the whole checkpoint so far.
    StatusOr<std::optional<frontend::FrontEndCheckpoint>> read = ReadCheckpoint(**store);
    if (!read.ok()) return read.status();
    EXPECT_TRUE(read->has_value());
    EXPECT_EQ((*read)->frames.size(), merged.frames.size());
    EXPECT_EQ((*read)->open_targets.size(), merged.open_targets.size());
    return Status::Ok();
  };
  const int64_t opened = video::InputsOpened();
  StatusOr<frontend::FrontEndResult> result = frontend::RunFrontEnd(Video(), options);
  ASSERT_TRUE(result.ok()) << result.status().ToString();
  EXPECT_EQ(video::InputsOpened() - opened, 1) << "the front end opens its video once";
  ASSERT_GE(deliveries, 5);
  StatusOr<std::optional<frontend::FrontEndCheckpoint>> read = ReadCheckpoint(**store);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_TRUE(read->has_value());
  const frontend::FrontEndCheckpoint& c = **read;
  EXPECT_TRUE(c.complete);
  EXPECT_EQ(c.through_frame, merged.through_frame);
  ASSERT_EQ(c.frames.size(), result->frames.size());
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const frontend::FrameResult& a = c.frames[i];
    const frontend::FrameResult& b = result->frames[i];
    ASSERT_TRUE(a.index == b.index && a.time_s == b.time_s && a.pts == b.pts &&
                a.key_frame == b.key_frame && a.homography_ok == b.homography_ok &&
                a.current_from_previous == b.current_from_previous &&
                a.covariance == b.covariance && a.tracked == b.tracked && a.inliers == b.inliers &&
                a.moving == b.moving)
        << "frame " << i;
  }
  ASSERT_EQ(c.key_frames.size(), result->key_frames.size());
  for (size_t k = 0; k < c.key_frames.size(); ++k) {
    EXPECT_EQ(c.key_frames[k].frame_index, result->key_frames[k].frame_index);
    EXPECT_EQ(c.key_frames[k].segment, result->key_frames[k].segment);
    EXPECT_EQ(c.key_frames[k].points, result->key_frames[k].points);
  }
  ASSERT_EQ(c.key_frame_images.size(), result->key_frame_images.size());
  for (size_t k = 0; k < c.key_frame_images.size(); ++k) {
    const frontend::KeyFrameImage& a = c.key_frame_images[k].image;
    const frontend::KeyFrameImage& b = result->key_frame_images[k];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.scale, b.scale);
    ASSERT_EQ(a.grey.size(), b.grey.size());
    EXPECT_EQ(cv::norm(a.grey, b.grey, cv::NORM_INF), 0) << "key frame image " << k;
  }
  ASSERT_EQ(c.links.size(), result->links.size());
  for (size_t l = 0; l < c.links.size(); ++l) {
    EXPECT_EQ(c.links[l].to_from_from, result->links[l].to_from_from);
    EXPECT_EQ(c.links[l].covariance, result->links[l].covariance);
    EXPECT_EQ(c.links[l].chained, result->links[l].chained);
    ASSERT_EQ(c.links[l].correspondences.size(), result->links[l].correspondences.size());
  }
  ASSERT_EQ(c.targets.size(), result->targets.size());
  for (size_t t = 0; t < c.targets.size(); ++t) {
    ASSERT_EQ(c.targets[t].observations.size(), result->targets[t].observations.size());
    for (size_t o = 0; o < c.targets[t].observations.size(); ++o) {
      const track::TargetObservation& a = c.targets[t].observations[o];
      const track::TargetObservation& b = result->targets[t].observations[o];
      EXPECT_TRUE(a.frame == b.frame && a.position == b.position && a.box_min == b.box_min &&
                  a.box_max == b.box_max && a.features == b.features && a.change == b.change);
    }
  }
}

// A job stopped half way resumes from its checkpoint into a mission as good as one processed
// in one go; the checkpoint is dropped once the job completes.
TEST_F(ProcessTest, AnInterruptedJobResumesFromItsCheckpoint) {
  // Two and a half whole runs (about 200 s under TSan); cancel and a whole run cover its threads.
  SAKER_SKIP_UNDER_TSAN("CancelKeepsTheStagesThatCompleted and ProcessesIntoAMission...");
  ProcessOptions options;
  options.saker_version = "test";
  const std::string whole = (*dir_ / "whole.saker").string();
  const auto baseline = ProcessVideo(Video(), whole, options);
  ASSERT_TRUE(baseline.ok()) << baseline.status().ToString();

  const std::string path = (*dir_ / "interrupted.saker").string();
  JobContext job;
  int64_t stopped_at = -1;
  options.front_end.checkpoint_interval_s = 0;
  options.front_end.on_checkpoint = [&](const frontend::FrontEndCheckpoint& c) {
    if (2 * c.through_frame >= baseline->frames && stopped_at < 0) {
      stopped_at = c.through_frame;
      job.RequestCancel();
    }
    return Status::Ok();
  };
  const auto interrupted = ProcessVideo(Video(), path, options, &job);
  ASSERT_FALSE(interrupted.ok());
  ASSERT_EQ(interrupted.status().code(), StatusCode::kCancelled);
  ASSERT_GT(stopped_at, 0);
  {
    auto store = mission::MissionStore::Open(path);
    ASSERT_TRUE(store.ok());
    const auto checkpoint = ReadCheckpoint(**store);
    ASSERT_TRUE(checkpoint.ok()) << checkpoint.status().ToString();
    ASSERT_TRUE(checkpoint->has_value());
    EXPECT_EQ((*checkpoint)->through_frame, stopped_at);
    EXPECT_FALSE((*checkpoint)->complete);
  }
  // A damaged checkpoint is refused with the file and the record named, the mission kept.
  const std::string damaged = (*dir_ / "damaged.saker").string();
  ASSERT_TRUE(CopyMission(path, damaged, false).ok());
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(damaged.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(
        sqlite3_exec(db, "UPDATE checkpoint SET data = x'0102' WHERE kind = 'frame' AND key = 7",
                     nullptr, nullptr, nullptr),
        SQLITE_OK);
    sqlite3_close(db);
  }
  options.front_end.on_checkpoint = nullptr;
  options.resume = true;
  const auto refused = ProcessVideo(Video(), damaged, options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidData);
  EXPECT_NE(refused.status().message().find("damaged.saker: checkpoint: record frame 7"),
            std::string::npos)
      << refused.status().message();

  const int64_t opened = video::InputsOpened();
  const auto resumed = ProcessVideo(Video(), path, options);
  ASSERT_TRUE(resumed.ok()) << resumed.status().ToString();
  std::cout << resumed->ToText();
  // The scan decodes the frames before the checkpoint with the same reader.
  EXPECT_EQ(video::InputsOpened() - opened, 1) << "the resumed job opens its video once";
  EXPECT_EQ(resumed->resumed_from_frame, stopped_at);
  EXPECT_LT(resumed->front_end_s, baseline->front_end_s);
  auto store = mission::MissionStore::Open(path);
  ASSERT_TRUE(store.ok());
  const auto checkpoint = ReadCheckpoint(**store);
  ASSERT_TRUE(checkpoint.ok());
  EXPECT_FALSE(checkpoint->has_value()) << "the checkpoint of a completed job is dropped";
  const auto m = (*store)->Load();
  ASSERT_TRUE(m.ok());
  EXPECT_TRUE(m->progress.front_end && m->progress.mosaic && m->progress.activity &&
              m->progress.tiles);
  EXPECT_FALSE(m->progress.cancelled);

  // As good as the mission processed in one go.
  const auto reference = (*mission::MissionStore::Open(whole))->Load();
  ASSERT_TRUE(reference.ok());
  EXPECT_EQ(m->frames.size(), reference->frames.size());
  EXPECT_EQ(resumed->frames_placed, baseline->frames_placed);
  EXPECT_NEAR(static_cast<double>(resumed->key_frames), static_cast<double>(baseline->key_frames),
              0.15 * static_cast<double>(baseline->key_frames) + 1);
  EXPECT_NEAR(static_cast<double>(resumed->tracks), static_cast<double>(baseline->tracks), 3);
  const auto truth = sim::ReadTruth(*truth_path_);
  ASSERT_TRUE(truth.ok());
  const auto a = eval::EvaluateActivity(*reference, *truth, options.activity.visit_gap_s);
  const auto b = eval::EvaluateActivity(*m, *truth, options.activity.visit_gap_s);
  ASSERT_TRUE(a.ok() && b.ok());
  std::cout << "in one go:\n"
            << eval::ActivityAccuracyToText(*a) << "resumed:\n"
            << eval::ActivityAccuracyToText(*b);
  EXPECT_GE(b->matched, a->matched - 1);
  EXPECT_LT(b->speed_median_error_mps, a->speed_median_error_mps + 0.3);
  EXPECT_GE(b->visit_agreement, a->visit_agreement - 0.1);

  // Resuming a complete mission leaves it as it is.
  const auto again = ProcessVideo(Video(), path, options);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_TRUE(again->already_complete);
  EXPECT_NE(again->ToText().find("nothing to resume"), std::string::npos);
  // Resuming with another video is refused.
  const std::filesystem::path other = *dir_ / "other.ts";
  std::filesystem::copy_file(Video(), other, std::filesystem::copy_options::overwrite_existing);
  std::filesystem::resize_file(other, std::filesystem::file_size(other) - 188);
  const auto wrong = ProcessVideo(other.string(), path, options);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.status().message().find("made from another video"), std::string::npos)
      << wrong.status().message();
}

// Save As: a complete copy, tiles included; never over the source or over a file that is not a
// mission.
TEST_F(ProcessTest, CopyMissionCopiesEverythingAndRefusesToOverwriteOtherFiles) {
  SAKER_SKIP_UNDER_TSAN("ProcessesIntoAMissionThatReopensWithTheTruthsActivity");
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
  const int64_t opened = video::InputsOpened();
  const auto summary = ProcessVideo(text.string(), path, {});
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.status().message().find("notes.ts"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_EQ(video::InputsOpened() - opened, 1);
  // The stages on a path (the evaluation, saker-cli mosaic): the front end fails, naming the file.
  MissionRun run;
  const Status ran = RunStages(text.string(), {}, {}, nullptr, &run);
  EXPECT_EQ(ran.code(), summary.status().code());
  EXPECT_NE(ran.message().find("notes.ts"), std::string::npos) << ran.message();
  EXPECT_EQ(run.failed, Stage::kFrontEnd);
}

// kill -9 of `saker-cli process` at random moments: the mission, when there is one, always
// reopens in a committed state.
TEST_F(ProcessTest, KillNineDuringProcessingLeavesAReadableMission) {
  SAKER_SKIP_UNDER_TSAN("the tests that process in this process");
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
