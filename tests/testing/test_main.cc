// Test main shared by all engine tests: re-seeds the C random generator
// before each test so tests never depend on the order they run in.

#include <gtest/gtest.h>

#include <cstdlib>

namespace {

class ReseedListener : public ::testing::EmptyTestEventListener {
  void OnTestStart(const ::testing::TestInfo&) override { std::srand(42); }
};

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ::testing::UnitTest::GetInstance()->listeners().Append(new ReseedListener);
  return RUN_ALL_TESTS();
}
