#include "benchmarks/accuracy_corpus.h"

#include "core/eval/video_evaluation.h"
#include "core/util/durable_file.h"
#include "core/util/fingerprint.h"
#include "core/util/statistics.h"
#include "core/util/timer.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <thread>

namespace saker::bench {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kVideoName = "video.ts";
constexpr const char* kTruthName = "video.truth.json";
constexpr const char* kOptionsName = "options.json";
constexpr const char* kTemporaryPrefix = ".tmp-";  // older versions' temporaries

fs::path& DefaultTestDataDir() {
  static fs::path dir;
  return dir;
}

// The real third-party test data: $SAKER_TEST_DATA, else the default given by the executable.
fs::path TestDataDir() {
  if (const char* env = std::getenv("SAKER_TEST_DATA"); env != nullptr && *env != '\0') return env;
  return DefaultTestDataDir();
}

// ---- The manifest ----------------------------------------------------------------------------

// Reads the manifest's parts, each error naming the manifest and where in it the problem is.
class ManifestReader {
 public:
  explicit ManifestReader(fs::path manifest) : manifest_(std::move(manifest)) {}

  Status Error(const std::string& where, const std::string& problem) const {
    return InvalidArgumentError(manifest_.string() + ": " + where + ": " + problem);
  }

  // Fails on a key of `object` not in `known`.
  Status CheckKeys(const json& object, const std::string& where,
                   const std::set<std::string>& known) const {
    for (const auto& item : object.items()) {
      if (known.count(item.key()) == 0) {
        std::string list;
        for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
        return Error(where, "unknown key '" + item.key() + "' (known: " + list + ")");
      }
    }
    return Status::Ok();
  }

  StatusOr<std::vector<uint64_t>> Seeds(const json& root, const char* key) const {
    const auto it = root.find(key);
    if (it == root.end()) return Error(key, "missing (a list of seeds, possibly empty)");
    if (!it->is_array()) return Error(key, "must be a list of seeds, got " + it->dump());
    std::vector<uint64_t> seeds;
    for (const json& seed : *it) {
      if (!seed.is_number_unsigned()) {
        return Error(key, "seeds must be whole numbers >= 0, got " + seed.dump());
      }
      const uint64_t value = seed.get<uint64_t>();
      if (std::find(seeds.begin(), seeds.end(), value) != seeds.end()) {
        return Error(key, "seed " + std::to_string(value) + " is listed twice");
      }
      seeds.push_back(value);
    }
    return seeds;
  }

  // Simulation options over `options`; seeds come from the seed lists only.
  Status ApplyOptions(const json& overrides, const std::string& where,
                      sim::SimulationOptions* options) const {
    if (!overrides.is_object()) return Error(where, "must be an object of simulation options");
    if (overrides.contains("seed")) {
      return Error(where,
                   "'seed' is not an option here: seeds come from tuning_seeds and "
                   "reporting_seeds");
    }
    const Status applied = sim::ApplyOptionsJson(overrides, options);
    if (!applied.ok()) return Error(where, applied.message());
    // An orthophoto of the test data, or named relative to the manifest, so that the corpus can
    // carry its own.
    const std::string image = options->ground_image.string();
    if (image.rfind(kTestDataPrefix, 0) == 0) {
      options->ground_image = TestDataDir() / image.substr(std::strlen(kTestDataPrefix));
    } else if (!options->ground_image.empty() && options->ground_image.is_relative()) {
      options->ground_image = fs::absolute(manifest_).parent_path() / options->ground_image;
    }
    return Status::Ok();
  }

  Status ApplyScoring(const json& overrides, const std::string& where,
                      CorpusScoring* scoring) const {
    if (!overrides.is_object()) return Error(where, "must be an object");
    const std::map<std::string, double*> fields = {
        {"min_speed_mps", &scoring->min_speed_mps},
        {"gate_px", &scoring->gate_px},
        {"min_mover_s", &scoring->min_mover_s},
        {"max_sighting_gap_s", &scoring->max_sighting_gap_s}};
    for (const auto& [key, value] : overrides.items()) {
      const auto field = fields.find(key);
      if (field == fields.end()) {
        return Error(where, "unknown key '" + key +
                                "' (known: gate_px, max_sighting_gap_s, min_mover_s, "
                                "min_speed_mps)");
      }
      if (!value.is_number() || value.get<double>() < 0) {
        return Error(where + "." + key, "must be a number >= 0, got " + value.dump());
      }
      *field->second = value.get<double>();
    }
    if (!(scoring->gate_px > 0)) return Error(where + ".gate_px", "must be above 0");
    return Status::Ok();
  }

