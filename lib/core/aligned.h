#pragma once
// 64-byte aligned byte buffers: chunk payloads are read into these so that the formats/ structs
// (aligned up to 64 bytes) can be viewed in place.
#include <cstddef>
#include <cstdint>
#include <new>
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
  template <class U>
  bool operator==(const AlignedAllocator<U, A>&) const { return true; }
};

using AlignedBytes = std::vector<uint8_t, AlignedAllocator<uint8_t>>;

}  // namespace rtp
