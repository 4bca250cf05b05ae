// LargeVector: the build's big arrays (reference ids and their data, leaf storage, cell bounds,
// the work arrays) in memory mapped for them, on transparent huge pages where the kernel offers
// them, and left uninitialised by resize().
//
// Why: a build writes these arrays into memory new to the process whenever the previous ones were
// freed (a first build, FreeSearchStructure, a larger rebuild). glibc maps such blocks afresh and
// every 4 KiB page then costs a page fault, and the arrays were zeroed by resize() before the
// build wrote every element anyway. On the development machine (a VM, where a fault costs a few
// microseconds) pipe_flow_tets took 3,700 faults per build after FreeSearchStructure, 59 with
// these arrays (perf stat -e page-faults; docs/bench_locators.md has the commands and timings).
// Arrays under 2 MiB are left to operator new: brick_tets' still take about 1,300 faults.
//
// How: blocks of at least kLargeBytes are mmap'ed at a 2 MiB boundary and advised MADV_HUGEPAGE,
// so on Linux with transparent huge pages set to "madvise" or "always" each 2 MiB is one fault;
// the length is rounded up to whole huge pages when that adds at most an eighth (else the tail
// stays on small pages). Smaller blocks and other systems use operator new.
// MATRIXTREE_HUGE_PAGES=0 in the environment keeps the mappings but drops the advice.
// Elements are default-initialised: resize() leaves trivial types (the ids, counts, boxes)
// unwritten, so code must write every element it reads (assign() and resize(n, v) still fill).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace mtree {

namespace detail {
constexpr size_t kHugePage = size_t{2} << 20;
constexpr size_t kSmallPage = size_t{4} << 10;
/// Blocks from this size up are mapped (one huge page: smaller ones gain nothing from it).
constexpr size_t kLargeBytes = kHugePage;

/// The mapping length for a block of `bytes` (>= kLargeBytes): whole huge pages when rounding up
/// adds at most an eighth, else whole small pages.
inline size_t mappedLength(size_t bytes) {
  const size_t huge = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  return huge - bytes <= bytes / 8 ? huge : (bytes + kSmallPage - 1) / kSmallPage * kSmallPage;
}

/// Whether to ask for huge pages: yes unless the environment variable MATRIXTREE_HUGE_PAGES is
/// "0" (read once), for systems where the kernel's compaction on a huge-page fault is unwelcome.
inline bool hugePagesWanted() {
  static const bool wanted = [] {
    const char* v = std::getenv("MATRIXTREE_HUGE_PAGES");
    return !(v && v[0] == '0' && v[1] == '\0');
  }();
  return wanted;
}

/// A 2 MiB-aligned anonymous mapping of mappedLength(bytes) bytes advised for huge pages, or
/// nullptr when mmap fails.
inline void* mapLarge(size_t bytes) {
#if defined(__linux__)
  const size_t len = mappedLength(bytes);
  void* raw = mmap(nullptr, len + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) return nullptr;
  const uintptr_t r = reinterpret_cast<uintptr_t>(raw);
  const uintptr_t a = (r + kHugePage - 1) & ~(uintptr_t(kHugePage) - 1);
  if (a > r) munmap(raw, a - r);  // the unaligned head
  const size_t tail = (r + len + kHugePage) - (a + len);
  if (tail) munmap(reinterpret_cast<void*>(a + len), tail);
#if defined(MADV_HUGEPAGE)
  if (hugePagesWanted()) (void)madvise(reinterpret_cast<void*>(a), len, MADV_HUGEPAGE);
#endif
  return reinterpret_cast<void*>(a);
#else
  (void)bytes;
  return nullptr;
#endif
}

/// Whether a block of `bytes` would be mapped (the same rule for allocate and deallocate).
inline bool isLarge(size_t bytes) {
#if defined(__linux__)
  return bytes >= kLargeBytes;
#else
  (void)bytes;
  return false;
#endif
}
}  // namespace detail

/// The allocator of LargeVector (see the file comment). Stateless: any two compare equal, so
/// vectors swap and move their storage freely.
template <class T>
struct LargeAllocator {
  using value_type = T;
  LargeAllocator() noexcept = default;
  template <class U>
  LargeAllocator(const LargeAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    if (n > static_cast<size_t>(-1) / sizeof(T)) throw std::bad_array_new_length();
    const size_t bytes = n * sizeof(T);
    if (detail::isLarge(bytes)) {
      // deallocate() tells the two kinds of block apart by their size alone, so a large block
      // is always a mapping: when none can be had, memory is out, as operator new would find.
      if (void* p = detail::mapLarge(bytes)) return static_cast<T*>(p);
      throw std::bad_alloc();
    }
    return static_cast<T*>(::operator new(bytes));
  }
  void deallocate(T* p, size_t n) noexcept {
    const size_t bytes = n * sizeof(T);
#if defined(__linux__)
    if (detail::isLarge(bytes)) {
      munmap(static_cast<void*>(p), detail::mappedLength(bytes));
      return;
    }
#endif
    ::operator delete(static_cast<void*>(p));
  }
  /// Default-initialisation: resize(n) on trivial types writes nothing.
  template <class U>
  void construct(U* p) noexcept(noexcept(::new (static_cast<void*>(p)) U)) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... A>
  void construct(U* p, A&&... a) {
    ::new (static_cast<void*>(p)) U(std::forward<A>(a)...);
  }
  template <class U>
  friend bool operator==(const LargeAllocator&, const LargeAllocator<U>&) noexcept {
    return true;
  }
  template <class U>
  friend bool operator!=(const LargeAllocator&, const LargeAllocator<U>&) noexcept {
    return false;
  }
};

template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

}  // namespace mtree
