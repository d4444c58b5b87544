#pragma once
// 64-byte aligned byte buffers: chunk payloads are read into these so that the formats/ structs
// (aligned up to 64 bytes) can be viewed in place. New bytes are not zeroed (see construct).
#include <cstddef>
#include <cstdint>
#include <new>
#include <utility>
#include <vector>

namespace rtp {

template <class T, size_t A = 64>
struct AlignedAllocator {
  using value_type = T;
  template <class U>
  struct rebind { using other = AlignedAllocator<U, A>; };
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U, A>&) {}
  T* allocate(size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(A))); }
  void deallocate(T* p, size_t) { ::operator delete(p, std::align_val_t(A)); }
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
  bool operator==(const AlignedAllocator<U, A>&) const { return true; }
};

using AlignedBytes = std::vector<uint8_t, AlignedAllocator<uint8_t>>;

}  // namespace rtp
