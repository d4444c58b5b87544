// Large buffers on transparent huge pages (see aligned.h): mmap, trimmed to a 2 MiB boundary, madvise.
#include "core/aligned.h"

#include <sys/mman.h>

#include <cstdint>

namespace rtp {
namespace {
constexpr size_t kHuge = size_t(2) << 20;
size_t round_up(size_t v, size_t a) { return (v + a - 1) / a * a; }
}  // namespace

void* allocate_large(size_t bytes) {
  const size_t len = round_up(bytes, kHuge);
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

void deallocate_large(void* p, size_t bytes) { ::munmap(p, round_up(bytes, kHuge)); }

}  // namespace rtp
