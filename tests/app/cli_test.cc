// saker-cli run as a newcomer runs it: through the shell, reading its output
// and exit code.

#include "core/mission/mission_store.h"
#include "tests/testing/test_data.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

namespace {

struct CliRun {
  int exit_code = -1;
  std::string out;  // stdout and stderr together
};

// `shell_prefix` goes before the command, in the same shell (a `ulimit`).
CliRun RunCli(const std::string& arguments, const std::string& shell_prefix = "") {
  const std::string command =
      shell_prefix + "exec " + std::string(SAKER_CLI_PATH) + " " + arguments + " 2>&1";
  CliRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0) run.out.append(buffer.data(), n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

TEST(CliTest, HelpListsTheCommands) {
  const CliRun run = RunCli("--help");
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_NE(run.out.find("probe"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("klv"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("Exit codes"), std::string::npos) << run.out;
}

TEST(CliTest, BadCommandLineExitsTwo) {
  EXPECT_EQ(RunCli("").exit_code, 2);
  EXPECT_EQ(RunCli("probe").exit_code, 2);
  EXPECT_EQ(RunCli("frobnicate x.ts").exit_code, 2);
  EXPECT_EQ(RunCli("probe x.ts --async-tolerance -3").exit_code, 2);
}

TEST(CliTest, MissingFileExitsOneAndNamesIt) {
  const CliRun run = RunCli("probe /nonexistent/sortie-7.ts");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("/nonexistent/sortie-7.ts"), std::string::npos) << run.out;
}

TEST(CliTest, ProbeSummarisesTheRealClip) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/aphill_short.ts");
  const CliRun run = RunCli("probe '" + path.string() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("h264 720x480, 29.970 fps, 48 frames"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("48 packets, 48 EG 0104"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("48 of 48 with metadata, 48 with image corners"), std::string::npos)
      << run.out;
  // FFmpeg's own log lines stay off unless --verbose.
  EXPECT_EQ(run.out.find("[mpegts @"), std::string::npos) << run.out;
}

TEST(CliTest, JsonOutputsParse) {
  SAKER_REQUIRE_TEST_DATA(path, "kwiver/h265_tricky_klv.ts");
  const CliRun probe = RunCli("probe --json '" + path.string() + "'");
  ASSERT_EQ(probe.exit_code, 0) << probe.out;
  const auto summary = nlohmann::json::parse(probe.out);
  EXPECT_EQ(summary["klv_streams"].size(), 3u);
  EXPECT_EQ(summary["klv_streams"][0]["timing"], "synchronous");
  EXPECT_EQ(summary["metadata"]["packets"], 90);

  const CliRun klv = RunCli("klv --json '" + path.string() + "'");
  ASSERT_EQ(klv.exit_code, 0);
  const auto dump = nlohmann::json::parse(klv.out);
  ASSERT_EQ(dump["packets"].size(), 90u);
  // Every tag is listed, nested sets raw: the security set (tag 48) of the
  // first packet of the exhaustive (synchronous) stream.
  const int exhaustive_stream = summary["klv_streams"][0]["stream"];
  bool found_security = false;
  for (const auto& packet : dump["packets"]) {
    if (packet["stream"] != exhaustive_stream) continue;
    for (const auto& item : packet["items"]) {
      if (item["tag"] == 48) found_security = !item["raw"].get<std::string>().empty();
    }
    break;
  }
  EXPECT_TRUE(found_security);
}

}  // namespace

namespace {

const char* kSmallSimulation =
    "--width 320 --height 180 --altitude 100 --fps 10 --duration 2 --quiet";

// Simulates the small straight flight into DIR/flight.ts and, with `process`, its mission
// DIR/flight.saker; gives (video, mission), empty when a step failed (reported).
std::pair<std::string, std::string> SmallFlight(const std::filesystem::path& dir, bool process) {
  const std::string video = (dir / "flight.ts").string();
  const CliRun sim = RunCli("simulate --scenario straight -o '" + video + "' " + kSmallSimulation);
  EXPECT_EQ(sim.exit_code, 0) << sim.out;
  if (sim.exit_code != 0) return {};
  const std::string mission = (dir / "flight.saker").string();
  if (!process) return {video, ""};
  const CliRun run = RunCli("process -q '" + video + "' -o '" + mission + "'");
  EXPECT_EQ(run.exit_code, 0) << run.out;
  if (run.exit_code != 0) return {};
  return {video, mission};
}

TEST(CliSimulateTest, HelpListsScenariosAndOptions) {
  const CliRun run = RunCli("simulate --help");
  EXPECT_EQ(run.exit_code, 0);
  for (const char* word : {"roundabout-loop", "figure-eight", "raster", "straight", "--klv-noise",
                           "--klv-every", "--klv-dropout", "--ground", "--gsd", "--blank-start",
                           "--seed", "--truth", "--cars", "--altitude"}) {
    EXPECT_NE(run.out.find(word), std::string::npos) << word;
  }
}

TEST(CliSimulateTest, OutputProbesWithVideoAndKlv) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-sim");
  const std::string video = (dir / "small.ts").string();
  const CliRun sim = RunCli("simulate --scenario straight -o '" + video + "' " + kSmallSimulation);
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  EXPECT_TRUE(std::filesystem::exists(dir / "small.truth.json"));
  const CliRun probe = RunCli("probe --json '" + video + "'");
  ASSERT_EQ(probe.exit_code, 0) << probe.out;
  const nlohmann::json summary = nlohmann::json::parse(probe.out);
  ASSERT_EQ(summary["klv_streams"].size(), 1u);
  EXPECT_EQ(summary["klv_streams"][0]["st0601_packets"], 20);
  EXPECT_EQ(summary["klv_streams"][0]["checksum_failures"], 0);
  EXPECT_EQ(summary["metadata"]["frames_with_corners"], 20);
  bool h264 = false;
  for (const auto& stream : summary["streams"]) h264 |= stream["codec"] == "h264";
  EXPECT_TRUE(h264) << probe.out;

  // An existing output is never overwritten without --force.
  const CliRun again =
      RunCli("simulate --scenario straight -o '" + video + "' " + kSmallSimulation);
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.out.find("--force"), std::string::npos) << again.out;
  EXPECT_EQ(RunCli("simulate --scenario straight --force -o '" + video + "' " + kSmallSimulation)
                .exit_code,
            0);
}

TEST(CliSimulateTest, BadArgumentsAreUsageErrors) {
  const CliRun run = RunCli("simulate --scenario loop-the-loop -o /tmp/x.ts");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.out.find("roundabout-loop"), std::string::npos) << run.out;
  EXPECT_EQ(RunCli("simulate -o /tmp/x.ts --width 321").exit_code, 2);
  EXPECT_EQ(RunCli("simulate --scenario straight").exit_code, 2);  // no -o
}

}  // namespace

