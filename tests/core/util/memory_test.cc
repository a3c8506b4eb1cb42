#include "core/util/memory.h"

#include <gtest/gtest.h>

#include <vector>

namespace saker {
namespace {

TEST(MemoryTest, ResidentMemoryFollowsAllocations) {
  const int64_t physical = PhysicalMemoryBytes();
  const int64_t before = ResidentMemoryBytes();
  ASSERT_GT(before, 0) << "no /proc on this system";
  ASSERT_GT(physical, before);
  // 64 MiB touched page by page becomes resident.
  std::vector<char> block(64u << 20);
  volatile char* bytes = block.data();  // the writes must happen
  for (size_t i = 0; i < block.size(); i += 4096) bytes[i] = 1;
  const int64_t after = ResidentMemoryBytes();
  EXPECT_GE(after - before, int64_t(56) << 20);
  EXPECT_GE(PeakResidentMemoryBytes(), after);
  EXPECT_EQ(DefaultMemoryLimitMiB(), physical / 4 * 3 / (1024 * 1024));
}

}  // namespace
}  // namespace saker