  Status ReadFloor(const json& object, const std::string& where, CorpusFloor* floor) const {
    if (!object.is_object()) return Error(where, "must be an object");
    SAKER_RETURN_IF_ERROR(CheckKeys(object, where,
                                    {"track_precision", "track_recall", "overlay_tracks",
                                     "cuts_found", "tracks_across_cuts", "false_tracks"}));
    for (const auto& [key, value] : object.items()) {
      const std::string at = where + "." + key;
      if (key == "overlay_tracks" || key == "tracks_across_cuts" || key == "false_tracks") {
        if (!value.is_number_unsigned()) {
          return Error(at, "must be a whole number >= 0 (at most), got " + value.dump());
        }
        (key == "overlay_tracks"       ? floor->overlay_tracks
         : key == "tracks_across_cuts" ? floor->tracks_across_cuts
                                       : floor->false_tracks) = value.get<int64_t>();
        continue;
      }
      if (!value.is_number() || value.get<double>() < 0 || value.get<double>() > 1) {
        return Error(at, "must be a fraction from 0 to 1 (at least), got " + value.dump());
      }
      const double fraction = value.get<double>();
      if (key == "track_precision") floor->track_precision = fraction;
      if (key == "track_recall") floor->track_recall = fraction;
      if (key == "cuts_found") floor->cuts_found = fraction;
    }
    return Status::Ok();
  }

 private:
  fs::path manifest_;
};

// ---- The cache --------------------------------------------------------------------------------

// A complete entry made from exactly these options.
bool EntryMatches(const fs::path& entry, const json& options) {
  std::error_code ec;
  if (!fs::is_regular_file(entry / kVideoName, ec) || !fs::is_regular_file(entry / kTruthName, ec))
    return false;
  std::ifstream in(entry / kOptionsName);
  if (!in) return false;
  const json recorded = json::parse(in, nullptr, /*allow_exceptions=*/false);
  return recorded == options;
}

// Removes temporaries of runs that are no longer alive: ".<key>.part-<pid>-<n>" (a
// FileReplacement's) and, from older versions, ".tmp-<key>-<pid>-<n>".
void RemoveStaleTemporaries(const fs::path& cache_dir) {
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(cache_dir, ec)) {
    const std::string name = entry.path().filename().string();
    size_t pid_start = 0;  // after ".<16 hex>.part-" or ".tmp-<16 hex>-"
    if (name.rfind(kTemporaryPrefix, 0) == 0) {
      pid_start = std::string(kTemporaryPrefix).size() + 17;
    } else if (name.size() > 1 + 16 && name[0] == '.' && name.compare(17, 6, ".part-") == 0) {
      pid_start = 1 + 16 + 6;
    } else {
      continue;
    }
    if (name.size() <= pid_start) continue;
    const long pid = std::strtol(name.c_str() + pid_start, nullptr, 10);
    if (pid <= 0 || (kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH)) {
      fs::remove_all(entry.path(), ec);
    }
  }
}

// ---- Figures ------------------------------------------------------------------------------------

std::optional<double> Ratio(int64_t numerator, int64_t denominator) {
  if (denominator <= 0) return std::nullopt;
  return static_cast<double>(numerator) / static_cast<double>(denominator);
}

std::optional<double> PooledRms(double sum_sq, int64_t count, CorpusFigures::MosaicUnit unit) {
  if (count <= 0 || unit == CorpusFigures::MosaicUnit::kMixed ||
      unit == CorpusFigures::MosaicUnit::kNone)
    return std::nullopt;
  return std::sqrt(sum_sq / static_cast<double>(count));
}

const char* MosaicUnitName(CorpusFigures::MosaicUnit unit) {
  switch (unit) {
    case CorpusFigures::MosaicUnit::kMetres:
      return "m";
    case CorpusFigures::MosaicUnit::kPixels:
      return "px";
    case CorpusFigures::MosaicUnit::kMixed:
      return "mixed";
    case CorpusFigures::MosaicUnit::kNone:
      break;
  }
  return "none";
}

CorpusFigures FiguresOf(const eval::VideoEvaluation& e, const sim::Truth& truth) {
  CorpusFigures f;
  f.cases = 1;
  const eval::DetectionAccuracy& t = e.detection.targets;
  f.truth_targets = t.truth_targets;
  f.found_targets = t.found_targets;
  f.detected_tracks = t.detected_tracks;
  f.correct_tracks = t.correct_tracks;
  f.truth_mover_frames = t.truth_mover_frames;
  f.paired_movers = t.paired;
  f.detections = t.detections;
  f.paired_detections = t.paired_detections;
  for (const eval::SightingOutcome& s : t.sightings) {
    if (s.found) f.latencies_s.push_back(s.latency_s);
  }
  f.overlay_tracks = CountOverlayTracks(e.front_end, truth);
  f.frames = static_cast<int64_t>(truth.frames.size());
  f.noisy_frames = std::max(e.front_end.noise.feature_frames, e.front_end.noise.change_frames);
  f.mask_off_overlay_frames =
      e.detection.overlay_mask.off_overlay_fraction * static_cast<double>(f.frames);
  f.speed_relative_errors = e.activity.speed_relative_errors;
  f.homography_errors_px = e.detection.homography.errors_px;
  f.homography_failed = e.detection.homography.failed;
  const eval::MosaicAccuracy& m = e.mosaic;
  if (m.key_frames > 0) {
    const bool metres = m.geo_referenced && m.before_absolute && m.after_absolute;
    f.mosaic_unit =
        metres ? CorpusFigures::MosaicUnit::kMetres : CorpusFigures::MosaicUnit::kPixels;
    const double before = metres ? m.before_absolute->rms_m : m.before.rms_px;
    const double after = metres ? m.after_absolute->rms_m : m.after.rms_px;
    f.mosaic_key_frames = m.key_frames;
    f.mosaic_before_sq = static_cast<double>(m.key_frames) * before * before;
    f.mosaic_after_sq = static_cast<double>(m.key_frames) * after * after;
  }
  f.cuts = ScoreCuts(truth.CutFrames(), e.front_end.breaks, e.front_end.targets);
  return f;
}

