// The accuracy benchmark's corpus code (benchmarks/accuracy_corpus.h): the manifests in the
// repository read, a bad manifest is refused with its name and the key at fault, cuts and overlay
// tracks are scored, figures pool as counts, and the smoke manifest runs end to end, every case
// simulated once and taken from the cache the second time.

#include "benchmarks/accuracy_corpus.h"

#include "core/sim/truth.h"
#include "tests/testing/test_data.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace saker::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kCorpusDir = fs::path(SAKER_SOURCE_DIR) / "benchmarks" / "corpus";

json ValidManifest() {
  return json::parse(R"({
    "format": "saker-accuracy-corpus", "version": 1,
    "defaults": { "duration_s": 4, "camera": { "width": 320, "height": 180 } },
    "tuning_seeds": [1, 2], "reporting_seeds": [101],
    "conditions": [ { "name": "a", "options": { "fps": 2 } },
                    { "name": "b", "options": { "flight": { "altitude_m": 600 } },
                      "evaluation": { "min_mover_s": 2 } } ] })");
}

fs::path WriteManifest(const json& manifest, const std::string& name) {
  static const fs::path dir = saker::testing::MakeTempDir("saker-corpus-manifest");
  const fs::path path = dir / name;
  std::ofstream(path) << manifest.dump(2);
  return path;
}

TEST(AccuracyCorpusTest, TheRepositoryManifestsReadWithApartSeeds) {
  if (const auto data = saker::testing::TestDataDir()) SetDefaultTestDataDir(*data);
  for (const char* name : {"corpus.json", "smoke.json", "floors.json"}) {
    const StatusOr<Corpus> corpus = ReadCorpus(kCorpusDir / name);
    ASSERT_TRUE(corpus.ok()) << corpus.status().ToString();
    EXPECT_FALSE(corpus->reporting_seeds.empty()) << name;
    for (uint64_t seed : corpus->reporting_seeds) {
      // The defaults were tuned on worlds 1 to 3.
      EXPECT_GT(seed, 3u) << name;
    }
    // Every condition runs, but one whose orthophoto is in the real test data when that is
    // absent.
    size_t available = 0;
    for (const CorpusCondition& condition : corpus->conditions) {
      available += condition.unavailable.empty();
      if (!condition.unavailable.empty()) {
        EXPECT_NE(condition.unavailable.find("SAKER_TEST_DATA"), std::string::npos);
      }
    }
    EXPECT_GE(available + 1, corpus->conditions.size()) << name;
    EXPECT_EQ(CorpusCases(*corpus, SeedSet::kAll).size(),
              available * (corpus->tuning_seeds.size() + corpus->reporting_seeds.size()));
  }
  const StatusOr<Corpus> corpus = ReadCorpus(kCorpusDir / "corpus.json");
  ASSERT_TRUE(corpus.ok());
  EXPECT_GE(corpus->conditions.size(), 12u);
  // Scoring is in seconds: at 25 fps it is saker-cli evaluate's, at 2 fps no fewer than the floor.
  const std::vector<CorpusCase> demo = CorpusCases(*corpus, SeedSet::kTuning, "nadir-25fps");
  ASSERT_EQ(demo.size(), corpus->tuning_seeds.size());
  const eval::FrontEndEvaluationOptions cli;
  EXPECT_EQ(demo[0].evaluation.min_mover_frames, cli.min_mover_frames);
  EXPECT_EQ(demo[0].evaluation.max_sighting_gap_frames, cli.max_sighting_gap_frames);
  EXPECT_EQ(demo[0].evaluation.gate_px, cli.gate_px);
  EXPECT_EQ(demo[0].simulation.seed, corpus->tuning_seeds[0]);
  EXPECT_TRUE(demo[0].tuning);
  const std::vector<CorpusCase> slow = CorpusCases(*corpus, SeedSet::kReporting, "nadir-2fps");
  ASSERT_FALSE(slow.empty());
  EXPECT_EQ(slow[0].simulation.fps, 2);
  EXPECT_EQ(slow[0].evaluation.min_mover_frames, CorpusScoring::kMinMoverFrames);
  EXPECT_EQ(slow[0].evaluation.max_sighting_gap_frames, 4);
  EXPECT_FALSE(slow[0].tuning);
}

