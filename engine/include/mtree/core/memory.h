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
// the length is rounded up to whole huge pages when that adds at most an eighth, else to a size
// class (1/32 of the block's power of two, at least a 4 KiB page) so that blocks of about the
// same size get mappings of the same length. Smaller blocks and other systems use operator new.
// MATRIXTREE_HUGE_PAGES=0 in the environment keeps the mappings but drops the advice.
//
// Freed mappings are kept for reuse (MappingCache: at most 16 of them and 512 MiB, the oldest
// unmapped first), as glibc keeps freed heap blocks: a build that follows another one (a
// deforming mesh rebuilt every frame, or a build after FreeSearchStructure) then writes into
// pages the process already has, with no fault and no zeroing by the kernel (steady builds, the
// median of 4 processes: lucy 11.9 ms without, 9.5 ms with; docs/bench_locators.md, "Freed
// mappings kept for reuse"). A mapping is reused only
// for a block of the same mapped length. releaseCachedMemory() unmaps them all;
// MATRIXTREE_MAP_CACHE=0 in the environment turns the cache off.
//
// Elements are default-initialised: resize() leaves trivial types (the ids, counts, boxes)
// unwritten, so code must write every element it reads (assign() and resize(n, v) still fill):
// a reused mapping holds what its last user wrote (tests poison them to check, see
// setMappingCachePoison).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace mtree {

/// Asks for the cache lines of [begin, end), in 64-byte steps from begin: for data read at a
/// random place (a leaf's ids and boxes), so that the lines' misses overlap instead of coming
/// one after another.
inline void prefetchLines(const void* begin, const void* end) {
  for (const char *b = static_cast<const char*>(begin), *e = static_cast<const char*>(end); b < e; b += 64)
    __builtin_prefetch(b);
}

namespace detail {
constexpr size_t kHugePage = size_t{2} << 20;
constexpr size_t kSmallPage = size_t{4} << 10;
/// Blocks from this size up are mapped (one huge page: smaller ones gain nothing from it).
constexpr size_t kLargeBytes = kHugePage;

inline size_t roundUpTo(size_t bytes, size_t granule) { return (bytes + granule - 1) / granule * granule; }

/// The mapping length for a block of `bytes` (>= kLargeBytes): whole huge pages when rounding up
/// adds at most an eighth, else a size class: `bytes` rounded up to 1/32 of its largest power of
/// two not above it (at least a small page), at most 1/32 more.
inline size_t mappedLength(size_t bytes) {
  const size_t huge = roundUpTo(bytes, kHugePage);
  if (huge - bytes <= bytes / 8) return huge;
  size_t pow2 = 1;
  while (pow2 <= bytes / 2) pow2 *= 2;
  return roundUpTo(bytes, pow2 / 32 > kSmallPage ? pow2 / 32 : kSmallPage);
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

/// Freed mappings kept for reuse (see the file comment): oldest first. One per process (a copy
/// per shared object at worst: then only fewer reuses). Never destroyed, so that vectors freed
/// by static destructors still find it.
struct MappingCache {
  static constexpr size_t kMaxEntries = 16;
  static constexpr size_t kMaxBytes = size_t{512} << 20;
  std::mutex mutex;
  std::vector<std::pair<void*, size_t>> entries;
  size_t bytes = 0;
  bool poison = false;  // tests: fill a reused mapping with 0xA5 bytes
  MappingCache() { entries.reserve(kMaxEntries + 1); }
};
inline MappingCache& mappingCache() {
  static MappingCache* cache = new MappingCache;
  return *cache;
}
/// Whether freed mappings are kept: yes unless MATRIXTREE_MAP_CACHE is "0" (read once).
inline bool mappingCacheWanted() {
  static const bool wanted = [] {
    const char* v = std::getenv("MATRIXTREE_MAP_CACHE");
    return !(v && v[0] == '0' && v[1] == '\0');
  }();
  return wanted;
}

#if defined(__linux__)
/// A kept mapping of exactly `len` bytes (the newest), or nullptr.
inline void* takeCachedMapping(size_t len) {
  if (!mappingCacheWanted()) return nullptr;
  MappingCache& c = mappingCache();
  std::lock_guard<std::mutex> lock(c.mutex);
  for (size_t i = c.entries.size(); i-- > 0;) {
    if (c.entries[i].second != len) continue;
    void* p = c.entries[i].first;
    c.entries.erase(c.entries.begin() + static_cast<std::ptrdiff_t>(i));
    c.bytes -= len;
    if (c.poison) std::memset(p, 0xA5, len);
    return p;
  }
  return nullptr;
}

/// Keeps the mapping [p, p + len) for reuse, unmapping the oldest ones past the limits (or
/// this one, with the cache off).
inline void releaseMapping(void* p, size_t len) noexcept {
  if (!mappingCacheWanted()) {
    munmap(p, len);
    return;
  }
  MappingCache& c = mappingCache();
  std::lock_guard<std::mutex> lock(c.mutex);
  c.entries.emplace_back(p, len);  // capacity reserved: no allocation
  c.bytes += len;
  while (c.entries.size() > MappingCache::kMaxEntries || c.bytes > MappingCache::kMaxBytes) {
    munmap(c.entries.front().first, c.entries.front().second);
    c.bytes -= c.entries.front().second;
    c.entries.erase(c.entries.begin());
  }
}
#endif

/// A 2 MiB-aligned anonymous mapping of mappedLength(bytes) bytes advised for huge pages (a
/// kept one when there is one of that length), or nullptr when mmap fails.
inline void* mapLarge(size_t bytes) {
#if defined(__linux__)
  const size_t len = mappedLength(bytes);
  if (void* kept = takeCachedMapping(len)) return kept;
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
      detail::releaseMapping(static_cast<void*>(p), detail::mappedLength(bytes));
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

/// Unmaps every mapping kept for reuse (LargeVector's freed blocks, see the file comment) and
/// returns their bytes: memory back to the system after the last build.
inline size_t releaseCachedMemory() {
#if defined(__linux__)
  detail::MappingCache& c = detail::mappingCache();
  std::lock_guard<std::mutex> lock(c.mutex);
  const size_t released = c.bytes;
  for (const auto& e : c.entries) munmap(e.first, e.second);
  c.entries.clear();
  c.bytes = 0;
  return released;
#else
  return 0;
#endif
}

/// Bytes of the mappings kept for reuse.
inline size_t cachedMemoryBytes() {
  detail::MappingCache& c = detail::mappingCache();
  std::lock_guard<std::mutex> lock(c.mutex);
  return c.bytes;
}

namespace detail {
/// Tests: fill every reused mapping with 0xA5 bytes (code that reads what it did not write then
/// reads garbage instead of the zeros of a fresh mapping).
inline void setMappingCachePoison(bool on) {
  MappingCache& c = mappingCache();
  std::lock_guard<std::mutex> lock(c.mutex);
  c.poison = on;
}
}  // namespace detail

}  // namespace mtree
