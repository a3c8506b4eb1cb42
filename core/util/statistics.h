#pragma once

// The one definition of a quantile (and so of a median) for summaries, evaluation figures and
// robust estimators, so that a "median" means the same thing everywhere it is printed.

#include <vector>

namespace saker {

// The q-quantile of `values` (q in [0, 1], clamped) as one of the values, no interpolation: the
// element of rank round(q * (n - 1)) in ascending order (ranks from 0, halves rounded up). So the
// median of an even count is the upper of the two middle values, the 0- and 1-quantiles are the
// minimum and the maximum. 0 for no values. NaN values give an unspecified result.
// O(n) (std::nth_element on the copy).
double Quantile(std::vector<double> values, double q);

// Quantile(values, 0.5).
double Median(std::vector<double> values);

}  // namespace saker