TEST(AccuracyCorpusTest, AnOrthophotoOfTheTestDataIsFoundOrTheConditionIsLeftOut) {
  const fs::path empty = saker::testing::MakeTempDir("saker-corpus-no-data");
  const nlohmann::json manifest = {
      {"format", "saker-accuracy-corpus"},
      {"version", 1},
      {"tuning_seeds", nlohmann::json::array()},
      {"reporting_seeds", {101}},
      {"conditions",
       {{{"name", "ortho"},
         {"options",
          {{"scenario", "straight"},
           {"ground_image", "$SAKER_TEST_DATA/imagery/odm_aukerman_orthomosaic.png"},
           {"ground_gsd_m", 0.3}}}}}}};
  const fs::path path = WriteManifest(manifest, "ortho.json");
  SetDefaultTestDataDir(empty);
  const char* env = std::getenv("SAKER_TEST_DATA");
  const std::string saved = env != nullptr ? env : "";
  unsetenv("SAKER_TEST_DATA");
  StatusOr<Corpus> corpus = ReadCorpus(path);
  ASSERT_TRUE(corpus.ok()) << corpus.status().ToString();
  EXPECT_EQ(corpus->conditions[0].simulation.ground_image,
            empty / "imagery/odm_aukerman_orthomosaic.png");
  EXPECT_NE(corpus->conditions[0].unavailable.find("is missing"), std::string::npos);
  EXPECT_TRUE(CorpusCases(*corpus, SeedSet::kAll).empty());
  // The variable wins over the default.
  setenv("SAKER_TEST_DATA", "/elsewhere", 1);
  corpus = ReadCorpus(path);
  ASSERT_TRUE(corpus.ok());
  EXPECT_EQ(corpus->conditions[0].simulation.ground_image,
            fs::path("/elsewhere/imagery/odm_aukerman_orthomosaic.png"));
  if (env != nullptr) {
    setenv("SAKER_TEST_DATA", saved.c_str(), 1);
  } else {
    unsetenv("SAKER_TEST_DATA");
  }
}

TEST(AccuracyCorpusTest, ConditionOptionsGoOverTheDefaults) {
  const StatusOr<Corpus> corpus = ReadCorpus(WriteManifest(ValidManifest(), "valid.json"));
  ASSERT_TRUE(corpus.ok()) << corpus.status().ToString();
  const std::vector<CorpusCase> cases = CorpusCases(*corpus, SeedSet::kAll);
  ASSERT_EQ(cases.size(), 6u);
  EXPECT_EQ(cases[0].Name(), "a/1");
  EXPECT_EQ(cases[2].Name(), "a/101");
  EXPECT_EQ(cases[0].simulation.fps, 2);
  EXPECT_EQ(cases[0].simulation.camera.width, 320);
  EXPECT_EQ(cases[0].simulation.duration_s, 4);
  EXPECT_EQ(cases[3].simulation.fps, 25);
  EXPECT_EQ(cases[3].simulation.flight.altitude_m, 600);
  EXPECT_EQ(cases[3].simulation.camera.height, 180);
  EXPECT_EQ(cases[3].evaluation.min_mover_frames, 50);
  EXPECT_EQ(CorpusCases(*corpus, SeedSet::kReporting, "b").size(), 1u);
  EXPECT_TRUE(CorpusCases(*corpus, SeedSet::kTuning, "zzz").empty());
  // The cache key follows every option, and only the options.
  StatusOr<std::string> key_a = SimulationKey(cases[0].simulation);
  StatusOr<std::string> key_b = SimulationKey(cases[1].simulation);
  ASSERT_TRUE(key_a.ok() && key_b.ok());
  EXPECT_NE(*key_a, *key_b);
  sim::SimulationOptions moved = cases[0].simulation;
  moved.output = "/elsewhere/video.ts";
  EXPECT_EQ(*SimulationKey(moved), *key_a);
}

