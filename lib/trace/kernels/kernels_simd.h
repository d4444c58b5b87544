#pragma once
// The SIMD kernels behind the interface traversal uses (trace_ray.h), for a choice of vector type per
// width: AVX2 runs 4 lanes in SSE, 8 in AVX, 16 as two AVX halves; AVX-512 runs 16 in one zmm.
#include <type_traits>

#include "trace/kernels/box_simd.h"
#include "trace/kernels/simd_avx2.h"
#include "trace/kernels/triangle_simd.h"

namespace rtp::RTP_ISA_NS {

template <class V4, class V8, class V16>
struct SimdKernels {
  template <int N>
  using Vec = std::conditional_t<N == 4, V4, std::conditional_t<N == 8, V8, V16>>;

  template <int W>
  using NodeRay = SimdNodeRay<Vec<W>>;
  template <int W>
  RTP_KERNEL_INLINE static NodeRay<W> node_ray(const detail::BoxRay& r) {
    return simd_node_ray<Vec<W>, W>(r);
  }
  template <int W>
  RTP_KERNEL_INLINE static uint32_t node(const fmt::WideNode<W>& n, const NodeRay<W>& r, float tfar, float* dist) {
    return box_test_simd<Vec<W>, W>(n, r, tfar, dist);
  }
  template <int W>
  RTP_KERNEL_INLINE static uint32_t ordered(uint32_t mask, const uint8_t* order) {
    return ordered_mask_sse<W>(mask, order);
  }
  // W = 8 walks push their ordered child hits with one permutation (push_ordered8).
  static constexpr bool kPushOrdered8 = true;
  RTP_KERNEL_INLINE static void push_ordered8(void* dst, const uint32_t* child, const float* dist, const uint8_t* order,
                                              uint32_t rest) {
    rtp::RTP_ISA_NS::push_ordered8(dst, child, dist, order, rest);
  }
  RTP_KERNEL_INLINE static void push_ordered8_refs(uint32_t* dst, const uint32_t* child, const uint8_t* order, uint32_t rest) {
    rtp::RTP_ISA_NS::push_ordered8_refs(dst, child, order, rest);
  }
  // W = 16 walks push with one compress where the 16-lane vector has one (AVX-512: Push16).
  static constexpr bool kPushOrdered16 = !std::is_void_v<typename Vec<16>::Push>;
  template <class P = typename Vec<16>::Push>
  RTP_KERNEL_INLINE static void push_ordered16(void* dst, const uint32_t* child, const float* dist, const uint8_t* order,
                                               uint32_t rest) {
    P::pairs(dst, child, dist, order, rest);
  }
  template <int B>
  RTP_KERNEL_INLINE static uint32_t block(const fmt::LeafBlock<B>& b, const detail::TriRay& r, float tfar, BlockHits<B>* out) {
    return triangle_test_simd<Vec<B>, B, false>(b, r, tfar, out);
  }
  template <int B>
  RTP_KERNEL_INLINE static bool block_any(const fmt::LeafBlock<B>& b, const detail::TriRay& r, float tfar) {
    return triangle_test_simd<Vec<B>, B, true>(b, r, tfar, nullptr) != 0;
  }
};

}  // namespace rtp::RTP_ISA_NS
