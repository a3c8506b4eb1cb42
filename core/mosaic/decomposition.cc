#include "core/mosaic/decomposition.h"

#include "core/mosaic/residuals.h"
#include "core/track/homography.h"
#include "core/track/image_geometry.h"
#include "core/util/check.h"
#include "core/util/timer.h"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <utility>

namespace saker::mosaic {
namespace {

Eigen::Matrix3d Normalised(const Eigen::Matrix3d& h) { return h / h(2, 2); }

// Whether cross-link `a` belongs to the same loop closure as `b`: both ends within `spacing` key
// frames of b's, either way round.
bool SameClosure(const Link& a, const Link& b, int spacing) {
  const auto near = [spacing](KeyFrameId x, KeyFrameId y) {
    return std::abs(static_cast<int>(x) - static_cast<int>(y)) <= spacing;
  };
  return (near(a.from, b.from) && near(a.to, b.to)) || (near(a.from, b.to) && near(a.to, b.from));
}

// The chained homography and covariance of an arc: last_from_first = H_n ... H_1.
StatusOr<track::HomographyWithCovariance> ChainArc(const LinkGraph& graph, const Arc& arc) {
  SAKER_CHECK(!arc.links.empty());
  const Link& first = graph.links[arc.links.front()];
  track::HomographyWithCovariance chained{first.to_from_from, first.covariance};
  for (size_t i = 1; i < arc.links.size(); ++i) {
    const Link& link = graph.links[arc.links[i]];
    StatusOr<track::HomographyWithCovariance> next = track::Compose(
        link.to_from_from, link.covariance, chained.target_from_source, chained.covariance);
    if (!next.ok()) {
      return InvalidDataError(
          "decomposition: the arc from key frame " + std::to_string(static_cast<int>(arc.from)) +
          " to " + std::to_string(static_cast<int>(arc.to)) + " cannot be chained at key frame " +
          std::to_string(static_cast<int>(link.to)) + ": " + next.status().message());
    }
    chained = std::move(next).value();
  }
  return chained;
}

// RMS per corner coordinate of the whitened misfit between a (reduced) link's measurement and the
// relation its adjusted ends imply: the Mahalanobis length of the corner residual over 8.
double Flex(const LinkGraph& reduced, const Link& link, double floor_px) {
  const auto corners = track::ImageCorners(reduced.image_width, reduced.image_height);
  const Eigen::Matrix3d predicted =
      reduced.nodes[static_cast<size_t>(link.to)].map_from_frame.inverse() *
      reduced.nodes[static_cast<size_t>(link.from)].map_from_frame;
  Eigen::Matrix<double, internal::kResiduals, 1> error;
  for (int c = 0; c < 4; ++c) {
    error.segment<2>(2 * c) = track::Transfer(predicted, corners[static_cast<size_t>(c)]) -
                              track::Transfer(link.to_from_from, corners[static_cast<size_t>(c)]);
  }
  const Eigen::Matrix<double, internal::kResiduals, 1> whitened =
      internal::LinkWhitening(link.to_from_from, link.covariance, corners, floor_px) * error;
  return std::sqrt(whitened.squaredNorm() / internal::kResiduals);
}

// The steps of an arc for the chain solver.
std::vector<ChainStep> ArcSteps(const LinkGraph& graph, const Arc& arc) {
  std::vector<ChainStep> steps;
  steps.reserve(arc.links.size());
  for (size_t i : arc.links) {
    steps.push_back({graph.links[i].to_from_from, graph.links[i].covariance});
  }
  return steps;
}

// The key frames along an arc, both ends included, in chain order.
std::vector<KeyFrameId> ArcKeyFrames(const LinkGraph& graph, const Arc& arc) {
  std::vector<KeyFrameId> ids{arc.from};
  for (size_t i : arc.links) ids.push_back(graph.links[i].to);
  return ids;
}

// Places the key frames inside an arc between its fixed end nodes. When the two ends cannot be
// solved between (an end node the adjustment left singular), they are chained from the first
// end; false when even that fails (the key frames then keep their values).
bool PlaceArc(LinkGraph* graph, const Arc& arc, const ChainOptions& options) {
  if (arc.links.size() < 2) return true;
  const std::vector<ChainStep> steps = ArcSteps(*graph, arc);
  const Eigen::Matrix3d& first = graph->nodes[static_cast<size_t>(arc.from)].map_from_frame;
  StatusOr<ChainSolution> solution =
      SolveChain(first, graph->nodes[static_cast<size_t>(arc.to)].map_from_frame, steps,
                 graph->image_width, graph->image_height, options);
  const bool solved = solution.ok();
  if (!solved) {
    solution =
        SolveChain(first, std::nullopt, steps, graph->image_width, graph->image_height, options);
    if (!solution.ok()) return false;
  }
  const std::vector<KeyFrameId> ids = ArcKeyFrames(*graph, arc);
  for (size_t j = 1; j + 1 < ids.size(); ++j) {
    graph->nodes[static_cast<size_t>(ids[j])].map_from_frame = solution->map_from_frame[j];
  }
  return solved;
}

}  // namespace

const char* AdjustmentModeName(AdjustmentMode mode) {
  switch (mode) {
    case AdjustmentMode::kFull:
      return "full";
    case AdjustmentMode::kDecomposed:
      return "decomposed";
  }
  return "unknown";
}

std::optional<AdjustmentMode> ParseAdjustmentMode(std::string_view name) {
  if (name == "full") return AdjustmentMode::kFull;
  if (name == "decomposed") return AdjustmentMode::kDecomposed;
  return std::nullopt;
}

Status DecompositionOptions::Validate() const {
  if (max_arc_links < 1) {
    return InvalidArgumentError("decomposition: max_arc_links must be at least 1");
  }
  if (cross_link_spacing < 0) {
    return InvalidArgumentError("decomposition: cross_link_spacing must be >= 0 key frames");
  }
  if (!(max_flex > 0)) return InvalidArgumentError("decomposition: max_flex must be positive");
  if (max_rounds < 0) return InvalidArgumentError("decomposition: max_rounds must be >= 0");
  return placement.Validate();
}

Decomposition Decompose(const LinkGraph& graph, const DecompositionOptions& options,
                        bool metadata_nodes, const std::vector<KeyFrameId>& extra_nodes) {
  const size_t n = graph.nodes.size();
  Decomposition d;
  d.is_node.assign(n, false);
  for (KeyFrameId id : extra_nodes) {
    SAKER_CHECK(static_cast<int>(id) >= 0 && static_cast<size_t>(id) < n)
        << "extra node " << static_cast<int>(id) << " out of range";
    d.is_node[static_cast<size_t>(id)] = true;
  }

  // The chains: at most one sequential link out of and into each key frame; any other link
  // (a cross-link, or a sequential link that would fork a chain) joins two nodes directly.
  std::vector<int> next_link(n, -1), previous_link(n, -1);
  std::vector<size_t> others;
  for (size_t i = 0; i < graph.links.size(); ++i) {
    const Link& link = graph.links[i];
    if (link.kind == LinkKind::kSequential && next_link[static_cast<size_t>(link.from)] < 0 &&
        previous_link[static_cast<size_t>(link.to)] < 0) {
      next_link[static_cast<size_t>(link.from)] = static_cast<int>(i);
      previous_link[static_cast<size_t>(link.to)] = static_cast<int>(i);
    } else {
      others.push_back(i);
    }
  }

  // Cross-links, strongest first, less those of an already kept one's loop closure.
  std::stable_sort(others.begin(), others.end(), [&](size_t a, size_t b) {
    return graph.links[a].correspondences.size() > graph.links[b].correspondences.size();
  });
  for (size_t i : others) {
    const bool sequential = graph.links[i].kind == LinkKind::kSequential;
    bool left_out = false;
    if (options.cross_link_spacing > 0 && !sequential) {
      for (size_t kept : d.cross_links) {
        if (graph.links[kept].kind == LinkKind::kSequential) continue;
        if (SameClosure(graph.links[i], graph.links[kept], options.cross_link_spacing)) {
          left_out = true;
          break;
        }
      }
    }
    if (left_out) {
      d.left_out_links.push_back(i);
    } else {
      d.cross_links.push_back(i);
      d.is_node[static_cast<size_t>(graph.links[i].from)] = true;
      d.is_node[static_cast<size_t>(graph.links[i].to)] = true;
    }
  }
  std::sort(d.cross_links.begin(), d.cross_links.end());
  std::sort(d.left_out_links.begin(), d.left_out_links.end());

  for (size_t k = 0; k < n; ++k) {
    if (next_link[k] < 0 || previous_link[k] < 0) d.is_node[k] = true;  // a chain end
    if (metadata_nodes && graph.nodes[k].metadata_corners) d.is_node[k] = true;
  }

  // Walk every chain from its start; a chain closed on itself (no start) is entered at its
  // lowest key frame, made a node.
  std::vector<bool> walked(n, false);
  const auto walk = [&](size_t start) {
    Arc arc;
    arc.from = static_cast<KeyFrameId>(start);
    size_t k = start;
    walked[k] = true;
    while (next_link[k] >= 0) {
      const size_t link = static_cast<size_t>(next_link[k]);
      arc.links.push_back(link);
      k = static_cast<size_t>(graph.links[link].to);
      const bool closed = walked[k];
      walked[k] = true;
      if (d.is_node[k] || closed) {
        arc.to = static_cast<KeyFrameId>(k);
        d.arcs.push_back(std::move(arc));
        arc = Arc{};
        arc.from = static_cast<KeyFrameId>(k);
        if (closed) break;
      }
    }
  };
  for (size_t k = 0; k < n; ++k) {
    if (previous_link[k] < 0) walk(k);
  }
  for (size_t k = 0; k < n; ++k) {
    if (!walked[k]) {
      d.is_node[k] = true;
      walk(k);
    }
  }

  // Long arcs, and an arc from a node back to itself, are split evenly.
  std::vector<Arc> arcs;
  for (Arc& arc : d.arcs) {
    const int links = static_cast<int>(arc.links.size());
    int parts = (links + options.max_arc_links - 1) / options.max_arc_links;
    if (arc.from == arc.to) parts = std::max(parts, 2);
    parts = std::min(parts, links);
    if (parts <= 1) {
      arcs.push_back(std::move(arc));
      continue;
    }
    int begin = 0;
    for (int p = 1; p <= parts; ++p) {
      const int end = static_cast<int>(std::lround(static_cast<double>(p) * links / parts));
      Arc piece;
      piece.from =
          begin == 0 ? arc.from : graph.links[arc.links[static_cast<size_t>(begin - 1)]].to;
      piece.to = graph.links[arc.links[static_cast<size_t>(end - 1)]].to;
      piece.links.assign(arc.links.begin() + begin, arc.links.begin() + end);
      d.is_node[static_cast<size_t>(piece.to)] = true;
      arcs.push_back(std::move(piece));
      begin = end;
    }
  }
  d.arcs = std::move(arcs);
  for (size_t k = 0; k < n; ++k) {
    if (d.is_node[k]) d.nodes.push_back(static_cast<KeyFrameId>(k));
  }
  return d;
}

StatusOr<LinkGraph> ReducedGraph(const LinkGraph& graph, const Decomposition& decomposition) {
  std::vector<int> reduced_id(graph.nodes.size(), -1);
  LinkGraph reduced;
  reduced.image_width = graph.image_width;
  reduced.image_height = graph.image_height;
  reduced.geo_referenced = graph.geo_referenced;
  reduced.nodes.reserve(decomposition.nodes.size());
  for (KeyFrameId id : decomposition.nodes) {
    Node node = graph.nodes[static_cast<size_t>(id)];
    reduced_id[static_cast<size_t>(id)] = static_cast<int>(reduced.nodes.size());
    node.id = static_cast<KeyFrameId>(reduced.nodes.size());
    reduced.nodes.push_back(std::move(node));
  }
  const auto remap = [&](KeyFrameId id) {
    SAKER_CHECK(reduced_id[static_cast<size_t>(id)] >= 0)
        << "key frame " << static_cast<int>(id) << " is not a node";
    return static_cast<KeyFrameId>(reduced_id[static_cast<size_t>(id)]);
  };
  reduced.links.reserve(decomposition.arcs.size() + decomposition.cross_links.size());
  for (const Arc& arc : decomposition.arcs) {
    SAKER_ASSIGN_OR_RETURN(track::HomographyWithCovariance chained, ChainArc(graph, arc));
    Link link;
    link.from = remap(arc.from);
    link.to = remap(arc.to);
    link.kind = LinkKind::kSequential;
    link.to_from_from = chained.target_from_source;
    link.covariance = chained.covariance;
    reduced.links.push_back(std::move(link));
  }
  for (size_t i : decomposition.cross_links) {
    const Link& original = graph.links[i];
    Link link;
    link.from = remap(original.from);
    link.to = remap(original.to);
    link.kind = original.kind;
    link.to_from_from = original.to_from_from;
    link.covariance = original.covariance;
    reduced.links.push_back(std::move(link));
  }
  return reduced;
}

std::string DecomposedSummary::ToString() const {
  char line[360];
  std::snprintf(line, sizeof(line),
                "decomposed: %d key frames -> %d nodes, %d arcs, %d cross-links (%d left out), "
                "%d round(s), %d node(s) inserted, max flex %.2f, %d arc(s) not solved; reduce "
                "%.3f s, adjust %.3f s, place %.3f s",
                key_frames, nodes, arcs, cross_links, left_out_cross_links, rounds, inserted_nodes,
                max_flex, arcs_not_solved, reduce_s, adjust_s, place_s);
  return line;
}

StatusOr<DecomposedSummary> AdjustDecomposed(LinkGraph* graph, const AdjustmentOptions& options,
                                             const DecompositionOptions& decomposition_options,
                                             JobContext* job) {
  SAKER_CHECK(graph != nullptr);
  SAKER_RETURN_IF_ERROR(options.Validate());
  SAKER_RETURN_IF_ERROR(decomposition_options.Validate());
  SAKER_RETURN_IF_ERROR(graph->Validate());
  const bool metadata_nodes = graph->geo_referenced && options.use_metadata;

  DecomposedSummary summary;
  summary.key_frames = static_cast<int>(graph->nodes.size());
  std::vector<KeyFrameId> inserted;
  Decomposition d;
  for (int round = 0;; ++round) {
    Stopwatch start;
    d = Decompose(*graph, decomposition_options, metadata_nodes, inserted);
    SAKER_ASSIGN_OR_RETURN(LinkGraph reduced, ReducedGraph(*graph, d));
    summary.reduce_s += start.ElapsedSeconds();

    start.Restart();
    SAKER_ASSIGN_OR_RETURN(summary.adjustment, Adjust(&reduced, options, job));
    summary.adjust_s += start.ElapsedSeconds();
    ++summary.rounds;
    for (size_t i = 0; i < d.nodes.size(); ++i) {
      graph->nodes[static_cast<size_t>(d.nodes[i])].map_from_frame =
          reduced.nodes[i].map_from_frame;
    }

    // The linearity check on the arcs (the reduced graph's first links, in the same order).
    summary.max_flex = 0;
    std::vector<KeyFrameId> flexed;
    for (size_t a = 0; a < d.arcs.size(); ++a) {
      Arc& arc = d.arcs[a];
      arc.flex = Flex(reduced, reduced.links[a], options.min_link_sigma_px);
      summary.max_flex = std::max(summary.max_flex, arc.flex);
      if (arc.links.size() >= 2 && arc.flex > decomposition_options.max_flex) {
        flexed.push_back(graph->links[arc.links[arc.links.size() / 2 - 1]].to);
      }
    }
    if (summary.adjustment.cancelled || flexed.empty() ||
        round >= decomposition_options.max_rounds) {
      break;
    }
    inserted.insert(inserted.end(), flexed.begin(), flexed.end());
    summary.inserted_nodes += static_cast<int>(flexed.size());
  }
  summary.nodes = d.NodeCount();
  summary.arcs = static_cast<int>(d.arcs.size());
  summary.cross_links = static_cast<int>(d.cross_links.size());
  summary.left_out_cross_links = static_cast<int>(d.left_out_links.size());

  const Stopwatch start;
  for (const Arc& arc : d.arcs) {
    if (!PlaceArc(graph, arc, decomposition_options.placement)) ++summary.arcs_not_solved;
  }
  summary.place_s = start.ElapsedSeconds();
  summary.decomposition = std::move(d);
  return summary;
}

StatusOr<std::vector<track::HomographyCovariance>> DecomposedCovariances(
    const LinkGraph& graph, const Decomposition& decomposition, const AdjustmentOptions& options,
    const ChainOptions& placement) {
  SAKER_ASSIGN_OR_RETURN(LinkGraph reduced, ReducedGraph(graph, decomposition));
  SAKER_ASSIGN_OR_RETURN(std::vector<track::HomographyCovariance> at_nodes,
                         NodeCovariances(reduced, options));
  std::vector<track::HomographyCovariance> result(graph.nodes.size(),
                                                  track::HomographyCovariance::Zero());
  for (size_t i = 0; i < decomposition.nodes.size(); ++i) {
    result[static_cast<size_t>(decomposition.nodes[i])] = at_nodes[i];
  }
  ChainOptions chain = placement;
  chain.covariances = true;
  for (const Arc& arc : decomposition.arcs) {
    if (arc.links.size() < 2) continue;
    const Eigen::Matrix3d& map_from_first =
        graph.nodes[static_cast<size_t>(arc.from)].map_from_frame;
    const Eigen::Matrix3d& map_from_last = graph.nodes[static_cast<size_t>(arc.to)].map_from_frame;
    SAKER_ASSIGN_OR_RETURN(ChainSolution solution,
                           SolveChain(map_from_first, map_from_last, ArcSteps(graph, arc),
                                      graph.image_width, graph.image_height, chain));
    const track::HomographyCovariance& first = result[static_cast<size_t>(arc.from)];
    const track::HomographyCovariance& last = result[static_cast<size_t>(arc.to)];
    const std::vector<KeyFrameId> ids = ArcKeyFrames(graph, arc);
    const double length = static_cast<double>(ids.size() - 1);
    for (size_t j = 1; j + 1 < ids.size(); ++j) {
      // map_from_j = map_from_end * (end_from_j): the end's uncertainty carried to j.
      const Eigen::Matrix3d& map_from_j = graph.nodes[static_cast<size_t>(ids[j])].map_from_frame;
      const Eigen::Matrix<double, 8, 8> j_first =
          track::ComposeJacobian(map_from_first, Normalised(map_from_first.inverse() * map_from_j))
              .leftCols<8>();
      const Eigen::Matrix<double, 8, 8> j_last =
          track::ComposeJacobian(map_from_last, Normalised(map_from_last.inverse() * map_from_j))
              .leftCols<8>();
      const double t = static_cast<double>(j) / length;
      track::HomographyCovariance c = solution.covariances[j] +
                                      (1 - t) * j_first * first * j_first.transpose() +
                                      t * j_last * last * j_last.transpose();
      result[static_cast<size_t>(ids[j])] = 0.5 * (c + c.transpose());
    }
  }
  return result;
}

}  // namespace saker::mosaic