TEST(CliMosaicTest, WritesThePictureAndSummarises) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-mosaic");
  const std::string video = SmallFlight(dir, /*process=*/false).first;
  ASSERT_FALSE(video.empty());
  const std::string picture = (dir / "mosaic.png").string();
  const CliRun run = RunCli("mosaic --json -o '" + picture + "' '" + video + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json j = nlohmann::json::parse(run.out);
  EXPECT_GE(j["key_frames"].get<int>(), 2);
  EXPECT_TRUE(j["geo_referenced"].get<bool>());
  EXPECT_GT(j["picture_width"].get<int>(), 0);
  EXPECT_TRUE(std::filesystem::exists(picture));
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename().string().find(".part-"), std::string::npos) << entry.path();
  }
}

TEST(CliMosaicTest, BadInputsNameTheProblem) {
  CliRun run = RunCli("mosaic /nonexistent/sortie-7.ts -o /tmp/saker-never.png");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("sortie-7.ts"), std::string::npos) << run.out;
  run = RunCli("mosaic /nonexistent/sortie-7.ts -o /nonexistent/folder/m.png");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("/nonexistent/folder"), std::string::npos) << run.out;
  EXPECT_EQ(RunCli("mosaic x.ts").exit_code, 2);  // no -o
}

namespace {

// process, then copy (Save As): the copy holds the same mission; the original is never the
// target, a file that is not a mission is never replaced, and an existing mission only with
// --replace.
TEST(CliMissionTest, CopyMakesTheSameMissionAndRefusesWhatItMustNot) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-copy");
  const std::string mission = SmallFlight(dir, /*process=*/true).second;
  ASSERT_FALSE(mission.empty());
  CliRun run;
  const std::string copy = (dir / "copy.saker").string();
  run = RunCli("copy '" + mission + "' '" + copy + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const auto info = [&](const std::string& path) {
    const CliRun i = RunCli("info --json '" + path + "'");
    EXPECT_EQ(i.exit_code, 0) << i.out;
    nlohmann::json j = nlohmann::json::parse(i.out, nullptr, /*allow_exceptions=*/false);
    j.erase("path");
    j.erase("mission");
    return j;
  };
  const nlohmann::json original = info(mission), copied = info(copy);
  EXPECT_FALSE(original.is_discarded());
  EXPECT_EQ(original.dump(), copied.dump());

  run = RunCli("copy '" + mission + "' '" + mission + "' --replace");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("an input of this job"), std::string::npos) << run.out;
  run = RunCli("copy '" + mission + "' '" + copy + "'");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("already there"), std::string::npos) << run.out;
  EXPECT_EQ(RunCli("copy '" + mission + "' '" + copy + "' --replace").exit_code, 0);
  const std::string text = (dir / "notes.saker").string();
  std::FILE* file = std::fopen(text.c_str(), "w");
  ASSERT_NE(file, nullptr);
  std::fputs("not a mission\n", file);
  std::fclose(file);
  run = RunCli("copy '" + mission + "' '" + text + "' --replace");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.out.find("notes.saker"), std::string::npos) << run.out;
  EXPECT_EQ(std::filesystem::file_size(text), 14u);
  std::filesystem::remove_all(dir);
}