TEST(AccuracyCorpusTest, ABadManifestIsRefusedNamingTheFileAndTheKey) {
  struct Bad {
    const char* name;
    std::function<void(json&)> spoil;
    const char* expected;  // in the message, after the file's name
  };
  const std::vector<Bad> cases = {
      {"format", [](json& j) { j["format"] = "other"; }, "format"},
      {"version", [](json& j) { j["version"] = 2; }, "version"},
      {"top-key", [](json& j) { j["condition"] = json::array(); }, "unknown key 'condition'"},
      {"seeds-apart", [](json& j) { j["reporting_seeds"] = {2}; }, "seed 2 is a tuning seed"},
      {"seed-type", [](json& j) { j["tuning_seeds"] = {-1}; }, "tuning_seeds"},
      {"no-conditions", [](json& j) { j["conditions"] = json::array(); }, "conditions"},
      {"option-name",
       [](json& j) {
         j["conditions"][1]["options"]["flight"] = {{"altitud_m", 600}};
       },
       "conditions[1] \"b\".options: unknown simulation option 'flight.altitud_m'"},
      {"option-type", [](json& j) { j["defaults"]["fps"] = "fast"; }, "defaults: option fps"},
      {"option-value", [](json& j) { j["conditions"][0]["options"]["fps"] = 0; },
       "conditions[0] \"a\".options: simulate: fps"},
      {"seed-option", [](json& j) { j["conditions"][0]["options"]["seed"] = 5; },
       "conditions[0] \"a\".options: 'seed'"},
      {"same-name", [](json& j) { j["conditions"][1]["name"] = "a"; }, "a second condition"},
      {"condition-key", [](json& j) { j["conditions"][0]["seeds"] = {7}; },
       "conditions[0] \"a\": unknown key 'seeds'"},
      {"scoring-key",
       [](json& j) {
         j["evaluation"] = {{"min_mover_frames", 3}};
       },
       "evaluation: unknown key 'min_mover_frames'"},
      {"floor-key",
       [](json& j) {
         j["conditions"][0]["floor"] = {{"recall", 0.5}};
       },
       "conditions[0] \"a\".floor: unknown key 'recall'"},
      {"floor-fraction",
       [](json& j) {
         j["conditions"][1]["floor"] = {{"track_recall", 1.5}};
       },
       "conditions[1] \"b\".floor.track_recall: must be a fraction from 0 to 1"},
      {"floor-count",
       [](json& j) {
         j["conditions"][1]["floor"] = {{"overlay_tracks", -1}};
       },
       "conditions[1] \"b\".floor.overlay_tracks: must be a whole number >= 0"},
  };
  for (const Bad& bad : cases) {
    json manifest = ValidManifest();
    bad.spoil(manifest);
    const fs::path path = WriteManifest(manifest, std::string(bad.name) + ".json");
    const StatusOr<Corpus> corpus = ReadCorpus(path);
    ASSERT_FALSE(corpus.ok()) << bad.name;
    EXPECT_NE(corpus.status().message().find(path.string() + ": "), std::string::npos)
        << corpus.status().message();
    EXPECT_NE(corpus.status().message().find(bad.expected), std::string::npos)
        << bad.name << ": " << corpus.status().message();
  }
  const fs::path not_json = WriteManifest(json(), "not-json.json");
  std::ofstream(not_json) << "{ \"format\": ";
  StatusOr<Corpus> corpus = ReadCorpus(not_json);
  ASSERT_FALSE(corpus.ok());
  EXPECT_NE(corpus.status().message().find("not JSON"), std::string::npos);
  corpus = ReadCorpus(not_json.parent_path() / "missing.json");
  ASSERT_FALSE(corpus.ok());
  EXPECT_EQ(corpus.status().code(), StatusCode::kNotFound);
}