json Optional(const std::optional<double>& value) { return value ? json(*value) : json(nullptr); }

json FiguresToJson(const CorpusFigures& f) {
  return {{"cases", f.cases},
          {"failed_cases", f.failed_cases},
          {"track_precision", Optional(f.TrackPrecision())},
          {"correct_tracks", f.correct_tracks},
          {"detected_tracks", f.detected_tracks},
          {"track_recall", Optional(f.TrackRecall())},
          {"found_targets", f.found_targets},
          {"truth_targets", f.truth_targets},
          {"frame_precision", Optional(f.FramePrecision())},
          {"paired_detections", f.paired_detections},
          {"detections", f.detections},
          {"frame_recall", Optional(f.FrameRecall())},
          {"paired_mover_frames", f.paired_movers},
          {"truth_mover_frames", f.truth_mover_frames},
          {"median_latency_s", Optional(f.MedianLatency())},
          {"overlay_tracks", f.overlay_tracks},
          {"mask_off_overlay", Optional(f.MaskOffOverlay())},
          {"noisy_frames", f.noisy_frames},
          {"speed",
           {{"compared", f.speed_relative_errors.size()},
            {"median_relative_error", Optional(f.SpeedError(0.5))},
            {"p90_relative_error", Optional(f.SpeedError(0.9))}}},
          {"homography",
           {{"frames", f.homography_errors_px.size()},
            {"failed", f.homography_failed},
            {"median_px", Optional(f.HomographyMedian())}}},
          {"mosaic",
           {{"key_frames", f.mosaic_key_frames},
            {"unit", MosaicUnitName(f.mosaic_unit)},
            {"before_rms", Optional(f.MosaicBeforeRms())},
            {"after_rms", Optional(f.MosaicAfterRms())}}},
          {"cuts",
           {{"expected", f.cuts.expected},
            {"found", f.cuts.found},
            {"other_breaks", f.cuts.other_breaks},
            {"tracks_across", f.cuts.tracks_across}}},
          {"time", {{"simulate_s", f.simulate_s}, {"process_s", f.process_s}}}};
}

// ---- The text report ----------------------------------------------------------------------------

std::string Format(const char* format, double value) {
  char text[32];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}
std::string FormatOr(const char* format, const std::optional<double>& value) {
  return value ? Format(format, *value) : "-";
}
std::string Counts(int64_t numerator, int64_t denominator) {
  return std::to_string(numerator) + "/" + std::to_string(denominator);
}
std::string Pad(const std::string& text, size_t width, bool left = false) {
  if (text.size() >= width) return text;
  const std::string fill(width - text.size(), ' ');
  return left ? text + fill : fill + text;
}

// Column titles, in the order Cells() gives the cells.
const std::vector<std::string>& Titles() {
  // clang-format off
  static const std::vector<std::string> titles = {
      "track P", "ok/all", "track R", "found/all", "frame P", "frame R", "lat s", "ovl",
      "mask off %", "noisy %", "speed %", "H px", "mosaic before > after", "cuts", "x-cut",
      "other", "sim s", "proc s"};
  // clang-format on
  return titles;
}

std::vector<std::string> Cells(const CorpusFigures& f, bool cached) {
  std::string speed = "-";
  if (const auto median = f.SpeedError(0.5)) {
    speed = Format("%.0f", 100 * *median) + "/" + Format("%.0f", 100 * *f.SpeedError(0.9));
  }
  std::string mosaic = "-";
  if (const auto before = f.MosaicBeforeRms()) {
    mosaic = Format("%.2f", *before) + " > " + Format("%.2f", *f.MosaicAfterRms()) + " " +
             MosaicUnitName(f.mosaic_unit);
  } else if (f.mosaic_unit == CorpusFigures::MosaicUnit::kMixed) {
    mosaic = "(m and px)";
  }
  return {FormatOr("%.3f", f.TrackPrecision()),
          Counts(f.correct_tracks, f.detected_tracks),
          FormatOr("%.3f", f.TrackRecall()),
          Counts(f.found_targets, f.truth_targets),
          FormatOr("%.3f", f.FramePrecision()),
          FormatOr("%.3f", f.FrameRecall()),
          FormatOr("%.2f", f.MedianLatency()),
          std::to_string(f.overlay_tracks),
          FormatOr("%.2f",
                   f.MaskOffOverlay() ? std::optional(100 * *f.MaskOffOverlay()) : std::nullopt),
          f.frames > 0 ? Format("%.0f", 100.0 * static_cast<double>(f.noisy_frames) /
                                            static_cast<double>(f.frames))
                       : "-",
          speed,
          FormatOr("%.3f", f.HomographyMedian()),
          mosaic,
          Counts(f.cuts.found, f.cuts.expected),
          std::to_string(f.cuts.tracks_across),
          std::to_string(f.cuts.other_breaks),
          cached ? "cached" : Format("%.1f", f.simulate_s),
          Format("%.1f", f.process_s)};
}

