#pragma once
// Node/arc decomposition of the link graph (paper: "decomposing the sequential chains of key frames
// into a graph containing nodes and arcs"). Bundle adjustment over every key frame grows as the
// cube of their number; most key frames, though, take part in nothing but their two sequential
// links.
//
// - Nodes: the key frames that a kept cross-link touches, key frames with metadata corners (when
//   they are used), the ends of every chain segment, and extra key frames so that no arc is longer
//   than `max_arc_links` sequential links.
// - Arcs: the runs of sequential links between consecutive nodes of a segment. An arc is one link
//   of the reduced graph: its homography is the chained product of its links, its covariance
//   chained from theirs to first order (track::Compose, the links taken as independent).
// - The reduced graph (nodes, arcs, cross-links) is adjusted by Adjust, the same residuals and
//   gauge as the full adjustment; then the key frames inside each arc are placed by the linear-time
//   chain solver (chain_solver.h) with the arc's two end nodes held fixed.
// - Linearity check: an arc's chained covariance is a linear analysis about its measured shape. If
//   the adjustment flexes it far from that shape, the analysis no longer holds. The measure is the
//   arc's *flex*: the RMS, per corner coordinate, of the whitened misfit between its chained
//   homography and the one its adjusted end nodes imply (about 1 for an arc that bends as its
//   covariance predicts). An arc longer than one link with flex above `max_flex` gets a node in its
//   middle and the nodes are adjusted again, at most `max_rounds` times.
//
// Cross-links: a loop closure usually yields several cross-links between neighbouring key frames
// of the two passes, and each of their ends would be a node. `cross_link_spacing` keeps the
// strongest cross-link of such a cluster (most correspondences) and leaves out the others, whose
// ends are within that many key frames of a kept one's on both sides; 0 keeps every cross-link.
#include "core/mosaic/adjustment.h"
#include "core/mosaic/chain_solver.h"
#include "core/mosaic/link_graph.h"
#include "core/util/job_context.h"
#include "core/util/status.h"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace saker::mosaic {

// Which adjustment the mosaic runs.
enum class AdjustmentMode {
  kFull,        // every key frame is a parameter block
  kDecomposed,  // nodes only, then the arcs' key frames by the chain solver
};
const char* AdjustmentModeName(AdjustmentMode mode);
std::optional<AdjustmentMode> ParseAdjustmentMode(std::string_view name);

struct DecompositionOptions {
  // Longest arc, in sequential links (>= 1): longer runs get evenly spaced extra nodes.
  int max_arc_links = 50;
  // Cross-links whose ends both lie within this many key frames of a stronger kept cross-link's
  // ends are left out (>= 0; 0 keeps all).
  int cross_link_spacing = 0;
  // Linearity check: arcs flexed beyond this RMS whitened misfit get a node (> 0).
  double max_flex = 3;
  // Rounds of node insertion and re-adjustment at most (>= 0; 0: no linearity check).
  int max_rounds = 3;
  // Placement of the key frames inside the arcs.
  ChainOptions placement;
  // Whether metadata key frames are nodes: follows AdjustmentOptions::use_metadata and the graph's
  // geo_referenced flag, nothing to set here.

  // InvalidArgument naming the first bad field.
  Status Validate() const;
};

// An arc: a run of sequential links between two nodes of one segment.
struct Arc {
  KeyFrameId from{};          // the node it starts at (earlier in the chain)
  KeyFrameId to{};            // the node it ends at
  std::vector<size_t> links;  // indices into LinkGraph::links, in chain order
  double flex = 0;            // after the adjustment (see the file comment)
};

struct Decomposition {
  std::vector<bool> is_node;           // per key frame of the graph
  std::vector<KeyFrameId> nodes;       // in increasing order
  std::vector<Arc> arcs;               // in chain order
  std::vector<size_t> cross_links;     // kept non-sequential links (indices into links)
  std::vector<size_t> left_out_links;  // cross-links left out by cross_link_spacing
  int NodeCount() const { return static_cast<int>(nodes.size()); }
};

// Chooses the nodes and arcs. `extra_nodes` are made nodes as well (the linearity check's).
// The graph must be valid (LinkGraph::Validate), SAKER_CHECK otherwise.
Decomposition Decompose(const LinkGraph& graph, const DecompositionOptions& options,
                        bool metadata_nodes, const std::vector<KeyFrameId>& extra_nodes = {});

// The reduced graph of a decomposition: one node per node (renumbered 0..n-1 in the same order,
// map_from_frame and metadata as in `graph`), one link per arc (chained homography and
// covariance, kind kSequential, no correspondences), and the kept cross-links. InvalidData when
// an arc cannot be chained (a product through infinity).
StatusOr<LinkGraph> ReducedGraph(const LinkGraph& graph, const Decomposition& decomposition);

struct DecomposedSummary {
  AdjustmentSummary adjustment;  // of the last round's node adjustment
  int key_frames = 0;
  int nodes = 0;
  int arcs = 0;
  int cross_links = 0;           // used
  int left_out_cross_links = 0;  // by cross_link_spacing
  int rounds = 0;                // node adjustments run (1 + linearity rounds)
  int inserted_nodes = 0;        // by the linearity check
  double max_flex = 0;           // of the final arcs
  // Arcs whose key frames could not be solved between their end nodes (an end node the
  // adjustment left singular): chained from the first end instead, or left as they were.
  int arcs_not_solved = 0;
  double reduce_s = 0;           // decomposing and chaining the arcs
  double adjust_s = 0;           // the node adjustments
  double place_s = 0;            // the chain solves
  Decomposition decomposition;   // the final one (DecomposedCovariances needs it)
  std::string ToString() const;  // one line
};

// Adjusts `graph` through its decomposition and writes every key frame's map_from_frame back
// (nodes from the node adjustment, the others from the chain solves). Cancel and progress as
// Adjust (a cancelled node adjustment keeps its best solution; the arcs are then placed from it).
// InvalidArgument for bad options, InvalidData for an invalid graph or an arc that cannot be
// chained; an arc that cannot be placed is counted (arcs_not_solved), not an error.
StatusOr<DecomposedSummary> AdjustDecomposed(LinkGraph* graph, const AdjustmentOptions& options,
                                             const DecompositionOptions& decomposition,
                                             JobContext* job = nullptr);

// The covariance of every key frame's map_from_frame after AdjustDecomposed, for its final
// decomposition (DecomposedSummary::decomposition): nodes from the node adjustment
// (NodeCovariances of the reduced graph), the others from the chain solver's marginal covariance
// with the ends fixed, plus the ends' covariances carried through the arc and weighted by the key
// frame's position t along it (1 - t and t: exact when the two ends move together, larger than
// the truth when they move independently, so it errs on the safe side for loop-closure search
// regions). Errors as NodeCovariances and SolveChain.
StatusOr<std::vector<track::HomographyCovariance>> DecomposedCovariances(
    const LinkGraph& graph, const Decomposition& decomposition, const AdjustmentOptions& options,
    const ChainOptions& placement);

}  // namespace saker::mosaic
