#pragma once

// The accuracy corpus (docs/accuracy.md): a manifest lists conditions of simulated flight and the
// seeds (worlds) each is flown over; every (condition, seed) case is simulated once into a cache,
// then the front end, the mosaic and the mission's activity are measured against its truth, and
// the figures are summed per condition. saker-bench-accuracy prints them; its test runs the smoke
// manifest through the same code.

#include "core/eval/front_end_accuracy.h"
#include "core/frontend/front_end.h"
#include "core/sim/simulator.h"
#include "core/sim/truth.h"
#include "core/util/status.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace saker::bench {

inline constexpr const char* kCorpusFormat = "saker-accuracy-corpus";
inline constexpr int kCorpusVersion = 1;

// Which of the manifest's seeds to run. Defaults may be tuned on the tuning seeds only; the
// figures that docs and targets quote come from the reporting seeds.
enum class SeedSet { kTuning, kReporting, kAll };
std::optional<SeedSet> ParseSeedSet(const std::string& name);  // "tuning", "reporting", "all"

// How targets are scored, in seconds rather than frames so that a condition means the same at
// every frame rate; at 25 fps these are saker-cli evaluate's defaults (25 and 50 frames).
struct CorpusScoring {
  double min_speed_mps = 1.0;       // slowest truth target counted as moving
  double gate_px = 12;              // pairing distance (or half the target's length, if larger)
  double min_mover_s = 1.0;         // a sighting counts with this long moving in view...
  double max_sighting_gap_s = 2.0;  // ...and ends when out of view longer than this
  // In frames at `fps`; never fewer than kMinMoverFrames mover frames.
  eval::FrontEndEvaluationOptions ForFrameRate(double fps) const;
  static constexpr int kMinMoverFrames = 3;
};

// What a condition must reach, pooled over its cases (a manifest's `conditions[].floor`): the
// reduced corpus of the test suite holds the front end to these (benchmarks/corpus/floors.json).
// Unset figures are not checked.
struct CorpusFloor {
  std::optional<double> track_precision;      // at least
  std::optional<double> track_recall;         // at least
  std::optional<int64_t> overlay_tracks;      // at most (0: no track on an overlay)
  std::optional<double> cuts_found;           // at least this fraction of the cuts found
  std::optional<int64_t> tracks_across_cuts;  // at most
  std::optional<int64_t> false_tracks;        // at most: target tracks paired with no target
  bool empty() const {
    return !track_precision && !track_recall && !overlay_tracks && !cuts_found &&
           !tracks_across_cuts && !false_tracks;
  }
};

struct CorpusCondition {
  std::string name;
  std::string description;
  sim::SimulationOptions simulation;  // defaults, then the condition's options; seed and output
                                      // paths are set per case
  CorpusScoring scoring;
  CorpusFloor floor;
  // Why the condition cannot run here (its orthophoto is in the test data folder, which is
  // absent); empty when it can. CorpusCases leaves such conditions out.
  std::string unavailable;
};

// A manifest read and checked: every condition's options are valid simulation options.
struct Corpus {
  std::filesystem::path manifest;
  std::vector<uint64_t> tuning_seeds, reporting_seeds;
  std::vector<CorpusCondition> conditions;
};

// One condition flown over one seed.
struct CorpusCase {
  std::string condition;
  uint64_t seed = 0;
  bool tuning = false;                // a tuning seed, else a reporting one
  sim::SimulationOptions simulation;  // output paths empty: the cache gives them
  eval::FrontEndEvaluationOptions evaluation;
  std::string Name() const { return condition + "/" + std::to_string(seed); }
};

// A `ground_image` that starts with "$SAKER_TEST_DATA/" names a file of the real third-party test
// data: the folder of the environment variable SAKER_TEST_DATA, else `default_test_data` (the
// shared data folder beside the source tree). Other relative paths are relative to the manifest.
inline constexpr const char* kTestDataPrefix = "$SAKER_TEST_DATA/";
void SetDefaultTestDataDir(const std::filesystem::path& default_test_data);

// Reads a manifest (format in docs/accuracy.md). Errors name the manifest and the key at fault
// ("corpus.json: conditions[3] "nadir-2fps": options: unknown simulation option 'flight.alt'").
StatusOr<Corpus> ReadCorpus(const std::filesystem::path& manifest);

// The cases of `seeds` for the conditions whose name contains `only` (every condition when
// empty) that are available here (CorpusCondition::unavailable), condition by condition in manifest
// order, seeds in manifest order.
std::vector<CorpusCase> CorpusCases(const Corpus& corpus, SeedSet seeds,
                                    const std::string& only = "");

// A simulated video in the cache: <cache>/<key>/video.ts, its truth video.truth.json and the
// options that made it, options.json. The key hashes SimulationOptions::ToJson() (which holds the
// simulator's version) and an orthophoto ground's bytes. An entry is made in a temporary
// directory and renamed into place whole, so an interrupted run never leaves a partial entry and
// two runs making the same entry at once both end with a good one.
struct CachedVideo {
  std::string key;
  std::filesystem::path video, truth;
  bool simulated = false;  // made now (else found in the cache)
  double simulate_s = 0;   // when made now
};
StatusOr<std::string> SimulationKey(const sim::SimulationOptions& options);
StatusOr<CachedVideo> SimulateCached(const sim::SimulationOptions& options,
                                     const std::filesystem::path& cache_dir);