// A table row: a label and its cells, or a label and an error.
struct Row {
  std::string label;
  std::vector<std::string> cells;
  std::string error;
};

std::string FormatTable(const std::vector<Row>& rows) {
  size_t label_width = 0;
  std::vector<size_t> widths(Titles().size(), 0);
  for (const Row& row : rows) {
    label_width = std::max(label_width, row.label.size());
    for (size_t i = 0; i < row.cells.size(); ++i)
      widths[i] = std::max(widths[i], row.cells[i].size());
  }
  std::string text;
  for (const Row& row : rows) {
    text += Pad(row.label, label_width, /*left=*/true);
    if (!row.error.empty()) text += "  FAILED: " + row.error;
    for (size_t i = 0; i < row.cells.size(); ++i) text += "  " + Pad(row.cells[i], widths[i]);
    text += "\n";
  }
  return text;
}

// Condition names in order of first appearance, with their results.
std::vector<std::pair<std::string, std::vector<const CaseResult*>>> ByCondition(
    const std::vector<CaseResult>& results) {
  std::vector<std::pair<std::string, std::vector<const CaseResult*>>> groups;
  for (const CaseResult& r : results) {
    auto it = std::find_if(groups.begin(), groups.end(),
                           [&](const auto& g) { return g.first == r.corpus_case.condition; });
    if (it == groups.end()) it = groups.insert(groups.end(), {r.corpus_case.condition, {}});
    it->second.push_back(&r);
  }
  return groups;
}

std::string Elapsed(double seconds) {
  char text[32];
  std::snprintf(text, sizeof(text), "%d:%02d", static_cast<int>(seconds) / 60,
                static_cast<int>(seconds) % 60);
  return text;
}

// RunCase's work: the video from the cache (or simulated into it), then the evaluation.
Status MeasureCase(const fs::path& cache_dir, const frontend::FrontEndOptions& front_end,
                   CaseResult* result) {
  SAKER_ASSIGN_OR_RETURN(const CachedVideo cached,
                         SimulateCached(result->corpus_case.simulation, cache_dir));
  result->cache_key = cached.key;
  result->simulated = cached.simulated;
  const Stopwatch start;
  SAKER_ASSIGN_OR_RETURN(const sim::Truth truth, sim::ReadTruth(cached.truth));
  eval::VideoEvaluationOptions options;
  options.front_end = front_end;
  options.evaluation = result->corpus_case.evaluation;
  options.experiments = false;
  SAKER_ASSIGN_OR_RETURN(const eval::VideoEvaluation evaluation,
                         eval::EvaluateVideo(cached.video.string(), truth, options));
  result->figures = FiguresOf(evaluation, truth);
  result->details = eval::VideoEvaluationToText(evaluation, /*details=*/true);
  result->figures.process_s = start.ElapsedSeconds();
  result->figures.simulate_s = cached.simulate_s;
  return Status::Ok();
}

}  // namespace

std::optional<SeedSet> ParseSeedSet(const std::string& name) {
  if (name == "tuning") return SeedSet::kTuning;
  if (name == "reporting") return SeedSet::kReporting;
  if (name == "all") return SeedSet::kAll;
  return std::nullopt;
}

eval::FrontEndEvaluationOptions CorpusScoring::ForFrameRate(double fps) const {
  eval::FrontEndEvaluationOptions options;
  options.min_speed_mps = min_speed_mps;
  options.gate_px = gate_px;
  options.min_mover_frames =
      std::max(kMinMoverFrames, static_cast<int>(std::lround(min_mover_s * fps)));
  options.max_sighting_gap_frames = static_cast<int>(std::lround(max_sighting_gap_s * fps));
  return options;
}

