// Large buffers on transparent huge pages (see aligned.h): mmap, trimmed to a 2 MiB boundary, madvise;
// freed mappings kept a moment, their pages moved into the next large allocations (mremap).
#include "core/aligned.h"

#include <sys/mman.h>

#include <cstdint>
#include <mutex>
#include <vector>

namespace rtp {
namespace {
constexpr size_t kHuge = size_t(2) << 20;
// At most this many bytes of freed mappings are kept for reuse (older ones beyond it are unmapped), and
// release_kept_large() drops them all: the chunk cache frees its evicted buffers just before it loads the
// next chunks, which then take their pages instead of faulting in and zeroing fresh ones.
constexpr size_t kKeepBytes = size_t(512) << 20;
size_t round_up(size_t v, size_t a) { return (v + a - 1) / a * a; }

struct Kept {
  void* p;
  size_t len;
};
// Never destroyed: a worker thread's thread_local buffer may be freed after static destructors ran.
struct KeptList {
  std::mutex mutex;
  std::vector<Kept> kept;
  size_t bytes = 0;
};
KeptList& kept_list() {
  static KeptList* list = new KeptList;
  return *list;
}

void* fresh(size_t len) {
  // Map one huge page more than needed, then unmap the unaligned head and the rest of the tail.
  void* raw = ::mmap(nullptr, len + kHuge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const uintptr_t start = reinterpret_cast<uintptr_t>(raw);
  const uintptr_t aligned = round_up(start, kHuge);
  if (aligned > start) ::munmap(raw, aligned - start);
  const uintptr_t end = start + len + kHuge;
  if (end > aligned + len) ::munmap(reinterpret_cast<void*>(aligned + len), end - (aligned + len));
  void* p = reinterpret_cast<void*>(aligned);
  ::madvise(p, len, MADV_HUGEPAGE);  // advice only: without THP the pages are 4 KiB, nothing else changes
  return p;
}

// Moves kept pages into [base, base + len) front to back, one 2 MiB step per mremap (a step never spans
// two mappings: a buffer filled from several kept ones is several mappings). mremap moves the page
// tables, not the bytes: the pages come without a fault or a zeroing, whatever sizes the old and the
// new buffers have (a kept mapping larger than the request gives its head and stays kept for the rest).
void fill_from_kept(char* base, size_t len) {
  KeptList& l = kept_list();
  std::lock_guard<std::mutex> lock(l.mutex);
  for (size_t filled = 0; filled < len && !l.kept.empty();) {
    Kept& k = l.kept.back();  // the most recently freed: its pages the likeliest still in cache
    char* src = static_cast<char*>(k.p);
    if (::mremap(src, kHuge, kHuge, MREMAP_MAYMOVE | MREMAP_FIXED, base + filled) == MAP_FAILED) {
      // The target may be unmapped by a failed move: map it anew (fresh pages), drop the source step.
      if (::mmap(base + filled, kHuge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0) == MAP_FAILED)
        throw std::bad_alloc();
      ::madvise(base + filled, kHuge, MADV_HUGEPAGE);
      ::munmap(src, kHuge);
    }
    filled += kHuge;
    k.p = src + kHuge;
    k.len -= kHuge;
    l.bytes -= kHuge;
    if (k.len == 0) l.kept.pop_back();
  }
}
}  // namespace

void* allocate_large(size_t bytes) {
  const size_t len = round_up(bytes, kHuge);
  void* p = fresh(len);  // address space only: no page is touched yet
  fill_from_kept(static_cast<char*>(p), len);
  return p;
}

void deallocate_large(void* p, size_t bytes) {
  const size_t len = round_up(bytes, kHuge);
  KeptList& l = kept_list();
  std::lock_guard<std::mutex> lock(l.mutex);
  l.kept.push_back({p, len});
  l.bytes += len;
  while (l.bytes > kKeepBytes) {  // oldest first
    ::munmap(l.kept.front().p, l.kept.front().len);
    l.bytes -= l.kept.front().len;
    l.kept.erase(l.kept.begin());
  }
}

void release_kept_large() {
  KeptList& l = kept_list();
  std::lock_guard<std::mutex> lock(l.mutex);
  for (const Kept& k : l.kept) ::munmap(k.p, k.len);
  l.kept.clear();
  l.bytes = 0;
}

}  // namespace rtp