// Detected target tracks whose observations lie on burned-in overlay pixels in at least half of
// their frames: false by construction (a logo, HUD text).
int64_t CountOverlayTracks(const frontend::FrontEndResult& result, const sim::Truth& truth);

// Chain breaks against the truth's cuts: a cut at frame c is found when the front end broke the
// chain at a frame within `tolerance` of c; other breaks are those near no cut. A target track
// seen before a cut and after it (first frame < c <= last frame) crosses it: it joins two
// scenes, and no track may.
struct CutScore {
  int64_t expected = 0, found = 0, other_breaks = 0;
  int64_t tracks_across = 0;
};
CutScore ScoreCuts(const std::vector<int64_t>& cut_frames,
                   const std::vector<track::ChainBreak>& breaks,
                   const std::vector<track::TargetTrack>& targets, int64_t tolerance = 2);

// What a row of the report shows, as sums and samples, so that several cases add up: ratios
// come from summed counts and quantiles from the pooled samples, never from averaging cases.
struct CorpusFigures {
  int cases = 0, failed_cases = 0;
  // Target tracks (eval::DetectionAccuracy, every class).
  int64_t truth_targets = 0, found_targets = 0;
  int64_t detected_tracks = 0, correct_tracks = 0;
  int64_t truth_mover_frames = 0, paired_movers = 0;
  int64_t detections = 0, paired_detections = 0;
  std::vector<double> latencies_s;  // per found sighting
  int64_t overlay_tracks = 0;
  // The overlay masks (eval::OverlayMaskAccuracy) summed over frames: masked cells that lie on no
  // overlay, as frames x fraction of the image.
  int64_t frames = 0;
  double mask_off_overlay_frames = 0;
  // Frames whose motion thresholds the video's own noise raised (FrontEndResult::noise).
  int64_t noisy_frames = 0;
  std::vector<double> speed_relative_errors;  // per matched track compared on speed
  std::vector<double> homography_errors_px;   // per frame with an estimate
  int64_t homography_failed = 0;
  // Mosaic key frame corners before and after adjustment: geo-referenced mosaics in map metres
  // (nothing removed), others in the key frames' pixels after the gauge fit (MosaicAccuracy).
  // Sums of key frames x squared RMS, so that the pooled RMS weighs every key frame alike.
  enum class MosaicUnit { kNone, kMetres, kPixels, kMixed };
  MosaicUnit mosaic_unit = MosaicUnit::kNone;
  int64_t mosaic_key_frames = 0;
  double mosaic_before_sq = 0, mosaic_after_sq = 0;
  CutScore cuts;
  double simulate_s = 0, process_s = 0;

  void Add(const CorpusFigures& other);
  // Pooled figures; nullopt where nothing was counted.
  std::optional<double> TrackPrecision() const;
  std::optional<double> TrackRecall() const;
  std::optional<double> FramePrecision() const;
  std::optional<double> FrameRecall() const;
  std::optional<double> MedianLatency() const;
  std::optional<double> SpeedError(double quantile) const;  // relative, as the activity's
  std::optional<double> HomographyMedian() const;
  std::optional<double> MosaicBeforeRms() const;
  std::optional<double> MosaicAfterRms() const;
  // The mean fraction of the image wrongly masked as overlay; nullopt without frames.
  std::optional<double> MaskOffOverlay() const;
};

struct CaseResult {
  CorpusCase corpus_case;
  std::string error;  // empty: it ran
  std::string cache_key;
  bool simulated = false;
  CorpusFigures figures;
  // `saker-cli evaluate --details`'s text for the case (missed sightings, false tracks): what
  // `saker-bench-accuracy --details DIR` writes; empty when the case failed.
  std::string details;
};

// Simulates (or takes from the cache) and measures one case with the front end's `front_end`
// options. Failures are recorded in the result, so one broken case does not stop a corpus.
CaseResult RunCase(const CorpusCase& corpus_case, const std::filesystem::path& cache_dir,
                   const frontend::FrontEndOptions& front_end = {});

struct CorpusRunOptions {
  std::filesystem::path cache_dir;
  frontend::FrontEndOptions front_end;  // the engine's defaults unless a run overrides them
  int jobs = 1;                         // cases at once (each is multi-threaded already)
  // Called with a line of progress (case k of n, its name, elapsed time), from any thread but
  // one call at a time.
  std::function<void(const std::string&)> progress;
};

// Runs every case, `jobs` at a time; results in the order of `cases`. Removes temporaries that
// killed runs left in the cache first.
std::vector<CaseResult> RunCorpus(const std::vector<CorpusCase>& cases,
                                  const CorpusRunOptions& options);

// Where `figures` (a condition's, pooled) fall short of `floor`: one line per figure, e.g.
// "track recall 0.412 (7 of 17) is below its floor 0.500"; empty when every floor is met. A
// figure with nothing to measure (no target, no cut) fails its floor.
std::vector<std::string> FloorShortfalls(const CorpusFloor& floor, const CorpusFigures& figures);

struct CaseResult;
// FloorShortfalls of every condition of `corpus` that has a floor and cases in `results`, pooled
// over its cases, each line prefixed with the condition's name; a failed case is a shortfall too.
std::vector<std::string> CorpusFloorShortfalls(const Corpus& corpus,
                                               const std::vector<CaseResult>& results);

// The report: a row per case, a summary per condition and an overall one.
std::string CorpusReportText(const std::vector<CaseResult>& results);
nlohmann::json CorpusReportJson(const Corpus& corpus, SeedSet seeds,
                                const std::vector<CaseResult>& results);

}  // namespace saker::bench