StatusOr<Corpus> ReadCorpus(const fs::path& manifest) {
  std::ifstream in(manifest);
  if (!in) return NotFoundError(manifest.string() + ": cannot read the corpus manifest");
  json root;
  try {
    root = json::parse(in);
  } catch (const json::parse_error& e) {
    return InvalidDataError(manifest.string() + ": not JSON: " + e.what());
  }
  const ManifestReader reader(manifest);
  if (!root.is_object()) return reader.Error("top level", "must be an object");
  SAKER_RETURN_IF_ERROR(
      reader.CheckKeys(root, "top level",
                       {"format", "version", "description", "defaults", "evaluation",
                        "tuning_seeds", "reporting_seeds", "conditions"}));
  if (root.value("format", json()) != kCorpusFormat) {
    return reader.Error("format", std::string("must be \"") + kCorpusFormat + "\"");
  }
  if (root.value("version", json()) != kCorpusVersion) {
    return reader.Error("version", "must be " + std::to_string(kCorpusVersion) +
                                       " (this build reads version " +
                                       std::to_string(kCorpusVersion) + ")");
  }
  Corpus corpus;
  corpus.manifest = manifest;
  SAKER_ASSIGN_OR_RETURN(corpus.tuning_seeds, reader.Seeds(root, "tuning_seeds"));
  SAKER_ASSIGN_OR_RETURN(corpus.reporting_seeds, reader.Seeds(root, "reporting_seeds"));
  for (uint64_t seed : corpus.reporting_seeds) {
    if (std::find(corpus.tuning_seeds.begin(), corpus.tuning_seeds.end(), seed) !=
        corpus.tuning_seeds.end()) {
      return reader.Error("reporting_seeds", "seed " + std::to_string(seed) +
                                                 " is a tuning seed too; the two sets must be "
                                                 "apart");
    }
  }
  if (corpus.tuning_seeds.empty() && corpus.reporting_seeds.empty()) {
    return reader.Error("tuning_seeds", "no seeds at all");
  }
  sim::SimulationOptions defaults;
  if (root.contains("defaults")) {
    SAKER_RETURN_IF_ERROR(reader.ApplyOptions(root["defaults"], "defaults", &defaults));
  }
  CorpusScoring scoring;
  if (root.contains("evaluation")) {
    SAKER_RETURN_IF_ERROR(reader.ApplyScoring(root["evaluation"], "evaluation", &scoring));
  }
  const json& conditions = root.value("conditions", json());
  if (!conditions.is_array() || conditions.empty()) {
    return reader.Error("conditions", "must be a non-empty list of conditions");
  }
  for (size_t i = 0; i < conditions.size(); ++i) {
    const json& c = conditions[i];
    std::string where = "conditions[" + std::to_string(i) + "]";
    if (!c.is_object()) return reader.Error(where, "must be an object");
    const json name = c.value("name", json());
    if (!name.is_string() || name.get<std::string>().empty()) {
      return reader.Error(where, "needs a \"name\"");
    }
    CorpusCondition condition;
    condition.name = name.get<std::string>();
    where += " \"" + condition.name + "\"";
    for (char ch : condition.name) {
      if (!std::isalnum(static_cast<unsigned char>(ch)) &&
          std::string("-_.+").find(ch) == std::string::npos) {
        return reader.Error(where, "a name may hold letters, digits and - _ . + only");
      }
    }
    for (const CorpusCondition& other : corpus.conditions) {
      if (other.name == condition.name) return reader.Error(where, "a second condition so named");
    }
    SAKER_RETURN_IF_ERROR(
        reader.CheckKeys(c, where, {"name", "description", "options", "evaluation", "floor"}));
    const json description = c.value("description", json(""));
    if (!description.is_string()) return reader.Error(where + ".description", "must be text");
    condition.description = description.get<std::string>();
    condition.simulation = defaults;
    if (c.contains("options")) {
      SAKER_RETURN_IF_ERROR(
          reader.ApplyOptions(c["options"], where + ".options", &condition.simulation));
    }
    sim::SimulationOptions check = condition.simulation;
    check.output = "case.ts";
    if (const Status valid = check.Validate(); !valid.ok()) {
      return reader.Error(where + ".options", valid.message());
    }
    if (!condition.simulation.ground_image.empty() &&
        !fs::exists(condition.simulation.ground_image)) {
      condition.unavailable = "its ground image " + condition.simulation.ground_image.string() +
                              " is missing (the real test data: set SAKER_TEST_DATA)";
    }
    condition.scoring = scoring;
    if (c.contains("evaluation")) {
      SAKER_RETURN_IF_ERROR(
          reader.ApplyScoring(c["evaluation"], where + ".evaluation", &condition.scoring));
    }
    if (c.contains("floor")) {
      SAKER_RETURN_IF_ERROR(reader.ReadFloor(c["floor"], where + ".floor", &condition.floor));
    }
    corpus.conditions.push_back(std::move(condition));
  }
  return corpus;
}

void SetDefaultTestDataDir(const std::filesystem::path& default_test_data) {
  DefaultTestDataDir() = default_test_data;
}

std::vector<CorpusCase> CorpusCases(const Corpus& corpus, SeedSet seeds, const std::string& only) {
  std::vector<std::pair<uint64_t, bool>> chosen;  // seed, tuning
  if (seeds != SeedSet::kReporting) {
    for (uint64_t s : corpus.tuning_seeds) chosen.emplace_back(s, true);
  }
  if (seeds != SeedSet::kTuning) {
    for (uint64_t s : corpus.reporting_seeds) chosen.emplace_back(s, false);
  }
  std::vector<CorpusCase> cases;
  for (const CorpusCondition& condition : corpus.conditions) {
    if (condition.name.find(only) == std::string::npos || !condition.unavailable.empty()) continue;
    for (const auto& [seed, tuning] : chosen) {
      CorpusCase c;
      c.condition = condition.name;
      c.seed = seed;
      c.tuning = tuning;
      c.simulation = condition.simulation;
      c.simulation.seed = seed;
      c.evaluation = condition.scoring.ForFrameRate(c.simulation.fps);
      cases.push_back(std::move(c));
    }
  }
  return cases;
}

StatusOr<std::string> SimulationKey(const sim::SimulationOptions& options) {
  const std::string text = options.ToJson().dump();
  uint64_t hash = Fnv1a(text.data(), text.size());
  if (!options.ground_image.empty()) {
    std::ifstream in(options.ground_image, std::ios::binary);
    if (!in) return NotFoundError(options.ground_image.string() + ": cannot read the ground image");
    std::vector<char> buffer(1 << 20);
    while (in) {
      in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
      hash = Fnv1a(buffer.data(), static_cast<size_t>(in.gcount()), hash);
    }
  }
  char key[17];
  std::snprintf(key, sizeof(key), "%016llx", static_cast<unsigned long long>(hash));
  return std::string(key);
}

