#include "core/util/statistics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace saker {
namespace {

TEST(StatisticsTest, QuantileIsTheValueOfTheRoundedRank) {
  const std::vector<double> v = {50, 10, 40, 20, 30};  // sorted: 10 20 30 40 50
  EXPECT_EQ(Quantile(v, 0), 10);
  EXPECT_EQ(Quantile(v, 1), 50);
  EXPECT_EQ(Quantile(v, 0.5), 30);
  EXPECT_EQ(Quantile(v, 0.25), 20);   // rank 1.0
  EXPECT_EQ(Quantile(v, 0.125), 20);  // rank 0.5 rounds up
  EXPECT_EQ(Quantile(v, 0.124), 10);  // rank 0.496
  EXPECT_EQ(Quantile(v, 0.9), 50);    // rank 3.6
  EXPECT_EQ(Quantile(v, 0.85), 40);   // rank 3.4
  EXPECT_EQ(Quantile(v, -1), 10);     // clamped
  EXPECT_EQ(Quantile(v, 7), 50);
}

TEST(StatisticsTest, MedianOfAnEvenCountIsTheUpperMiddleValue) {
  EXPECT_EQ(Median({4, 1, 3, 2}), 3);
  EXPECT_EQ(Median({2, 1}), 2);
  EXPECT_EQ(Median({7}), 7);
  EXPECT_EQ(Median({5, 1, 3}), 3);
  EXPECT_EQ(Median({}), 0);
  EXPECT_EQ(Quantile({}, 0.9), 0);
}

TEST(StatisticsTest, MatchesTheRankOfTheSortedValues) {
  std::mt19937 engine(3);
  std::uniform_real_distribution<double> uniform(-5, 5);
  for (int n = 1; n < 40; ++n) {
    std::vector<double> v(static_cast<size_t>(n));
    for (double& x : v) x = uniform(engine);
    std::vector<double> sorted = v;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(Median(v), sorted[static_cast<size_t>(n) / 2]) << n;
    for (double q : {0.05, 0.1, 0.5, 0.9, 0.95, 0.99}) {
      const size_t k = std::min(static_cast<size_t>(n - 1), static_cast<size_t>(q * (n - 1) + 0.5));
      EXPECT_EQ(Quantile(v, q), sorted[k]) << n << " " << q;
    }
  }
}

}  // namespace
}  // namespace saker
