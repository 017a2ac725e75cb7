#pragma once
// An allocator for the map's big hash tables (pose grids, LSH tables): blocks
// of 2 MiB or more are fresh anonymous mappings aligned to 2 MiB and marked
// for transparent huge pages (Linux madvise), so that filling a table takes
// 512 times fewer page faults and random probes miss the TLB less. Fresh
// mappings, not malloc's heap: memory malloc reuses was already faulted in
// as 4 KiB pages, which the advice does not turn into huge ones
// (BENCHMARKS.md). Smaller blocks come from operator new. No physical units.
// Thread safety: stateless; allocate and deallocate from any thread.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace lshloc {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  HugePageAllocator() = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) {}  // NOLINT: converting, as allocators are

  T* allocate(std::size_t n) {
    // Rounding up to whole pages and the alignment slack add up to two huge pages.
    if (n > (static_cast<std::size_t>(-1) - 2 * kHugePage) / sizeof(T)) throw std::bad_alloc();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugePage) return static_cast<T*>(::operator new(bytes));
    return static_cast<T*>(map_block(whole_pages(bytes)));
  }
  void deallocate(T* p, std::size_t n) {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < kHugePage) {
      ::operator delete(p);
    } else {
      unmap_block(p, whole_pages(bytes));
    }
  }
  template <class U>
  friend bool operator==(const HugePageAllocator&, const HugePageAllocator<U>&) {
    return true;
  }

 private:
  static std::size_t whole_pages(std::size_t bytes) { return (bytes + kHugePage - 1) / kHugePage * kHugePage; }

#if defined(__linux__)
  /// `size` bytes (whole huge pages) at a 2 MiB boundary: one huge page more
  /// is mapped, and the slack before and after the boundary given back.
  static void* map_block(std::size_t size) {
    void* raw = ::mmap(nullptr, size + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (raw == MAP_FAILED) throw std::bad_alloc();
    const auto start = reinterpret_cast<std::uintptr_t>(raw);
    const std::uintptr_t aligned = (start + kHugePage - 1) / kHugePage * kHugePage;
    if (aligned > start) ::munmap(raw, aligned - start);
    const std::size_t tail = start + size + kHugePage - (aligned + size);
    if (tail > 0) ::munmap(reinterpret_cast<void*>(aligned + size), tail);
    void* p = reinterpret_cast<void*>(aligned);
#if defined(MADV_HUGEPAGE)
    ::madvise(p, size, MADV_HUGEPAGE);  // advice only: without huge pages it works as before
#endif
    return p;
  }
  static void unmap_block(void* p, std::size_t size) { ::munmap(p, size); }
#else
  static void* map_block(std::size_t size) {
    void* p = std::aligned_alloc(kHugePage, size);
    if (p == nullptr) throw std::bad_alloc();
    return p;
  }
  static void unmap_block(void* p, std::size_t) { std::free(p); }
#endif
};

}  // namespace lshloc