TEST(AccuracyCorpusTest, ACutIsFoundByAChainBreakWithinTwoFrames) {
  const std::vector<track::ChainBreak> breaks = {{102, ""}, {200, ""}, {303, ""}};
  const CutScore score = ScoreCuts({100, 300}, breaks, {});
  EXPECT_EQ(score.expected, 2);
  EXPECT_EQ(score.found, 1);         // 102 finds 100; 303 is 3 frames from 300
  EXPECT_EQ(score.other_breaks, 2);  // 200 and 303
  const CutScore none = ScoreCuts({}, breaks, {});
  EXPECT_EQ(none.expected, 0);
  EXPECT_EQ(none.found, 0);
  EXPECT_EQ(none.other_breaks, 3);
  EXPECT_EQ(ScoreCuts({50}, {}, {}).found, 0);
}

TEST(AccuracyCorpusTest, ATrackSeenOnBothSidesOfACutCrossesIt) {
  const auto track = [](int64_t first, int64_t last) {
    track::TargetTrack t;
    for (int64_t f = first; f <= last; ++f) {
      track::TargetObservation o;
      o.frame = f;
      t.observations.push_back(o);
    }
    return t;
  };
  // Ends just before the cut, starts at it, spans it, spans the other.
  const std::vector<track::TargetTrack> tracks = {track(10, 99), track(100, 150), track(90, 110),
                                                  track(250, 320)};
  EXPECT_EQ(ScoreCuts({100, 300}, {}, tracks).tracks_across, 2);
  EXPECT_EQ(ScoreCuts({}, {}, tracks).tracks_across, 0);
}

TEST(AccuracyCorpusTest, ATrackOnOverlayPixelsInHalfItsFramesCounts) {
  sim::Truth truth;
  truth.overlays.push_back({"logo", 0, 0, 100, 40});
  frontend::FrontEndResult result;
  const auto track = [](std::vector<Eigen::Vector2d> positions) {
    track::TargetTrack t;
    for (size_t i = 0; i < positions.size(); ++i) {
      track::TargetObservation o;
      o.frame = static_cast<int64_t>(i);
      o.position = positions[i];
      t.observations.push_back(o);
    }
    return t;
  };
  result.targets.push_back(track({{10, 10}, {20, 10}, {30, 12}}));      // on the logo throughout
  result.targets.push_back(track({{50, 30}, {300, 300}}));              // half its frames
  result.targets.push_back(track({{99, 39}, {400, 200}, {410, 200}}));  // a third
  result.targets.push_back(track({{100, 10}, {120, 10}}));              // beside it
  EXPECT_EQ(CountOverlayTracks(result, truth), 2);
  truth.overlays.clear();
  EXPECT_EQ(CountOverlayTracks(result, truth), 0);
}

TEST(AccuracyCorpusTest, FiguresPoolAsCountsAndSamples) {
  CorpusFigures a, b;
  a.cases = b.cases = 1;
  a.correct_tracks = 1, a.detected_tracks = 2;
  b.correct_tracks = 9, b.detected_tracks = 10;
  a.truth_targets = 0;  // nothing to find: no recall, rather than a recall of 1
  a.latencies_s = {0.2};
  b.latencies_s = {0.4, 0.6};
  a.mosaic_unit = b.mosaic_unit = CorpusFigures::MosaicUnit::kMetres;
  a.mosaic_key_frames = 1, a.mosaic_before_sq = 1 * 3.0 * 3.0, a.mosaic_after_sq = 1 * 1.0;
  b.mosaic_key_frames = 3, b.mosaic_before_sq = 3 * 1.0, b.mosaic_after_sq = 3 * 1.0;
  CorpusFigures sum;
  EXPECT_FALSE(sum.TrackPrecision());
  EXPECT_FALSE(sum.MosaicBeforeRms());
  sum.Add(a);
  EXPECT_FALSE(sum.TrackRecall());
  sum.Add(b);
  EXPECT_EQ(sum.cases, 2);
  EXPECT_DOUBLE_EQ(*sum.TrackPrecision(), 10.0 / 12.0);  // not (0.5 + 0.9) / 2
  EXPECT_DOUBLE_EQ(*sum.MedianLatency(), 0.4);
  EXPECT_DOUBLE_EQ(*sum.MosaicBeforeRms(), std::sqrt((9.0 + 3.0) / 4.0));
  EXPECT_DOUBLE_EQ(*sum.MosaicAfterRms(), 1.0);
  CorpusFigures pixels;
  pixels.mosaic_unit = CorpusFigures::MosaicUnit::kPixels;
  pixels.mosaic_key_frames = 2;
  sum.Add(pixels);
  EXPECT_EQ(sum.mosaic_unit, CorpusFigures::MosaicUnit::kMixed);
  EXPECT_FALSE(sum.MosaicAfterRms());
}

