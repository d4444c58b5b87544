// Large buffers on transparent huge pages (see aligned.h): mmap, trimmed to a 2 MiB boundary, madvise;
// freed mappings kept a moment for the next large allocation (resized with mremap, pages kept).
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
}  // namespace

void* allocate_large(size_t bytes) {
  const size_t len = round_up(bytes, kHuge);
  Kept k{nullptr, 0};
  {
    KeptList& l = kept_list();
    std::lock_guard<std::mutex> lock(l.mutex);
    std::vector<Kept>& kept = l.kept;
    // The smallest kept mapping that holds `len`, else the largest (grown below).
    size_t best = kept.size();
    for (size_t i = 0; i < kept.size(); ++i) {
      const bool fits = kept[i].len >= len;
      if (best == kept.size()) {
        best = i;
        continue;
      }
      const bool best_fits = kept[best].len >= len;
      if (fits ? (!best_fits || kept[i].len < kept[best].len) : (!best_fits && kept[i].len > kept[best].len)) best = i;
    }
    if (best != kept.size()) {
      k = kept[best];
      kept[best] = kept.back();
      kept.pop_back();
      l.bytes -= k.len;
    }
  }
  if (!k.p) return fresh(len);
  if (k.len >= len) {
    if (k.len > len) ::munmap(static_cast<char*>(k.p) + len, k.len - len);  // shrink in place
    return k.p;
  }
  void* q = ::mremap(k.p, k.len, len, MREMAP_MAYMOVE);  // grow: the old pages move along, only the tail is new
  if (q == MAP_FAILED) {
    ::munmap(k.p, k.len);
    return fresh(len);
  }
  ::madvise(q, len, MADV_HUGEPAGE);
  return q;
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
