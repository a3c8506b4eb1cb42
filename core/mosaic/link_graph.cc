#include "core/mosaic/link_graph.h"

#include <cmath>
#include <numeric>

namespace saker::mosaic {

namespace {

bool FiniteHomography(const Eigen::Matrix3d& h) {
  return h.allFinite() && std::abs(h(2, 2) - 1.0) < 1e-9;
}

}  // namespace

Status LinkGraph::Validate() const {
  if (image_width <= 0 || image_height <= 0) {
    return InvalidDataError("link graph: the image size must be positive");
  }
  for (size_t i = 0; i < nodes.size(); ++i) {
    const Node& n = nodes[i];
    const std::string name = "link graph: key frame " + std::to_string(i);
    if (static_cast<size_t>(n.id) != i)
      return InvalidDataError(name + " has id " + std::to_string(static_cast<int>(n.id)));
    if (!FiniteHomography(n.map_from_frame)) {
      return InvalidDataError(name + " has a non-finite or unnormalised map_from_frame");
    }
    if (n.metadata_corners) {
      for (const Eigen::Vector2d& c : *n.metadata_corners) {
        if (!c.allFinite()) return InvalidDataError(name + " has non-finite metadata corners");
      }
    }
  }
  for (size_t k = 0; k < links.size(); ++k) {
    const Link& l = links[k];
    const std::string name = "link graph: link " + std::to_string(k);
    const int from = static_cast<int>(l.from), to = static_cast<int>(l.to);
    if (from < 0 || to < 0 || static_cast<size_t>(from) >= nodes.size() ||
        static_cast<size_t>(to) >= nodes.size()) {
      return InvalidDataError(name + " names a key frame that does not exist");
    }
    if (from == to) return InvalidDataError(name + " joins a key frame to itself");
    if (!FiniteHomography(l.to_from_from)) {
      return InvalidDataError(name + " has a non-finite or unnormalised homography");
    }
    if (!l.covariance.allFinite() ||
        (l.covariance - l.covariance.transpose()).cwiseAbs().maxCoeff() >
            1e-9 * (1 + l.covariance.cwiseAbs().maxCoeff())) {
      return InvalidDataError(name + " has a non-finite or asymmetric covariance");
    }
  }
  return Status::Ok();
}

std::vector<int> LinkGraph::Components() const {
  std::vector<int> parent(nodes.size());
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int x) {
    while (parent[static_cast<size_t>(x)] != x)
      x = parent[static_cast<size_t>(x)] =
          parent[static_cast<size_t>(parent[static_cast<size_t>(x)])];
    return x;
  };
  for (const Link& l : links) {
    const int a = find(static_cast<int>(l.from)), b = find(static_cast<int>(l.to));
    if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
  }
  std::vector<int> component(nodes.size(), -1), label(nodes.size(), -1);
  int next = 0;
  for (size_t i = 0; i < nodes.size(); ++i) {
    const int root = find(static_cast<int>(i));
    if (label[static_cast<size_t>(root)] < 0) label[static_cast<size_t>(root)] = next++;
    component[i] = label[static_cast<size_t>(root)];
  }
  return component;
}

bool LinkGraph::Linked(KeyFrameId a, KeyFrameId b) const {
  for (const Link& l : links) {
    if ((l.from == a && l.to == b) || (l.from == b && l.to == a)) return true;
  }
  return false;
}

}  // namespace saker::mosaic