// A video too small to track (16x16 pixels) but with metadata on every frame: no key frame, so
// no mosaic and no map. `process` and `info` say that, and that the frames have metadata, not
// "no metadata" (what they said before, inferring it from the map not being geo-referenced).
TEST(CliMissionTest, InfoSaysWhatTheMapIsAndThatTheFramesHaveMetadata) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-tiny");
  const std::string video = (dir / "tiny.ts").string();
  ASSERT_EQ(RunCli("simulate -q -o '" + video + "' --duration 1 --width 16 --height 16").exit_code,
            0);
  const std::string mission = (dir / "tiny.saker").string();
  CliRun run = RunCli("process -q --no-tiles '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_EQ(run.out.find("no metadata"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("no mosaic was made (25 of 25 frames have metadata)"), std::string::npos)
      << run.out;
  run = RunCli("info '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_EQ(run.out.find("no metadata"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("map: none: no mosaic was made"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("metadata: 25 of 25 frames; KLV 25 packets, 0 failed the checksum"),
            std::string::npos)
      << run.out;
  run = RunCli("info --json '" + mission + "'");
  const nlohmann::json info = nlohmann::json::parse(run.out, nullptr, false);
  ASSERT_FALSE(info.is_discarded()) << run.out;
  EXPECT_EQ(info["frames_with_metadata"], 25);
  EXPECT_EQ(info["klv"]["checksum_failures"], 0);
  std::filesystem::remove_all(dir);
}

// Issue 29: `export M.saker --csv M.saker` replaced the mission and exited 0 (item 5), and an
// export to a special file replaced it (item 6). The outputs may not be the job's inputs; "-" is
// standard output, which then gets the file alone.
TEST(CliMissionTest, ExportRefusesItsInputsAndWritesToStandardOutput) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-export");
  const auto flight = SmallFlight(dir, /*process=*/true);
  const std::string &video = flight.first, &mission = flight.second;
  ASSERT_FALSE(mission.empty());
  const auto size = std::filesystem::file_size(mission);
  for (const char* option : {"--csv", "--geojson", "--kml", "--geotiff"}) {
    for (const std::string& target : {mission, video}) {
      const CliRun run =
          RunCli("export '" + mission + "' " + std::string(option) + " '" + target + "'");
      EXPECT_EQ(run.exit_code, 1) << option << " " << target << ": " << run.out;
      EXPECT_NE(run.out.find("an input of this job"), std::string::npos) << run.out;
    }
  }
  EXPECT_EQ(std::filesystem::file_size(mission), size);
  ASSERT_EQ(RunCli("info '" + mission + "'").exit_code, 0);
  // Standard output: the CSV alone (the summary goes to stderr, discarded here).
  const CliRun csv = RunCli("export '" + mission + "' --csv - 2>/dev/null; exit $?");
  ASSERT_EQ(csv.exit_code, 0) << csv.out;
  EXPECT_EQ(csv.out.rfind("video,track_id,", 0), 0u) << csv.out;
  EXPECT_EQ(csv.out.find("wrote"), std::string::npos) << csv.out;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename().string().find(".part-"), std::string::npos) << entry.path();
  }
  std::filesystem::remove_all(dir);
}

