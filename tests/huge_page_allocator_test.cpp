// The map's allocator: big blocks at 2 MiB boundaries, every byte usable,
// and vectors on it holding what std::vector holds through growth, copies
// and shrinking, at sizes either side of the 2 MiB line.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "lshloc/common/huge_page_allocator.hpp"

namespace lshloc {
namespace {

TEST(HugePageAllocator, BigBlocksAreAlignedAndWholeSmallOnesComeFromNew) {
  HugePageAllocator<std::uint64_t> alloc;
  constexpr std::size_t kPage = HugePageAllocator<std::uint64_t>::kHugePage;
  for (const std::size_t bytes : {std::size_t{64}, kPage - 8, kPage, kPage + 8, 3 * kPage + 4096, 9 * kPage}) {
    const std::size_t n = bytes / sizeof(std::uint64_t);
    std::uint64_t* p = alloc.allocate(n);
    ASSERT_NE(p, nullptr);
    if (bytes >= kPage) {
      EXPECT_EQ(reinterpret_cast<std::uintptr_t>(p) % kPage, 0u) << bytes << " bytes";
    }
    for (std::size_t i = 0; i < n; ++i) p[i] = i * 2654435761u;  // every byte writable
    std::uint64_t sum = 0;
    for (std::size_t i = 0; i < n; ++i) sum += p[i] - i * 2654435761u;
    EXPECT_EQ(sum, 0u);
    alloc.deallocate(p, n);
  }
}

TEST(HugePageAllocator, VectorsHoldWhatStdVectorHolds) {
  std::mt19937_64 rng(5);
  std::vector<std::uint32_t, HugePageAllocator<std::uint32_t>> big;
  std::vector<std::uint32_t> plain;
  // Grows through the 2 MiB line and well beyond (reallocations copy between mappings).
  for (std::size_t i = 0; i < 3'000'000; ++i) {
    const auto v = static_cast<std::uint32_t>(rng());
    big.push_back(v);
    plain.push_back(v);
  }
  ASSERT_TRUE(std::equal(big.begin(), big.end(), plain.begin(), plain.end()));
  auto copy = big;
  big.resize(100);
  big.shrink_to_fit();
  plain.resize(100);
  EXPECT_TRUE(std::equal(big.begin(), big.end(), plain.begin(), plain.end()));
  EXPECT_EQ(copy.size(), 3'000'000u);
  EXPECT_EQ(std::accumulate(copy.begin() + 100, copy.end(), std::uint64_t{0}) +
                std::accumulate(big.begin(), big.end(), std::uint64_t{0}),
            std::accumulate(copy.begin(), copy.end(), std::uint64_t{0}));
  copy.assign(5'000'000, 7u);
  EXPECT_EQ(std::accumulate(copy.begin(), copy.end(), std::uint64_t{0}), 35'000'000u);
}

}  // namespace
}  // namespace lshloc
