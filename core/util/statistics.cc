#include "core/util/statistics.h"

#include <algorithm>
#include <cstddef>
#include <utility>

namespace saker {

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  q = std::clamp(q, 0.0, 1.0);
  const size_t k = std::min(values.size() - 1,
                            static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

double Median(std::vector<double> values) { return Quantile(std::move(values), 0.5); }

}  // namespace saker
