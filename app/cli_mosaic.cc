#include "app/cli_mosaic.h"

#include "app/cli_common.h"
#include "core/frontend/front_end.h"
#include "core/mosaic/mosaic_builder.h"
#include "core/mosaic/render.h"
#include "core/pipeline/stages.h"
#include "core/render/activity_map.h"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <map>
#include <system_error>

namespace saker::app {

struct MosaicCommand::State {
  CLI::App* command = nullptr;
  std::string video;
  std::filesystem::path output;
  bool json = false;
  bool quiet = false;
  bool no_metadata = false;
  bool accept_bad_checksums = false;
  bool outlines = false;
  bool unadjusted = false;
  std::string adjust = "decomposed";
  mosaic::MosaicOptions mosaic;
  mosaic::RenderOptions render;
};

MosaicCommand::MosaicCommand(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.command = app.add_subcommand(
      "mosaic",
      "Build the mosaic map of a video: track features, chain key frames, close loops (geometric\n"
      "matching inside uncertainty ellipses, SIFT appearance matching when lost), bundle adjust\n"
      "the key frames' absolute homographies (with the metadata corners when present; by default\n"
      "through the node/arc decomposition, see --adjust), place every frame between the key\n"
      "frames, and write the key frames warped and blended into one picture. See docs/mosaic.md.");
  s.command->add_option("VIDEO", s.video, "Video file (MPEG-TS, MP4, ...)")->required();
  s.command->add_option("-o,--output", s.output, "Mosaic picture to write (.png, .jpg, .tif)")
      ->required();
  s.command->add_flag("--json", s.json, "Print the summary as JSON");
  s.command->add_flag("-q,--quiet", s.quiet, "No progress on stderr");
  s.command->add_flag("--no-metadata", s.no_metadata,
                      "Ignore the metadata corners (map frame = the first key frame's pixels)");
  s.command
      ->add_option("--metadata-sigma", s.mosaic.adjustment.metadata_sigma_m,
                   "Stated accuracy of the metadata corners, metres (1 sigma)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  AddAcceptBadChecksumsFlag(s.command, &s.accept_bad_checksums);
  AddAdjustOption(s.command, &s.adjust);
  s.command->add_flag("--outlines", s.outlines,
                      "Draw key frame outlines (by chain segment) and links (cross-links in red)");
  s.command->add_flag("--unadjusted", s.unadjusted,
                      "Draw the key frames as the sequential chain alone places them (before loop "
                      "closure and adjustment), to see the drift the adjustment removes");
  s.command
      ->add_option("--ellipses", s.render.ellipse_confidence,
                   "Draw the key frame corners' uncertainty ellipses at this confidence (0..1)")
      ->check(CLI::Range(0.0, 0.9999));
  s.command->add_option("--max-side", s.render.max_side_px, "Longer side of the picture, pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 30000));
}

MosaicCommand::~MosaicCommand() = default;
bool MosaicCommand::parsed() const { return state_->command->parsed(); }
int MosaicCommand::Run() const { return RunOn(state_->video, state_->output.string()); }

int MosaicCommand::RunOn(const std::string& video, const std::string& output) const {
  const State& s = *state_;
  JobContext job = ProgressContext(s.quiet || s.json);
  const auto fail = [&](const Status& status) { return Fail(status, !s.quiet && !s.json); };
  // Fail before the work, not after it, when the picture cannot be written there.
  const std::filesystem::path folder = std::filesystem::absolute(output).parent_path();
  if (std::error_code error; !std::filesystem::is_directory(folder, error)) {
    std::cerr << "saker-cli: cannot write " << output << ": the folder " << folder.string()
              << " does not exist\n";
    return 1;
  }
  // The engine's stages up to the mosaic, as a processing job runs them.
  pipeline::StageOptions options;
  options.mosaic = s.mosaic;
  options.mosaic.use_metadata = !s.no_metadata;
  options.mosaic.adjust_mode = *mosaic::ParseAdjustmentMode(s.adjust);
  options.front_end.metadata.accept_bad_checksums = s.accept_bad_checksums;
  pipeline::StageHooks hooks;
  hooks.last = pipeline::Stage::kMosaic;
  pipeline::MissionRun run;
  const Status ran = pipeline::RunStages(video, options, hooks, &job, &run);
  if (!ran.ok()) {
    // The front end names the video in its errors, and so does the mosaic but for a cancellation.
    const bool named =
        run.failed == pipeline::Stage::kFrontEnd || ran.code() != StatusCode::kCancelled;
    return fail(named ? ran : Status(ran.code(), video + ": " + ran.message()));
  }
  if (!run.mosaic)
    return fail(Status(run.no_mosaic.code(), video + ": " + run.no_mosaic.message()));
  const frontend::FrontEndResult* front = &run.front;
  const mosaic::MosaicResult* result = &*run.mosaic;
  mosaic::RenderOptions render = s.render;
  render.outlines = render.links = s.outlines;
  mosaic::LinkGraph drawn = result->graph;
  if (s.unadjusted) {
    for (size_t k = 0; k < drawn.nodes.size(); ++k)
      drawn.nodes[k].map_from_frame = result->chained[k];
  }
  StatusOr<mosaic::MosaicImage> picture = mosaic::RenderMosaic(
      drawn, front->key_frame_images, render,
      s.unadjusted ? std::vector<track::HomographyCovariance>() : result->covariances);
  if (!picture.ok()) return fail(picture.status());
  if (Status written = render::WritePicture(picture->bgr, output); !written.ok())
    return fail(written);
  if (!s.quiet && !s.json && isatty(STDERR_FILENO) != 0) {
    std::cerr << "\r" << std::string(40, ' ') << "\r";
  }

  const mosaic::LinkGraph& graph = result->graph;
  std::map<std::string, int> links;
  for (const mosaic::Link& l : graph.links) ++links[mosaic::LinkKindName(l.kind)];
  const int segments = graph.nodes.empty() ? 0 : graph.nodes.back().segment + 1;
  if (s.json) {
    nlohmann::json closures = nlohmann::json::array();
    for (const mosaic::LoopClosure& c : result->closures) {
      closures.push_back({{"from", static_cast<int>(c.from)},
                          {"to", static_cast<int>(c.to)},
                          {"kind", mosaic::LinkKindName(c.kind)},
                          {"inliers", c.inliers}});
    }
    nlohmann::json adjustments = nlohmann::json::array();
    for (const mosaic::AdjustmentSummary& a : result->adjustments)
      adjustments.push_back(a.ToString());
    nlohmann::json j = {
        {"video", video},
        {"output", output},
        {"frames", front->frames.size()},
        {"key_frames", graph.nodes.size()},
        {"segments", segments},
        {"chain_breaks", front->breaks.size()},
        {"key_frames_with_metadata", result->key_frames_with_metadata},
        {"geo_referenced", graph.geo_referenced},
        {"links", links},
        {"loop_closures", closures},
        {"adjustments", adjustments},
        {"adjust_mode", s.adjust},
        {"nodes", result->decomposition ? result->decomposition->nodes
                                        : static_cast<int>(graph.nodes.size())},
        {"arcs", result->decomposition ? result->decomposition->arcs : 0},
        {"frames_placed",
         result->in_between.key_frames + result->in_between.solved + result->in_between.chained},
        {"picture_width", picture->bgr.cols},
        {"picture_height", picture->bgr.rows},
        {"map_units_per_pixel", picture->map_units_per_px},
        {"front_end_s", front->timing.wall_s},
        {"mosaic_s", result->timing.total_s}};
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::cout << video << ": " << front->frames.size() << " frames, " << graph.nodes.size()
            << " key frames in " << segments << " segment" << (segments == 1 ? "" : "s") << " ("
            << front->breaks.size() << " chain breaks)\n";
  std::cout << "  map frame: "
            << (graph.geo_referenced
                    ? "east-north-up metres from the metadata corners (" +
                          std::to_string(result->key_frames_with_metadata) +
                          " key frames with corners)"
                    : std::string("the first key frame's pixels (no metadata corners)"))
            << "\n";
  std::cout << "  links:";
  for (const auto& [kind, n] : links) std::cout << " " << n << " " << kind;
  std::cout << "\n  loop closures: " << result->closures.size() << "\n";
  for (const mosaic::LoopClosure& c : result->closures) {
    std::cout << "    key frame " << static_cast<int>(c.from) << " -> " << static_cast<int>(c.to)
              << " (" << mosaic::LinkKindName(c.kind) << ", " << c.inliers << " inliers)\n";
  }
  std::cout << "  adjustments: " << result->adjustments.size();
  if (!result->adjustments.empty())
    std::cout << ", last: " << result->adjustments.back().ToString();
  if (result->decomposition) std::cout << "\n  " << result->decomposition->ToString();
  std::cout << "\n  " << result->in_between.ToString();
  std::cout << "\n  time: front end " << front->timing.wall_s << " s, mosaic "
            << result->timing.total_s << " s\n";
  std::cout << "  wrote " << output << " (" << picture->bgr.cols << "x" << picture->bgr.rows << ", "
            << picture->map_units_per_px << (graph.geo_referenced ? " m" : " px")
            << " per pixel)\n";
  return 0;
}

}  // namespace saker::app
