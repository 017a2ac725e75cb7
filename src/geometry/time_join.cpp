#include "lshloc/geometry/time_join.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace lshloc {

std::vector<std::optional<std::size_t>> join_by_timestamp(std::span<const double> queries,
                                                          std::span<const double> reference, double tolerance) {
  std::vector<std::size_t> order(reference.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return reference[a] < reference[b]; });
  std::vector<std::optional<std::size_t>> out(queries.size());
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const double t = queries[i];
    const auto it =
        std::lower_bound(order.begin(), order.end(), t, [&](std::size_t k, double v) { return reference[k] < v; });
    double best = tolerance;
    if (it != order.end() && std::abs(reference[*it] - t) <= best) best = std::abs(reference[*it] - t), out[i] = *it;
    if (it != order.begin() && std::abs(reference[*std::prev(it)] - t) <= best) out[i] = *std::prev(it);
  }
  return out;
}

}  // namespace lshloc