// A floor names each figure that falls short, with its counts; a figure with nothing to measure
// falls short; unset figures are not checked.
TEST(AccuracyCorpusTest, AFloorNamesEveryFigureThatFallsShort) {
  CorpusFigures f;
  f.detected_tracks = 20, f.correct_tracks = 18;  // precision 0.9
  f.truth_targets = 10, f.found_targets = 6;      // recall 0.6
  f.overlay_tracks = 1;
  f.cuts.expected = 2, f.cuts.found = 1, f.cuts.tracks_across = 0;
  EXPECT_TRUE(FloorShortfalls(CorpusFloor{}, f).empty());
  CorpusFloor met;
  met.track_precision = 0.9, met.track_recall = 0.6, met.overlay_tracks = 1;
  met.tracks_across_cuts = 0, met.cuts_found = 0.5;
  EXPECT_TRUE(FloorShortfalls(met, f).empty());
  met.false_tracks = 2;
  EXPECT_TRUE(FloorShortfalls(met, f).empty());
  CorpusFloor high = met;
  high.track_precision = 0.95, high.track_recall = 0.7, high.overlay_tracks = 0;
  high.cuts_found = 1, high.false_tracks = 1;
  const std::vector<std::string> short_of = FloorShortfalls(high, f);
  ASSERT_EQ(short_of.size(), 5u);
  EXPECT_EQ(short_of[0], "track precision 0.900 (18 of 20) is below its floor 0.950");
  EXPECT_EQ(short_of[1], "track recall 0.600 (6 of 10) is below its floor 0.700");
  EXPECT_EQ(short_of[2], "tracks on overlay pixels: 1, at most 0 allowed");
  EXPECT_EQ(short_of[3], "cuts found 0.500 (1 of 2) is below its floor 1.000");
  EXPECT_EQ(short_of[4], "false tracks: 2, at most 1 allowed");
  CorpusFigures nothing;
  const std::vector<std::string> none = FloorShortfalls(met, nothing);
  ASSERT_EQ(none.size(), 3u);
  EXPECT_EQ(none[0], "track precision: nothing to measure (floor 0.900)");
}

// The reduced corpus (floors.json): a short clip of each class of footage of issue 24 (frame
// rates down to 1 fps, an oblique orbit, a thermal polarity switch, burned-in overlays, a cut)
// over two reporting seeds, each condition held to its floor: precision and recall, no track on an
// overlay, every cut found and no track across one. About 2 minutes in a release build (every
// video simulated afresh); sanitizer builds skip it.
TEST(AccuracyCorpusTest, TheReducedCorpusMeetsItsFloors) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the reduced corpus is run in the release build";
#endif
  const StatusOr<Corpus> corpus = ReadCorpus(kCorpusDir / "floors.json");
  ASSERT_TRUE(corpus.ok()) << corpus.status().ToString();
  for (const CorpusCondition& condition : corpus->conditions) {
    EXPECT_FALSE(condition.floor.empty()) << condition.name;
    if (condition.simulation.overlay.any()) {
      EXPECT_EQ(condition.floor.overlay_tracks, 0) << condition.name;
    }
  }
  const std::vector<CorpusCase> cases = CorpusCases(*corpus, SeedSet::kReporting);
  ASSERT_EQ(cases.size(), corpus->conditions.size() * corpus->reporting_seeds.size());
  CorpusRunOptions options;
  options.cache_dir = saker::testing::MakeTempDir("saker-floors-cache");
  options.jobs = 2;
  const std::vector<CaseResult> results = RunCorpus(cases, options);
  std::printf("%s", CorpusReportText(results).c_str());
  const std::vector<std::string> shortfalls = CorpusFloorShortfalls(*corpus, results);
  std::string lines;
  for (const std::string& line : shortfalls) lines += "\n  " + line;
  EXPECT_TRUE(shortfalls.empty()) << "below the floors of benchmarks/corpus/floors.json:" << lines;
}