// Issue 24 item 6: --min-confidence on `process` (tracks below are not stored) and `export`
// (tracks below are left out of every output); a value that is not a number from 0 to 1 is a
// usage error naming it.
TEST(CliMissionTest, MinConfidenceFiltersProcessAndExportAndRefusesBadValues) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-confidence");
  // 12 s of the small loop (tests/testing/small_loop.h): a few cars, of different confidences.
  const std::string video = (dir / "loop.ts").string(), mission = (dir / "loop.saker").string();
  CliRun sim = RunCli("simulate -q --scenario roundabout-loop -o '" + video +
                      "' --width 640 --height 360 --altitude 200 --fps 12.5 --loop-length 500 "
                      "--cars 6 --vans 0 --people 4 --duration 12");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  sim = RunCli("process -q --no-tiles '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  for (const std::string value : {"-1", "2", "abc", "nan", ""}) {
    for (const std::string& command :
         {"process -q '" + video + "' -o '" + (dir / "bad.saker").string() + "'",
          "export '" + mission + "' --csv '" + (dir / "bad.csv").string() + "'"}) {
      const CliRun run = RunCli(command + " --min-confidence '" + value + "'");
      EXPECT_EQ(run.exit_code, 2) << command << " " << value << ": " << run.out;
      EXPECT_NE(run.out.find("--min-confidence"), std::string::npos) << run.out;
      EXPECT_NE(run.out.find("\"" + value + "\" is not a confidence: give a number from 0 to 1"),
                std::string::npos)
          << run.out;
    }
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.saker"));
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.csv"));

  // Every track of a new mission has a confidence; the export keeps those at the threshold.
  const auto confidences = [&](const std::string& options) {
    const CliRun run =
        RunCli("export '" + mission + "' --geojson - " + options + " 2>/dev/null; exit $?");
    EXPECT_EQ(run.exit_code, 0) << run.out;
    std::vector<double> values;
    const nlohmann::json j = nlohmann::json::parse(run.out, nullptr, false);
    EXPECT_FALSE(j.is_discarded()) << run.out;
    if (j.is_discarded()) return values;
    for (const auto& feature : j["features"]) {
      EXPECT_TRUE(feature["properties"]["confidence"].is_number()) << feature["properties"];
      if (feature["properties"]["confidence"].is_number()) {
        values.push_back(feature["properties"]["confidence"].get<double>());
      }
    }
    return values;
  };
  std::vector<double> all = confidences("");  // before any verdict
  ASSERT_GE(all.size(), 2u) << "the small flight's cars";
  std::sort(all.begin(), all.end());
  // As the command line will read it back.
  const double threshold = std::stod(std::to_string(0.5 * (all.front() + all.back())));
  const size_t above =
      static_cast<size_t>(all.end() - std::lower_bound(all.begin(), all.end(), threshold));
  ASSERT_GT(all.back(), all.front()) << "tracks of one confidence cannot test a threshold";
  const std::vector<double> kept = confidences("--min-confidence " + std::to_string(threshold));
  EXPECT_EQ(kept.size(), above);
  for (const double c : kept) EXPECT_GE(c, threshold);
  // The activity map too.
  const CliRun png = RunCli("export '" + mission + "' --png '" + (dir / "map.png").string() +
                            "' --min-confidence " + std::to_string(threshold));
  ASSERT_EQ(png.exit_code, 0) << png.out;
  EXPECT_NE(png.out.find(std::to_string(above) + " track"), std::string::npos) << png.out;

  // `info` lists the tracks by confidence.
  CliRun info = RunCli("info '" + mission + "'");
  EXPECT_NE(info.out.find("track confidence: "), std::string::npos) << info.out;

  // `info` counts the observations interpolated across gaps; the CSV's last column marks the same.
  const CliRun csv = RunCli("export '" + mission + "' --csv - 2>/dev/null; exit $?");
  ASSERT_EQ(csv.exit_code, 0) << csv.out;
  const CliRun counts = RunCli("info --json '" + mission + "'");
  const nlohmann::json listed = nlohmann::json::parse(counts.out, nullptr, false);
  ASSERT_FALSE(listed.is_discarded()) << counts.out;
  int64_t rows = -1, marked = 0;  // less the header
  for (size_t at = 0; at < csv.out.size();) {
    const size_t end = csv.out.find("\r\n", at);
    if (end == std::string::npos) break;
    ++rows;
    marked += rows > 0 && csv.out.compare(end - 2, 2, ",1") == 0;
    at = end + 2;
  }
  EXPECT_GT(rows, 0);
  EXPECT_EQ(rows, listed["observations"].get<int64_t>());
  EXPECT_EQ(marked, listed["interpolated_observations"].get<int64_t>());
  std::printf("%lld of %lld observations interpolated\n", static_cast<long long>(marked),
              static_cast<long long>(rows));

  // The analyst marks a track false (as the workstation does): exports leave it out unless
  // --include-false, and carry the verdicts; `info` counts them.
  int64_t judged = 0;
  {
    auto store = saker::mission::MissionStore::Open(mission, saker::mission::OpenMode::kReadWrite);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    auto loaded = (*store)->Load();
    ASSERT_TRUE(loaded.ok());
    ASSERT_FALSE(loaded->tracks.empty());
    judged = loaded->tracks.front().id;
    loaded->reviews = {
        {judged, saker::mission::Verdict::kFalse, saker::mission::TargetLabel::kNone, "a shadow"}};
    ASSERT_TRUE((*store)->SaveReviews(*loaded).ok());
  }
  const auto exported_ids = [&](const std::string& options) {
    const CliRun run =
        RunCli("export '" + mission + "' --geojson - " + options + " 2>/dev/null; exit $?");
    EXPECT_EQ(run.exit_code, 0) << run.out;
    std::map<int64_t, std::string> ids;  // id -> verdict
    const nlohmann::json j = nlohmann::json::parse(run.out, nullptr, false);
    if (j.is_discarded()) return ids;
    for (const auto& feature : j["features"]) {
      const auto& verdict = feature["properties"]["verdict"];
      ids[feature["id"].get<int64_t>()] = verdict.is_string() ? verdict.get<std::string>() : "";
    }
    return ids;
  };
  const std::map<int64_t, std::string> trusted = exported_ids("");
  EXPECT_EQ(trusted.size(), all.size() - 1);
  EXPECT_EQ(trusted.count(judged), 0u);
  const std::map<int64_t, std::string> every = exported_ids("--include-false");
  EXPECT_EQ(every.size(), all.size());
  ASSERT_EQ(every.count(judged), 1u);
  EXPECT_EQ(every.at(judged), "false");
  info = RunCli("info '" + mission + "'");
  EXPECT_NE(info.out.find("analyst: 0 tracks confirmed, 1 marked false"), std::string::npos)
      << info.out;

  // The report: HTML or PDF by the name, the false track left out; another name is refused.
  const std::string html = (dir / "report.html").string(), pdf = (dir / "report.pdf").string();
  CliRun report = RunCli("report '" + mission + "' -o '" + html + "'");
  ASSERT_EQ(report.exit_code, 0) << report.out;
  EXPECT_NE(report.out.find("report: " + std::to_string(all.size() - 1) + " tracks"),
            std::string::npos)
      << report.out;
  std::ifstream html_in(html);
  const std::string html_text((std::istreambuf_iterator<char>(html_in)),
                              std::istreambuf_iterator<char>());
  EXPECT_EQ(html_text.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_EQ(html_text.find("<b>Track " + std::to_string(judged) + "</b>"), std::string::npos);
  report = RunCli("report '" + mission + "' -o '" + pdf + "' --no-chips");
  ASSERT_EQ(report.exit_code, 0) << report.out;
  EXPECT_TRUE(std::filesystem::file_size(pdf) > 1000);
  report = RunCli("report '" + mission + "' -o '" + (dir / "report.docx").string() + "'");
  EXPECT_EQ(report.exit_code, 2) << report.out;
  EXPECT_NE(report.out.find(".html or .pdf"), std::string::npos) << report.out;

  // Processing with the threshold stores only the tracks at it and counts the others.
  const std::string strict = (dir / "strict.saker").string();
  const CliRun run = RunCli("process -q --json --no-tiles '" + video + "' -o '" + strict +
                            "' --min-confidence " + std::to_string(threshold));
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json summary = nlohmann::json::parse(run.out, nullptr, false);
  ASSERT_FALSE(summary.is_discarded()) << run.out;
  EXPECT_EQ(summary["tracks"].get<size_t>(), above);
  EXPECT_EQ(summary["tracks_low_confidence"].get<size_t>(), all.size() - above);
  EXPECT_EQ(summary["tracks_implausible"].get<size_t>(), 0u);
  std::filesystem::remove_all(dir);
}

// Two jobs on one mission (issue 29): while a job writes the mission (it holds the lock beside
// it, docs/mission-file.md, held here by the test as that job), a second `process --replace` or
// `--resume` is refused naming the writer's process, and leaves the mission as it was; `info`
// still reads it. `info` and `export` leave no -wal/-shm beside a mission they read.
TEST(CliMissionTest, ASecondJobOnAMissionBeingWrittenIsRefused) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-two-jobs");
  const auto flight = SmallFlight(dir, /*process=*/true);
  const std::string &video = flight.first, &mission = flight.second;
  ASSERT_FALSE(mission.empty());
  CliRun run;
  const auto size = std::filesystem::file_size(mission);
  run = RunCli("info '" + mission + "'");
  EXPECT_EQ(run.exit_code, 0) << run.out;
  run = RunCli("export '" + mission + "' --csv '" + (dir / "tracks.csv").string() + "'");
  EXPECT_EQ(run.exit_code, 0) << run.out;
  for (const char* side : {"-wal", "-shm"}) {
    EXPECT_FALSE(std::filesystem::exists(mission + side)) << side << " left beside the mission";
  }

  const int lock = ::open((mission + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  ASSERT_GE(lock, 0);
  ASSERT_EQ(::flock(lock, LOCK_EX | LOCK_NB), 0);
  const std::string pid = std::to_string(::getpid());
  ASSERT_EQ(::write(lock, pid.data(), pid.size()), static_cast<ssize_t>(pid.size()));
  for (const char* how : {"--replace", "--resume"}) {
    run = RunCli("process -q '" + video + "' -o '" + mission + "' " + how);
    EXPECT_EQ(run.exit_code, 1) << how << ": " << run.out;
    EXPECT_NE(run.out.find("in use by process " + pid), std::string::npos)
        << how << ": " << run.out;
  }
  EXPECT_EQ(std::filesystem::file_size(mission), size);
  run = RunCli("info '" + mission + "'");  // readers are not blocked
  EXPECT_EQ(run.exit_code, 0) << run.out;
  ::close(lock);
  std::filesystem::remove_all(dir);
}

// Under memory pressure (`ulimit -v` of 400-800 MB) `process` aborted on an uncaught cv::Exception
// or std::runtime_error (a thread it could not start). Whatever the limit, it now ends with a
// message and exit code 1, or succeeds; the mission opens, holding what its last commit holds.
TEST(CliMissionTest, MemoryPressureEndsWithAMessageNeverAnAbort) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "sanitizers reserve terabytes of address space: no `ulimit -v` under them";
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
  GTEST_SKIP() << "sanitizers reserve terabytes of address space: no `ulimit -v` under them";
#endif
#endif
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-memory");
  const std::string video = (dir / "flight.ts").string();
  ASSERT_EQ(RunCli("simulate --scenario straight -o '" + video + "' " + kSmallSimulation).exit_code,
            0);
  int failed = 0;
  for (int mb = 400; mb <= 800; mb += 50) {
    const std::string mission = (dir / ("m" + std::to_string(mb) + ".saker")).string();
    const CliRun run = RunCli("process -q '" + video + "' -o '" + mission + "'",
                              "ulimit -v " + std::to_string(mb * 1000) + " && ");
    if (run.exit_code == 127) continue;  // too little even to load the shared libraries
    EXPECT_TRUE(run.exit_code == 0 || run.exit_code == 1) << mb << " MB: " << run.out;
    EXPECT_EQ(run.out.find("terminate"), std::string::npos) << mb << " MB: " << run.out;
    if (run.exit_code != 1) continue;
    ++failed;
    EXPECT_NE(run.out.find("out of memory"), std::string::npos) << mb << " MB: " << run.out;
    if (std::filesystem::exists(mission)) {
      const CliRun info = RunCli("info '" + mission + "'");
      EXPECT_EQ(info.exit_code, 0) << mb << " MB: " << info.out;
    }
  }
  std::cout << failed << " of 9 runs ran out of memory\n";
}

}  // namespace

