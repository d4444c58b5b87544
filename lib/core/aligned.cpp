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
std::mutex g_mutex;
std::vector<Kept> g_kept;
size_t g_kept_bytes = 0;

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
    std::lock_guard<std::mutex> lock(g_mutex);
    // The smallest kept mapping that holds `len`, else the largest (grown below).
    size_t best = g_kept.size();
    for (size_t i = 0; i < g_kept.size(); ++i) {
      const bool fits = g_kept[i].len >= len;
      if (best == g_kept.size()) {
        best = i;
        continue;
      }
      const bool best_fits = g_kept[best].len >= len;
      if (fits ? (!best_fits || g_kept[i].len < g_kept[best].len) : (!best_fits && g_kept[i].len > g_kept[best].len)) best = i;
    }
    if (best != g_kept.size()) {
      k = g_kept[best];
      g_kept[best] = g_kept.back();
      g_kept.pop_back();
      g_kept_bytes -= k.len;
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
  std::lock_guard<std::mutex> lock(g_mutex);
  g_kept.push_back({p, len});
  g_kept_bytes += len;
  while (g_kept_bytes > kKeepBytes) {  // oldest first
    ::munmap(g_kept.front().p, g_kept.front().len);
    g_kept_bytes -= g_kept.front().len;
    g_kept.erase(g_kept.begin());
  }
}

void release_kept_large() {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (const Kept& k : g_kept) ::munmap(k.p, k.len);
  g_kept.clear();
  g_kept_bytes = 0;
}

}  // namespace rtp
