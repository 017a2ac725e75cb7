#pragma once
// Joins two series by time stamp: for each query stamp, the nearest reference
// stamp (ground truth to scans, relations to a trajectory).
// Times [s].
// Stateless; safe from any thread.
#include <optional>
#include <span>
#include <vector>

namespace lshloc {

/// For each query time stamp, the index of the reference time stamp nearest to
/// it if that lies within `tolerance` [s], else nullopt. The reference needs no
/// order. O((n + m) log m).
std::vector<std::optional<std::size_t>> join_by_timestamp(std::span<const double> queries,
                                                          std::span<const double> reference, double tolerance = 1e-3);

}  // namespace lshloc
