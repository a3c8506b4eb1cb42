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

}  // namespace saker::mission
