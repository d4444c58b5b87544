#pragma once
// 64-byte aligned byte buffers: chunk payloads are read into these so that the formats/ structs
// (aligned up to 64 bytes) can be viewed in place. New bytes are not zeroed (see construct).
// Buffers of kHugeThreshold bytes or more are backed by transparent huge pages (aligned.cpp).
#include <cstddef>
#include <cstdint>
#include <new>
#include <utility>
#include <vector>

namespace rtp {

// From this size on, a buffer is mapped on its own, 2 MiB aligned, with madvise(MADV_HUGEPAGE): a
// decompressed chunk of 30 MiB is then faulted in 15 times instead of 7,680 (4 KiB pages), which on
// this project's VM took as long as decompressing it (docs/trace/budget.md).
inline constexpr size_t kHugeThreshold = size_t(4) << 20;
void* allocate_large(size_t bytes);  // throws std::bad_alloc
// Freed buffers stay mapped (up to 512 MiB, oldest unmapped first): the next allocate_large moves their
// pages into the new buffer 2 MiB at a time (mremap) instead of faulting in and zeroing fresh ones, of
// any sizes; release_kept_large() unmaps what is left.
void deallocate_large(void* p, size_t bytes);  // bytes: as given to allocate_large
void release_kept_large();

template <class T, size_t A = 64>
struct AlignedAllocator {
  using value_type = T;
  template <class U>
  struct rebind {
    using other = AlignedAllocator<U, A>;
  };
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U, A>&) {}
  T* allocate(size_t n) {
    static_assert(A <= 4096, "large buffers are page aligned");
    if (n * sizeof(T) >= kHugeThreshold) return static_cast<T*>(allocate_large(n * sizeof(T)));
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(A)));
  }
  void deallocate(T* p, size_t n) {
    if (n * sizeof(T) >= kHugeThreshold) return deallocate_large(p, n * sizeof(T));
    ::operator delete(p, std::align_val_t(A));
  }
  // resize() and the size constructor leave new bytes uninitialized (default-init), as a read or a
  // decompression overwrites them at once: no zero fill of megabytes first. Give a value to get it.
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <class U>
  bool operator==(const AlignedAllocator<U, A>&) const {
    return true;
  }
};

using AlignedBytes = std::vector<uint8_t, AlignedAllocator<uint8_t>>;

}  // namespace rtp
