#include "core/mosaic/in_between.h"

#include "core/util/timer.h"

#include <Eigen/LU>

#include <cstdio>

namespace saker::mosaic {
namespace {

Eigen::Matrix3d Normalised(const Eigen::Matrix3d& h) { return h / h(2, 2); }

}  // namespace

std::string InBetweenFrames::ToString() const {
  char line[200];
  std::snprintf(line, sizeof(line),
                "in-between frames: %d key frames, %d solved between key frames, %d chained from "
                "one, %d unplaced, %.3f s",
                key_frames, solved, chained, unplaced, time_s);
  return line;
}

StatusOr<InBetweenFrames> PlaceInBetweenFrames(const std::vector<MosaicFrame>& frames,
                                               const LinkGraph& graph, const ChainOptions& options,
                                               JobContext* job) {
  SAKER_RETURN_IF_ERROR(options.Validate());
  const Stopwatch start;
  const size_t n = frames.size();
  InBetweenFrames result;
  result.map_from_frame.assign(n, std::nullopt);

  std::vector<int> key_at(n, -1);
  for (const Node& node : graph.nodes) {
    if (node.frame_index < 0 || static_cast<size_t>(node.frame_index) >= n) {
      return InvalidArgumentError("in-between frames: key frame " +
                                  std::to_string(static_cast<int>(node.id)) + " is frame " +
                                  std::to_string(node.frame_index) + " but the video has " +
                                  std::to_string(n) + " frames");
    }
    int& at = key_at[static_cast<size_t>(node.frame_index)];
    if (at >= 0) {
      return InvalidArgumentError("in-between frames: key frames " + std::to_string(at) + " and " +
                                  std::to_string(static_cast<int>(node.id)) + " are both frame " +
                                  std::to_string(node.frame_index));
    }
    at = static_cast<int>(node.id);
  }

  std::vector<ChainStep> steps;
  size_t run_start = 0;
  while (run_start < n) {
    size_t run_end = run_start + 1;  // one past the run's last frame
    while (run_end < n && frames[run_end].homography_ok) ++run_end;

    std::vector<size_t> keys;
    for (size_t f = run_start; f < run_end; ++f) {
      if (key_at[f] >= 0) keys.push_back(f);
    }
    if (keys.empty()) {
      result.unplaced += static_cast<int>(run_end - run_start);
      run_start = run_end;
      continue;
    }
    for (size_t f : keys) {
      result.map_from_frame[f] = graph.nodes[static_cast<size_t>(key_at[f])].map_from_frame;
      ++result.key_frames;
    }
    // Before the first key frame: map_from_f = map_from_(f+1) * (f+1)_from_f.
    for (size_t f = keys.front(); f-- > run_start;) {
      result.map_from_frame[f] =
          Normalised(*result.map_from_frame[f + 1] * frames[f + 1].current_from_previous);
      ++result.chained;
    }
    // After the last: map_from_f = map_from_(f-1) * (f_from_(f-1))^-1.
    for (size_t f = keys.back() + 1; f < run_end; ++f) {
      result.map_from_frame[f] =
          Normalised(*result.map_from_frame[f - 1] * frames[f].current_from_previous.inverse());
      ++result.chained;
    }
    for (size_t i = 0; i + 1 < keys.size(); ++i) {
      if (job != nullptr && job->IsCancelled()) {
        return CancelledError("in-between frames: cancelled");
      }
      const size_t a = keys[i], b = keys[i + 1];
      if (b - a < 2) continue;
      steps.clear();
      for (size_t f = a + 1; f <= b; ++f) {
        steps.push_back({frames[f].current_from_previous, frames[f].covariance});
      }
      StatusOr<ChainSolution> solution =
          SolveChain(*result.map_from_frame[a], result.map_from_frame[b], steps, graph.image_width,
                     graph.image_height, options);
      if (!solution.ok()) {
        return InvalidDataError("in-between frames: frames " + std::to_string(a) + " to " +
                                std::to_string(b) + ": " + solution.status().message());
      }
      for (size_t f = a + 1; f < b; ++f) {
        result.map_from_frame[f] = solution->map_from_frame[f - a];
        ++result.solved;
      }
      if (job != nullptr)
        job->ReportProgress("in-between frames",
                            static_cast<double>(b + 1) / static_cast<double>(n));
    }
    run_start = run_end;
  }
  result.time_s = start.ElapsedSeconds();
  return result;
}

}  // namespace saker::mosaic