// The smoke manifest through RunCorpus twice: simulated, then from the cache, with the same
// figures. About 20 s in a release build; sanitizer builds skip it (the engine code it drives runs
// under the sanitizers in its own tests).
TEST(AccuracyCorpusTest, TheSmokeCorpusRunsEveryCaseAndTheSecondRunUsesTheCache) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the smoke corpus is run in the release build";
#endif
  const StatusOr<Corpus> corpus = ReadCorpus(kCorpusDir / "smoke.json");
  ASSERT_TRUE(corpus.ok()) << corpus.status().ToString();
  const std::vector<CorpusCase> cases = CorpusCases(*corpus, SeedSet::kAll);
  ASSERT_GE(cases.size(), 3u);
  const std::string of_n = "/" + std::to_string(cases.size()) + " ";
  const fs::path cache = saker::testing::MakeTempDir("saker-corpus-cache");
  // What a killed run leaves behind, removed before the run.
  const fs::path stale = cache / ".0000000000000000.part-999999999-0";
  fs::create_directories(stale);
  // And what one of an older version left.
  const fs::path stale_old = cache / ".tmp-0000000000000000-999999999-0";
  fs::create_directories(stale_old);

  CorpusRunOptions options;
  options.cache_dir = cache;
  options.jobs = 2;
  std::vector<std::string> progress;
  options.progress = [&](const std::string& line) { progress.push_back(line); };
  const std::vector<CaseResult> first = RunCorpus(cases, options);
  ASSERT_EQ(first.size(), cases.size());
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(stale_old));
  EXPECT_EQ(progress.size(), 2 * cases.size());  // started, done
  for (const std::string& line : progress) {
    EXPECT_NE(line.find(of_n), std::string::npos) << line;
  }

  int64_t cuts_expected = 0, overlays = 0;
  for (size_t i = 0; i < first.size(); ++i) {
    const CaseResult& r = first[i];
    SCOPED_TRACE(r.corpus_case.Name());
    ASSERT_TRUE(r.error.empty()) << r.error;
    EXPECT_EQ(r.corpus_case.Name(), cases[i].Name());
    EXPECT_TRUE(r.simulated);
    const CorpusFigures& f = r.figures;
    EXPECT_EQ(f.cases, 1);
    EXPECT_EQ(f.failed_cases, 0);
    EXPECT_GT(f.simulate_s, 0);
    EXPECT_GT(f.process_s, 0);
    // The counts hold together.
    EXPECT_GT(f.truth_targets, 0);
    EXPECT_LE(f.found_targets, f.truth_targets);
    EXPECT_LE(f.correct_tracks, f.detected_tracks);
    EXPECT_LE(f.paired_movers, f.truth_mover_frames);
    EXPECT_LE(f.paired_detections, f.detections);
    EXPECT_EQ(static_cast<int64_t>(f.latencies_s.size()), f.found_targets);
    EXPECT_LE(f.overlay_tracks, f.detected_tracks);
    EXPECT_GT(f.homography_errors_px.size(), 0u);
    EXPECT_GT(f.mosaic_key_frames, 0);
    EXPECT_LE(f.cuts.found, f.cuts.expected);
    // The cached video is the case's: its truth says so, and gives the cuts expected.
    const fs::path entry = cache / r.cache_key;
    EXPECT_TRUE(fs::exists(entry / "video.ts"));
    EXPECT_TRUE(fs::exists(entry / "options.json"));
    const StatusOr<sim::Truth> truth = sim::ReadTruth(entry / "video.truth.json");
    ASSERT_TRUE(truth.ok()) << truth.status().ToString();
    EXPECT_EQ(truth->generator, r.corpus_case.simulation.ToJson());
    EXPECT_EQ(static_cast<int64_t>(truth->frames.size()),
              std::llround(r.corpus_case.simulation.duration_s * r.corpus_case.simulation.fps));
    EXPECT_EQ(f.cuts.expected, static_cast<int64_t>(truth->CutFrames().size()));
    cuts_expected += f.cuts.expected;
    overlays += !truth->overlays.empty();
    // Geo-referenced by the KLV corners, in metres; without KLV, in pixels.
    const bool klv = r.corpus_case.simulation.metadata.every_n_frames > 0;
    EXPECT_EQ(f.mosaic_unit,
              klv ? CorpusFigures::MosaicUnit::kMetres : CorpusFigures::MosaicUnit::kPixels);
  }
  // The smoke manifest has a case with a cut and burned-in overlays, so both scores are exercised.
  EXPECT_GE(cuts_expected, 1);
  EXPECT_GE(overlays, 1);
  // One entry per case and no temporaries left.
  size_t entries = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(cache)) {
    ++entries;
    EXPECT_EQ(e.path().filename().string().rfind(".", 0), std::string::npos) << e.path();
  }
  EXPECT_EQ(entries, cases.size());

  // The report: a row per case, a summary per condition, the overall one; JSON that parses.
  const std::string text = CorpusReportText(first);
  for (const CaseResult& r : first) {
    EXPECT_NE(text.find(r.corpus_case.Name() + " "), std::string::npos) << text;
    EXPECT_NE(text.find("= " + r.corpus_case.condition + " (1 seed)"), std::string::npos) << text;
  }
  EXPECT_NE(text.find("= all (" + std::to_string(cases.size()) + " cases)"), std::string::npos)
      << text;
  const json report = json::parse(CorpusReportJson(*corpus, SeedSet::kAll, first).dump());
  ASSERT_EQ(report.at("cases").size(), cases.size());
  ASSERT_EQ(report.at("conditions").size(), corpus->conditions.size());
  int64_t truth_targets = 0;
  for (const json& c : report.at("cases")) {
    EXPECT_EQ(c.at("seed_set"), "reporting");
    truth_targets += c.at("figures").at("truth_targets").get<int64_t>();
  }
  EXPECT_EQ(report.at("overall").at("cases"), cases.size());
  EXPECT_EQ(report.at("overall").at("truth_targets"), truth_targets);
  for (const json& c : report.at("conditions")) {
    EXPECT_EQ(c.at("figures").at("mosaic").at("unit"), c.at("name") == "no-klv" ? "px" : "m");
  }

  // Again: nothing is simulated, and the figures are the same (the front end is deterministic).
  options.jobs = 1;
  const std::vector<CaseResult> second = RunCorpus(cases, options);
  ASSERT_EQ(second.size(), first.size());
  for (size_t i = 0; i < second.size(); ++i) {
    SCOPED_TRACE(second[i].corpus_case.Name());
    ASSERT_TRUE(second[i].error.empty()) << second[i].error;
    EXPECT_FALSE(second[i].simulated);
    EXPECT_EQ(second[i].cache_key, first[i].cache_key);
    EXPECT_EQ(second[i].figures.simulate_s, 0);
    EXPECT_EQ(second[i].figures.found_targets, first[i].figures.found_targets);
    EXPECT_EQ(second[i].figures.correct_tracks, first[i].figures.correct_tracks);
    EXPECT_EQ(second[i].figures.detected_tracks, first[i].figures.detected_tracks);
    EXPECT_EQ(second[i].figures.mosaic_key_frames, first[i].figures.mosaic_key_frames);
  }
  EXPECT_NE(CorpusReportText(second).find("cached"), std::string::npos);
}

}  // namespace
}  // namespace saker::bench
