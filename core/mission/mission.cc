#include "core/mission/mission.h"

namespace saker::mission {

const char* LinkKindName(LinkKind kind) {
  switch (kind) {
    case LinkKind::kSequential:
      return "sequential";
    case LinkKind::kGeometric:
      return "geometric";
    case LinkKind::kAppearance:
      return "appearance";
  }
  return "unknown";
}

std::optional<LinkKind> LinkKindFromName(const std::string& name) {
  for (LinkKind kind : {LinkKind::kSequential, LinkKind::kGeometric, LinkKind::kAppearance}) {
    if (name == LinkKindName(kind)) return kind;
  }
  return std::nullopt;
}

}  // namespace saker::mission
