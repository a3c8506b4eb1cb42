// saker-bench-accuracy: the front end and the mosaic over the accuracy corpus, a manifest of
// simulated conditions (frame rates, traffic, imaging, metadata, ...) each flown over several
// worlds, scored against the simulator's truth (docs/accuracy.md).
//
//   saker-bench-accuracy [MANIFEST] [--seeds tuning|reporting|all] [--only TEXT] [--jobs N]
//                        [--cache DIR] [--json]
//
// MANIFEST defaults to benchmarks/corpus/corpus.json in the source tree. Each case is simulated
// once into the cache (default build/accuracy-cache in the source tree), so a rerun only
// evaluates. It prints a row per case, a summary per condition and an overall one (--json: the
// same as JSON); progress goes to stderr. Conditions with a floor (benchmarks/corpus/floors.json)
// are checked against it after the report. Exit code 1 when a case failed, a floor was not met or
// the manifest is bad.

#include "benchmarks/accuracy_corpus.h"
#include "core/util/timer.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

int main(int argc, char** argv) {
  using namespace saker;
  namespace fs = std::filesystem;
  CLI::App app{"Accuracy of the front end and the mosaic over a corpus of simulated flights"};
  std::string manifest = (fs::path(SAKER_SOURCE_DIR) / "benchmarks/corpus/corpus.json").string();
  std::string seeds_name = "reporting";
  std::string only;
  std::string cache = (fs::path(SAKER_SOURCE_DIR) / "build/accuracy-cache").string();
  int jobs = 1;
  bool json = false;
  std::string overlay_mask = "default";
  std::string noise_thresholds = "measured";
  std::string details;
  app.add_option("MANIFEST", manifest, "Corpus manifest (docs/accuracy.md)")->capture_default_str();
  app.add_option("--seeds", seeds_name,
                 "Seeds to run: tuning (defaults may be tuned on these), reporting (the figures "
                 "quoted in docs) or all")
      ->capture_default_str()
      ->check(CLI::IsMember({"tuning", "reporting", "all"}));
  app.add_option("--only", only, "Only the conditions whose name contains this text");
  app.add_option("--jobs", jobs, "Cases run at once (each is multi-threaded already)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--cache", cache, "Folder of simulated videos, kept between runs")
      ->capture_default_str();
  app.add_flag("--json", json, "Print the figures as JSON");
  app.add_option("--overlay-mask", overlay_mask,
                 "The front end's screen-fixed overlay mask: the engine's default, on or off "
                 "(docs/front-end.md, Overlays)")
      ->capture_default_str()
      ->check(CLI::IsMember({"default", "on", "off"}));
  app.add_option("--noise-thresholds", noise_thresholds,
                 "The motion thresholds: raised where the video's measured noise asks for it "
                 "(measured, the engine's default) or the fixed ones alone (fixed), to measure "
                 "what measuring gains (docs/front-end.md, Noisy video)")
      ->capture_default_str()
      ->check(CLI::IsMember({"measured", "fixed"}));
  app.add_option("--details", details,
                 "Also write each case's evaluation with its missed sightings and false tracks "
                 "(saker-cli evaluate --details) to DIR/CONDITION-SEED.txt");
  CLI11_PARSE(app, argc, argv);

  bench::SetDefaultTestDataDir(SAKER_DEFAULT_TEST_DATA_DIR);
  const StatusOr<bench::Corpus> corpus = bench::ReadCorpus(manifest);
  if (!corpus.ok()) {
    std::cerr << "saker-bench-accuracy: " << corpus.status().message() << "\n";
    return 1;
  }
  for (const bench::CorpusCondition& condition : corpus->conditions) {
    if (!condition.unavailable.empty() && condition.name.find(only) != std::string::npos) {
      std::cerr << "saker-bench-accuracy: skipping " << condition.name << ": "
                << condition.unavailable << "\n";
    }
  }
  const bench::SeedSet seeds = *bench::ParseSeedSet(seeds_name);
  const std::vector<bench::CorpusCase> cases = bench::CorpusCases(*corpus, seeds, only);
  if (cases.empty()) {
    std::cerr << "saker-bench-accuracy: " << manifest << ": no case to run (no " << seeds_name
              << " seeds" << (only.empty() ? "" : ", or no condition name contains '" + only + "'")
              << ")\n";
    return 1;
  }
  std::cerr << "saker-bench-accuracy: " << cases.size() << " cases from " << manifest << ", cache "
            << cache << ", " << jobs << (jobs == 1 ? " job" : " jobs") << "\n";

  bench::CorpusRunOptions options;
  options.cache_dir = cache;
  options.jobs = jobs;
  if (overlay_mask != "default") options.front_end.overlays.enabled = overlay_mask == "on";
  if (noise_thresholds == "fixed") options.front_end.UseFixedThresholds();
  options.progress = [](const std::string& line) { std::cerr << line << std::endl; };
  const Stopwatch start;
  const std::vector<bench::CaseResult> results = bench::RunCorpus(cases, options);
  std::fprintf(stderr, "saker-bench-accuracy: done in %.0f s\n", start.ElapsedSeconds());

  if (!details.empty()) {
    std::error_code error;
    fs::create_directories(details, error);
    for (const bench::CaseResult& r : results) {
      if (r.details.empty()) continue;
      const fs::path path = fs::path(details) / (r.corpus_case.condition + "-" +
                                                 std::to_string(r.corpus_case.seed) + ".txt");
      std::ofstream out(path);
      out << r.details;
      if (!out) std::cerr << "saker-bench-accuracy: " << path.string() << ": cannot write\n";
    }
  }
  if (json) {
    std::cout << bench::CorpusReportJson(*corpus, seeds, results).dump(2) << "\n";
  } else {
    std::cout << bench::CorpusReportText(results);
  }
  const std::vector<std::string> shortfalls = bench::CorpusFloorShortfalls(*corpus, results);
  size_t floors = 0;
  for (const bench::CorpusCondition& condition : corpus->conditions)
    floors += !condition.floor.empty();
  if (floors > 0) {
    std::cerr << "saker-bench-accuracy: floors: "
              << (shortfalls.empty() ? "every condition with a floor meets it"
                                     : std::to_string(shortfalls.size()) + " short")
              << "\n";
    for (const std::string& line : shortfalls) std::cerr << "  " << line << "\n";
  }
  if (!shortfalls.empty()) return 1;
  for (const bench::CaseResult& r : results) {
    if (!r.error.empty()) return 1;
  }
  return 0;
}