StatusOr<CachedVideo> SimulateCached(const sim::SimulationOptions& options,
                                     const fs::path& cache_dir) {
  CachedVideo cached;
  SAKER_ASSIGN_OR_RETURN(cached.key, SimulationKey(options));
  const fs::path entry = cache_dir / cached.key;
  cached.video = entry / kVideoName;
  cached.truth = entry / kTruthName;
  const json recorded = options.ToJson();
  if (EntryMatches(entry, recorded)) return cached;

  std::error_code ec;
  fs::create_directories(cache_dir, ec);
  if (ec) return IoError(cache_dir.string() + ": cannot make the cache folder: " + ec.message());
  // The entry is made whole in a temporary folder and renamed into place, never over another.
  FileReplacement replacement(entry.string(), {.overwrite = false});
  const fs::path temporary = replacement.temporary();
  fs::create_directory(temporary, ec);
  if (ec) return IoError(temporary.string() + ": cannot make a folder: " + ec.message());

  sim::SimulationOptions simulation = options;
  simulation.output = temporary / kVideoName;
  simulation.truth = temporary / kTruthName;
  const Stopwatch start;
  const StatusOr<sim::SimulationSummary> summary = sim::Simulate(simulation);
  if (!summary.ok()) return summary.status();
  cached.simulate_s = start.ElapsedSeconds();
  {
    std::ofstream out(temporary / kOptionsName);
    out << recorded.dump(2) << "\n";
    if (!out.flush()) {
      return IoError((temporary / kOptionsName).string() + ": cannot write");
    }
  }
  // A damaged entry in the way goes; one that another run made meanwhile is used.
  if (fs::exists(entry, ec) && !EntryMatches(entry, recorded)) fs::remove_all(entry, ec);
  if (Status moved = replacement.Commit(); !moved.ok() && !EntryMatches(entry, recorded)) {
    return Status(moved.code(),
                  "cannot move the simulated video into the cache: " + moved.message());
  }
  cached.simulated = true;
  return cached;
}

int64_t CountOverlayTracks(const frontend::FrontEndResult& result, const sim::Truth& truth) {
  if (truth.overlays.empty()) return 0;
  int64_t count = 0;
  for (const track::TargetTrack& target : result.targets) {
    const auto on = std::count_if(
        target.observations.begin(), target.observations.end(),
        [&](const track::TargetObservation& o) { return truth.OnOverlay(o.position); });
    if (!target.observations.empty() && 2 * static_cast<size_t>(on) >= target.observations.size())
      ++count;
  }
  return count;
}

CutScore ScoreCuts(const std::vector<int64_t>& cut_frames,
                   const std::vector<track::ChainBreak>& breaks,
                   const std::vector<track::TargetTrack>& targets, int64_t tolerance) {
  const auto near = [&](int64_t a, int64_t b) { return std::abs(a - b) <= tolerance; };
  CutScore score;
  score.expected = static_cast<int64_t>(cut_frames.size());
  for (int64_t cut : cut_frames) {
    score.found += std::any_of(breaks.begin(), breaks.end(), [&](const track::ChainBreak& b) {
      return near(b.frame_index, cut);
    });
  }
  for (const track::ChainBreak& b : breaks) {
    score.other_breaks += std::none_of(cut_frames.begin(), cut_frames.end(),
                                       [&](int64_t cut) { return near(b.frame_index, cut); });
  }
  for (const track::TargetTrack& t : targets) {
    if (t.observations.empty()) continue;
    score.tracks_across += std::any_of(cut_frames.begin(), cut_frames.end(), [&](int64_t cut) {
      return t.observations.front().frame < cut && cut <= t.observations.back().frame;
    });
  }
  return score;
}

void CorpusFigures::Add(const CorpusFigures& o) {
  cases += o.cases;
  failed_cases += o.failed_cases;
  truth_targets += o.truth_targets;
  found_targets += o.found_targets;
  detected_tracks += o.detected_tracks;
  correct_tracks += o.correct_tracks;
  truth_mover_frames += o.truth_mover_frames;
  paired_movers += o.paired_movers;
  detections += o.detections;
  paired_detections += o.paired_detections;
  latencies_s.insert(latencies_s.end(), o.latencies_s.begin(), o.latencies_s.end());
  overlay_tracks += o.overlay_tracks;
  frames += o.frames;
  mask_off_overlay_frames += o.mask_off_overlay_frames;
  noisy_frames += o.noisy_frames;
  speed_relative_errors.insert(speed_relative_errors.end(), o.speed_relative_errors.begin(),
                               o.speed_relative_errors.end());
  homography_errors_px.insert(homography_errors_px.end(), o.homography_errors_px.begin(),
                              o.homography_errors_px.end());
  homography_failed += o.homography_failed;
  if (mosaic_unit == MosaicUnit::kNone) {
    mosaic_unit = o.mosaic_unit;
  } else if (o.mosaic_unit != MosaicUnit::kNone && o.mosaic_unit != mosaic_unit) {
    mosaic_unit = MosaicUnit::kMixed;
  }
  mosaic_key_frames += o.mosaic_key_frames;
  mosaic_before_sq += o.mosaic_before_sq;
  mosaic_after_sq += o.mosaic_after_sq;
  cuts.expected += o.cuts.expected;
  cuts.found += o.cuts.found;
  cuts.other_breaks += o.cuts.other_breaks;
  cuts.tracks_across += o.cuts.tracks_across;
  simulate_s += o.simulate_s;
  process_s += o.process_s;
}