namespace saker {
namespace {

// Video below 4 frames a second is processed in the low-frame-rate mode, and the summary says so
// (text and JSON); `--low-frame-rate off` turns it off, and a mode that is not one is refused.
TEST(CliProcessTest, LowFrameRateModeIsChosenBelowEightFramesASecond) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-low-rate");
  const std::string video = (dir / "two-fps.ts").string();
  const CliRun sim =
      RunCli("simulate --scenario straight -o '" + video +
             "' --width 320 --height 180 --altitude 100 --fps 2 --duration 6 --quiet");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string mission = (dir / "two-fps.saker").string();
  CliRun run = RunCli("process -q --no-tiles '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("low-frame-rate mode, video at 2 frames a second"), std::string::npos)
      << run.out;
  // The mission keeps it: info says it too.
  run = RunCli("info '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("front end found: targets: from change detection alone"),
            std::string::npos)
      << run.out;
  run = RunCli("info --json '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_TRUE(nlohmann::json::parse(run.out).at("findings").at("low_frame_rate").get<bool>());
  run = RunCli("process -q --json --no-tiles --replace --low-frame-rate off '" + video + "' -o '" +
               mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_FALSE(nlohmann::json::parse(run.out).at("low_frame_rate").get<bool>());
  run = RunCli("process -q --json --no-tiles --replace --low-frame-rate on '" + video + "' -o '" +
               mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_TRUE(nlohmann::json::parse(run.out).at("low_frame_rate").get<bool>());
  run = RunCli("process --low-frame-rate sometimes '" + video + "' -o '" + mission + "'");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.out.find("sometimes not in {auto,on,off}"), std::string::npos) << run.out;
}

// A low oblique view: process says the horizon was masked, and the mission keeps each frame's
// sky line (info: "sky masked: N of M frames", sky_frames in JSON).
TEST(CliProcessTest, ALowObliqueViewsSkyIsMaskedAndKeptInTheMission) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-horizon");
  const std::string video = (dir / "oblique.ts").string();
  const CliRun sim = RunCli("simulate --scenario straight -o '" + video +
                            "' --width 640 --height 360 --altitude 30 --off-nadir 82 --duration 3 "
                            "--quiet");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string mission = (dir / "oblique.saker").string();
  CliRun run = RunCli("process '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("horizon: the view reaches the horizon in"), std::string::npos) << run.out;
  run = RunCli("info --json '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json info = nlohmann::json::parse(run.out);
  const int64_t sky = info.at("sky_frames").get<int64_t>();
  EXPECT_GE(sky, info.at("frames").get<int64_t>() * 9 / 10);
  run = RunCli("info '" + mission + "'");
  EXPECT_NE(run.out.find("sky masked: " + std::to_string(sky) + " of "), std::string::npos)
      << run.out;
}

// Heavily compressed video raises the motion thresholds; process says so (text and JSON), and
// --noise-thresholds fixed keeps the thresholds tuned on clean video.
TEST(CliProcessTest, NoisyVideoRaisesTheThresholdsAndSaysSo) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-noise");
  const std::string video = (dir / "crf38.ts").string();
  const CliRun sim = RunCli("simulate --scenario straight -o '" + video +
                            "' --width 640 --height 360 --altitude 200 --duration 4 --crf 38 "
                            "--quiet");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string mission = (dir / "crf38.saker").string();
  CliRun run = RunCli("process --no-tiles '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("noise: the video's own noise (heavy compression?) raised the motion "
                         "thresholds in "),
            std::string::npos)
      << run.out;
  run = RunCli("process -q --json --no-tiles --replace '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_GT(nlohmann::json::parse(run.out).at("noise_feature_frames").get<int64_t>(), 0);
  run = RunCli("process -q --json --no-tiles --replace --noise-thresholds fixed '" + video +
               "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json fixed = nlohmann::json::parse(run.out);
  EXPECT_EQ(fixed.at("noise_feature_frames").get<int64_t>(), 0);
  EXPECT_EQ(fixed.at("noise_change_frames").get<int64_t>(), 0);
  run = RunCli("process --noise-thresholds loud '" + video + "' -o '" + mission + "'");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.out.find("loud not in {measured,fixed}"), std::string::npos) << run.out;
}

TEST(CliProcessTest, TheOverlayMaskIsOnByDefaultSaysWhatItMaskedAndCanBeTurnedOff) {
  const std::filesystem::path dir = saker::testing::MakeTempDir("saker-cli-overlay");
  const std::string video = (dir / "hud.ts").string();
  const CliRun sim = RunCli("simulate --scenario straight -o '" + video +
                            "' --width 640 --height 360 --altitude 200 --duration 10 --hud-text "
                            "--reticle --logo rotating --quiet");
  ASSERT_EQ(sim.exit_code, 0) << sim.out;
  const std::string mission = (dir / "hud.saker").string();
  CliRun run = RunCli("process --no-tiles '" + video + "' -o '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_NE(run.out.find("overlays: screen-fixed overlays masked out in"), std::string::npos)
      << run.out;
  // The mission keeps the masks; info reports them.
  run = RunCli("info --json '" + mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json on = nlohmann::json::parse(run.out);
  const nlohmann::json kept = on.at("overlay_masks");
  EXPECT_GT(kept.at("masks").get<int64_t>(), 0);
  EXPECT_GT(kept.at("frames").get<int64_t>(), 0);
  EXPECT_GT(kept.at("coverage").get<double>(), 0.0);
  EXPECT_LT(kept.at("coverage").get<double>(), 0.5);
  run = RunCli("info '" + mission + "'");
  EXPECT_NE(
      run.out.find("overlay masks: " + std::to_string(kept.at("masks").get<int64_t>()) + " over "),
      std::string::npos)
      << run.out;
  // A nadir view reaches no horizon: no frame's sky is masked.
  EXPECT_EQ(on.at("sky_frames").get<int64_t>(), 0);
  EXPECT_NE(run.out.find("sky masked: none"), std::string::npos) << run.out;
  run = RunCli("process -q --json --no-tiles --replace --overlay-mask off '" + video + "' -o '" +
               mission + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  const nlohmann::json off = nlohmann::json::parse(run.out);
  EXPECT_EQ(off.at("overlay_frames").get<int64_t>(), 0);
  EXPECT_EQ(off.at("overlay_coverage").get<double>(), 0.0);
  run = RunCli("info '" + mission + "'");
  EXPECT_NE(run.out.find("overlay masks: none"), std::string::npos) << run.out;
  // Without the mask the overlay's corners make tracks of their own.
  EXPECT_GT(off.at("tracks").get<int64_t>(), on.at("tracks").get<int64_t>());
  run = RunCli("process --overlay-mask sometimes '" + video + "' -o '" + mission + "'");
  EXPECT_EQ(run.exit_code, 2);
  EXPECT_NE(run.out.find("sometimes not in {on,off}"), std::string::npos) << run.out;
  // evaluate takes the same option, a bare --overlay-mask meaning on.
  run = RunCli("evaluate --json --overlay-mask '" + video + "'");
  ASSERT_EQ(run.exit_code, 0) << run.out;
  EXPECT_GT(nlohmann::json::parse(run.out).at("overlay_mask").at("frames").get<int64_t>(), 0);
}

}  // namespace
}  // namespace saker
