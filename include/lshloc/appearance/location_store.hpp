#pragma once
// The location store: the submap and pose of every map feature, by id.
// Positions [m], headings [rad], stored as floats.
// Thread safety: appends exclusive, reads concurrent (see LocationStore);
// reserve() counts as an append.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lshloc/common/huge_page_allocator.hpp"
#include "lshloc/common/byte_codec.hpp"
#include "lshloc/common/error.hpp"
#include "lshloc/appearance/feature.hpp"

namespace lshloc {

/// Where every map feature lies: an append-only list of MapLocation whose
/// index is the location id the appearance database stores (docs/design.md
/// section 3). 16 bytes per feature. Not thread-safe for concurrent
/// append; concurrent reads of existing ids are safe while nobody appends.
class LocationStore {
 public:
  /// Appends a location; returns its id (= the number of locations before).
  std::uint32_t append(const MapLocation& location) {
    if (locations_.size() >= std::numeric_limits<std::uint32_t>::max())
      throw Error("LocationStore: full (at most 2^32 - 1 locations)");
    locations_.push_back(location);
    return static_cast<std::uint32_t>(locations_.size() - 1);
  }
  std::uint32_t append(std::uint32_t submap, const Pose2& pose) {
    return append(
        MapLocation{submap, static_cast<float>(pose.x), static_cast<float>(pose.y), static_cast<float>(pose.theta)});
  }

  /// The location of `id`; throws lshloc::Error for an unknown id.
  const MapLocation& at(std::uint32_t id) const {
    if (id >= locations_.size())
      throw Error("LocationStore: unknown location id " + std::to_string(id) + " (store holds " +
                  std::to_string(locations_.size()) + ")");
    return locations_[id];
  }
  const MapLocation& operator[](std::uint32_t id) const { return locations_[id]; }

  std::size_t size() const { return locations_.size(); }
  bool empty() const { return locations_.empty(); }
  void reserve(std::size_t n) { locations_.reserve(n); }
  std::size_t bytes() const { return locations_.capacity() * sizeof(MapLocation); }
  using Locations = std::vector<MapLocation, HugePageAllocator<MapLocation>>;
  const Locations& locations() const { return locations_; }

  /// Every location bit for bit (docs/map-format.md): the submap as a
  /// varint, the pose as three floats.
  void write_snapshot(ByteWriter& out) const {
    out.varint(locations_.size());
    for (const MapLocation& l : locations_) {
      out.varint(l.submap);
      out.f32(l.x), out.f32(l.y), out.f32(l.theta);
    }
  }
  /// Restores what write_snapshot() wrote into this (empty) store; submaps
  /// must lie below `submap_limit`. Throws lshloc::Error naming `in`'s source.
  void read_snapshot(ByteReader& in, std::uint32_t submap_limit) {
    if (!locations_.empty()) throw Error("LocationStore::read_snapshot: the store is not empty");
    const auto n = static_cast<std::size_t>(in.varint_at_most(in.remaining() / 13, "a location count"));
    if (n > 0 && submap_limit == 0) in.fail("no locations in a map without submaps");
    locations_.resize(n);
    for (MapLocation& l : locations_) {
      l.submap = static_cast<std::uint32_t>(in.varint_at_most(submap_limit - 1, "a known submap"));
      l.x = in.f32(), l.y = in.f32(), l.theta = in.f32();
    }
  }

 private:
  /// On huge pages: hypotheses read a hundred of them per target feature,
  /// anywhere in millions (fewer TLB misses).
  Locations locations_;
};

}  // namespace lshloc