std::optional<double> CorpusFigures::TrackPrecision() const {
  return Ratio(correct_tracks, detected_tracks);
}
std::optional<double> CorpusFigures::TrackRecall() const {
  return Ratio(found_targets, truth_targets);
}
std::vector<std::string> FloorShortfalls(const CorpusFloor& floor, const CorpusFigures& figures) {
  std::vector<std::string> shortfalls;
  char line[200];
  const auto at_least = [&](const char* what, const std::optional<double>& floor_value,
                            int64_t count, int64_t of) {
    if (!floor_value) return;
    if (of == 0) {
      std::snprintf(line, sizeof(line), "%s: nothing to measure (floor %.3f)", what, *floor_value);
      shortfalls.push_back(line);
      return;
    }
    const double value = static_cast<double>(count) / static_cast<double>(of);
    if (value >= *floor_value) return;
    std::snprintf(line, sizeof(line), "%s %.3f (%lld of %lld) is below its floor %.3f", what, value,
                  static_cast<long long>(count), static_cast<long long>(of), *floor_value);
    shortfalls.push_back(line);
  };
  const auto at_most = [&](const char* what, const std::optional<int64_t>& ceiling, int64_t value) {
    if (!ceiling || value <= *ceiling) return;
    std::snprintf(line, sizeof(line), "%s: %lld, at most %lld allowed", what,
                  static_cast<long long>(value), static_cast<long long>(*ceiling));
    shortfalls.push_back(line);
  };
  at_least("track precision", floor.track_precision, figures.correct_tracks,
           figures.detected_tracks);
  at_least("track recall", floor.track_recall, figures.found_targets, figures.truth_targets);
  at_most("tracks on overlay pixels", floor.overlay_tracks, figures.overlay_tracks);
  at_least("cuts found", floor.cuts_found, figures.cuts.found, figures.cuts.expected);
  at_most("tracks across a cut", floor.tracks_across_cuts, figures.cuts.tracks_across);
  at_most("false tracks", floor.false_tracks, figures.detected_tracks - figures.correct_tracks);
  return shortfalls;
}

std::optional<double> CorpusFigures::FramePrecision() const {
  return Ratio(paired_detections, detections);
}
std::optional<double> CorpusFigures::FrameRecall() const {
  return Ratio(paired_movers, truth_mover_frames);
}
std::optional<double> CorpusFigures::MedianLatency() const {
  if (latencies_s.empty()) return std::nullopt;
  return Median(latencies_s);
}
std::optional<double> CorpusFigures::HomographyMedian() const {
  if (homography_errors_px.empty()) return std::nullopt;
  return Median(homography_errors_px);
}
std::optional<double> CorpusFigures::SpeedError(double quantile) const {
  if (speed_relative_errors.empty()) return std::nullopt;
  return Quantile(speed_relative_errors, quantile);
}
std::optional<double> CorpusFigures::MosaicBeforeRms() const {
  return PooledRms(mosaic_before_sq, mosaic_key_frames, mosaic_unit);
}
std::optional<double> CorpusFigures::MosaicAfterRms() const {
  return PooledRms(mosaic_after_sq, mosaic_key_frames, mosaic_unit);
}

std::optional<double> CorpusFigures::MaskOffOverlay() const {
  if (frames <= 0) return std::nullopt;
  return mask_off_overlay_frames / static_cast<double>(frames);
}

CaseResult RunCase(const CorpusCase& corpus_case, const fs::path& cache_dir,
                   const frontend::FrontEndOptions& front_end) {
  CaseResult result;
  result.corpus_case = corpus_case;
  result.figures.cases = 1;
  Status status;
  try {
    status = MeasureCase(cache_dir, front_end, &result);
  } catch (const std::exception& e) {  // a broken invariant (SAKER_CHECK): this case only
    status = Status(StatusCode::kInvalidData, std::string("internal error: ") + e.what());
  }
  if (!status.ok()) {
    result.error = status.message();
    result.figures.failed_cases = 1;
  }
  return result;
}

std::vector<CaseResult> RunCorpus(const std::vector<CorpusCase>& cases,
                                  const CorpusRunOptions& options) {
  RemoveStaleTemporaries(options.cache_dir);
  std::vector<CaseResult> results(cases.size());
  if (cases.empty()) return results;
  std::atomic<size_t> next{0};
  std::mutex progress_mutex;
  const Stopwatch start;
  const auto report = [&](size_t i, const std::string& what) {
    if (!options.progress) return;
    const std::lock_guard<std::mutex> lock(progress_mutex);
    options.progress("[" + std::to_string(i + 1) + "/" + std::to_string(cases.size()) + " " +
                     Elapsed(start.ElapsedSeconds()) + "] " + cases[i].Name() + ": " + what);
  };
  const auto work = [&] {
    for (size_t i = next++; i < cases.size(); i = next++) {
      report(i, "started");
      results[i] = RunCase(cases[i], options.cache_dir, options.front_end);
      const CaseResult& r = results[i];
      if (!r.error.empty()) {
        report(i, "FAILED: " + r.error);
      } else {
        report(i, (r.simulated ? "simulated in " + Format("%.1f", r.figures.simulate_s) + " s"
                               : std::string("from the cache")) +
                      ", processed in " + Format("%.1f", r.figures.process_s) + " s");
      }
    }
  };
  const size_t threads =
      std::clamp<size_t>(static_cast<size_t>(std::max(1, options.jobs)), 1, cases.size());
  std::vector<std::thread> workers;
  for (size_t t = 1; t < threads; ++t) workers.emplace_back(work);
  work();
  for (std::thread& w : workers) w.join();
  return results;
}

