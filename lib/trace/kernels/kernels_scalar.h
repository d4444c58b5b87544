#pragma once
// The scalar reference kernels behind the interface traversal uses (trace_ray.h): node test,
// octant order, block test (closest and any). Compiled only in trace_scalar.cpp.
#include "trace/kernels/box_scalar.h"
#include "trace/kernels/triangle_scalar.h"

namespace rtp::RTP_ISA_NS {

struct ScalarKernels {
  template <int W>
  using NodeRay = detail::BoxRay;  // the reference reads the ray as it is
  template <int W>
  static const detail::BoxRay& node_ray(const detail::BoxRay& r) {
    return r;
  }
  template <int W>
  static uint32_t node(const fmt::WideNode<W>& n, const detail::BoxRay& r, float tfar, float* dist) {
    return box_test_scalar<W>(n, r, tfar, dist);
  }
  template <int W>
  static uint32_t ordered(uint32_t mask, const uint8_t* order) {
    return ordered_mask_scalar<W>(mask, order);
  }
  static constexpr bool kPushOrdered8 = false;  // the walk's loop pushes the children
  static constexpr bool kPushOrdered16 = false;
  template <int B>
  static uint32_t block(const fmt::LeafBlock<B>& b, const detail::TriRay& r, float tfar, BlockHits<B>* out) {
    return triangle_test_scalar<B, false>(b, r, tfar, out);
  }
  template <int B>
  static bool block_any(const fmt::LeafBlock<B>& b, const detail::TriRay& r, float tfar) {
    return triangle_test_scalar<B, true>(b, r, tfar, nullptr) != 0;
  }
};

}  // namespace rtp::RTP_ISA_NS