std::vector<std::string> CorpusFloorShortfalls(const Corpus& corpus,
                                               const std::vector<CaseResult>& results) {
  std::vector<std::string> shortfalls;
  for (const auto& [condition, members] : ByCondition(results)) {
    const auto it = std::find_if(corpus.conditions.begin(), corpus.conditions.end(),
                                 [&](const CorpusCondition& c) { return c.name == condition; });
    if (it == corpus.conditions.end() || it->floor.empty()) continue;
    CorpusFigures sum;
    for (const CaseResult* r : members) {
      sum.Add(r->figures);
      if (!r->error.empty()) shortfalls.push_back(r->corpus_case.Name() + ": failed: " + r->error);
    }
    for (const std::string& line : FloorShortfalls(it->floor, sum)) {
      shortfalls.push_back(condition + ": " + line);
    }
  }
  return shortfalls;
}

std::string CorpusReportText(const std::vector<CaseResult>& results) {
  std::vector<Row> rows = {{"case", Titles(), ""}};
  CorpusFigures overall;
  const auto failed = [](const CorpusFigures& f) {
    return f.failed_cases > 0 ? ", " + std::to_string(f.failed_cases) + " failed" : "";
  };
  for (const auto& [condition, members] : ByCondition(results)) {
    CorpusFigures sum;
    for (const CaseResult* r : members) {
      sum.Add(r->figures);
      if (!r->error.empty()) {
        rows.push_back({r->corpus_case.Name(), {}, r->error});
      } else {
        rows.push_back({r->corpus_case.Name(), Cells(r->figures, !r->simulated), ""});
      }
    }
    rows.push_back({"= " + condition + " (" + std::to_string(members.size()) +
                        (members.size() == 1 ? " seed" : " seeds") + failed(sum) + ")",
                    Cells(sum, false), ""});
    overall.Add(sum);
  }
  rows.push_back({"= all (" + std::to_string(overall.cases) +
                      (overall.cases == 1 ? " case" : " cases") + failed(overall) + ")",
                  Cells(overall, false), ""});
  return FormatTable(rows) +
         "track P: target-track precision (ok/all: correct/detected tracks); track R: recall "
         "(found/all: truth sightings); frame P/R: per frame;\n"
         "lat s: median detection latency; ovl: tracks on overlay pixels; mask off %: image "
         "wrongly masked as overlay (mean over frames);\nnoisy %: frames whose motion "
         "thresholds the video's own noise raised; speed %: matched "
         "tracks' relative speed error, median/90th percentile;\n"
         "H px: median corner error of the frame homographies; mosaic: key frame corner RMS "
         "before > after adjustment (m: geo-referenced, as mapped;\n"
         "px: gauge removed); cuts: cuts found/expected; x-cut: tracks seen on both sides of a "
         "cut; other: chain breaks at no cut;\n"
         "sim s / proc s: simulation (cached: from the cache) / processing time.\n";
}

json CorpusReportJson(const Corpus& corpus, SeedSet seeds, const std::vector<CaseResult>& results) {
  json cases = json::array();
  for (const CaseResult& r : results) {
    json c = {{"name", r.corpus_case.Name()},
              {"condition", r.corpus_case.condition},
              {"seed", r.corpus_case.seed},
              {"seed_set", r.corpus_case.tuning ? "tuning" : "reporting"},
              {"cache_key", r.cache_key},
              {"simulated", r.simulated},
              {"figures", FiguresToJson(r.figures)}};
    if (!r.error.empty()) c["error"] = r.error;
    cases.push_back(std::move(c));
  }
  json conditions = json::array();
  CorpusFigures overall;
  for (const auto& [condition, members] : ByCondition(results)) {
    CorpusFigures sum;
    for (const CaseResult* r : members) sum.Add(r->figures);
    overall.Add(sum);
    json c = {{"name", condition}, {"figures", FiguresToJson(sum)}};
    for (const CorpusCondition& known : corpus.conditions) {
      if (known.name == condition) c["description"] = known.description;
    }
    conditions.push_back(std::move(c));
  }
  return {{"format", "saker-accuracy-report"},
          {"version", 1},
          {"manifest", corpus.manifest.string()},
          {"seeds", seeds == SeedSet::kTuning      ? "tuning"
                    : seeds == SeedSet::kReporting ? "reporting"
                                                   : "all"},
          {"simulator_version", sim::kSimulatorVersion},
          {"cases", cases},
          {"conditions", conditions},
          {"overall", FiguresToJson(overall)}};
}

}  // namespace saker::bench
