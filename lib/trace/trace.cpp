// The public entry points of trace.h / kernels.h: the requested ISA clamped to what the CPU has
// (core/isa.h), then the kernel of that ISA.
#include "trace/trace.h"

#include <string>

#include "core/error.h"
#include "trace/kernels/isa_entry.h"
#include "trace/kernels/kernels.h"

namespace rtp {
namespace {

// The requested ISA, or the best this CPU has when it lacks the requested one.
Isa usable(Isa requested) {
  const Isa best = detect_isa();
  return static_cast<int>(requested) <= static_cast<int>(best) ? requested : best;
}

}  // namespace

const char* order_name(TraversalOrder order) {
  switch (order) {
    case TraversalOrder::kOctantStack: return "octant-stack";
    case TraversalOrder::kActiveList: return "active-list";
  }
  return "unknown";
}

static void check_packet_size(uint32_t packet) {
  if (!packet_size_ok(packet)) throw Error(ExitCode::kUsage, "packet size " + std::to_string(packet) + " is not 0, 4, 8 or 16");
}

namespace {

template <int W, int B>
TraceStats closest_kernel(const SceneView<W, B>& scene, const fmt::Ray* rays, fmt::Hit* hits, size_t n,
                          const TraceOptions& options) {
  if (options.packet) {
    check_packet_size(options.packet);
    switch (usable(options.isa)) {
      case Isa::kAvx512: return avx512::closest_packets<W, B>(scene, rays, hits, n, options.packet);
      case Isa::kAvx2: return avx2::closest_packets<W, B>(scene, rays, hits, n, options.packet);
      case Isa::kScalar: break;
    }
  }
  switch (usable(options.isa)) {
    case Isa::kAvx512: return avx512::closest<W, B>(scene, rays, hits, n, options.order);
    case Isa::kAvx2: return avx2::closest<W, B>(scene, rays, hits, n, options.order);
    case Isa::kScalar: break;
  }
  return scalar::closest<W, B>(scene, rays, hits, n, options.order);
}

template <int W, int B>
TraceStats multi_kernel(const SceneView<W, B>& scene, const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits,
                        uint32_t* counts, const TraceOptions& options, bool cull) {
  switch (usable(options.isa)) {
    case Isa::kAvx512: return avx512::multi<W, B>(scene, rays, n, max_hits, cull, hits, counts, options.order);
    case Isa::kAvx2: return avx2::multi<W, B>(scene, rays, n, max_hits, cull, hits, counts, options.order);
    case Isa::kScalar: break;
  }
  return scalar::multi<W, B>(scene, rays, n, max_hits, cull, hits, counts, options.order);
}

}  // namespace

template <int W, int B>
TraceStats trace_closest(const SceneView<W, B>& scene, const fmt::Ray* rays, fmt::Hit* hits, size_t n,
                         const TraceOptions& options) {
  const TraceStats stats = closest_kernel(scene, rays, hits, n, options);
  name_merged_hits(scene, hits, n);
  return stats;
}

template <int W, int B>
TraceStats trace_any(const SceneView<W, B>& scene, const fmt::Ray* rays, uint8_t* occluded, size_t n,
                     const TraceOptions& options) {
  if (options.packet) {
    check_packet_size(options.packet);
    switch (usable(options.isa)) {
      case Isa::kAvx512: return avx512::any_packets<W, B>(scene, rays, occluded, n, options.packet);
      case Isa::kAvx2: return avx2::any_packets<W, B>(scene, rays, occluded, n, options.packet);
      case Isa::kScalar: break;
    }
  }
  switch (usable(options.isa)) {
    case Isa::kAvx512: return avx512::any<W, B>(scene, rays, occluded, n, options.order);
    case Isa::kAvx2: return avx2::any<W, B>(scene, rays, occluded, n, options.order);
    case Isa::kScalar: break;
  }
  return scalar::any<W, B>(scene, rays, occluded, n, options.order);
}

template <int W, int B>
TraceStats trace_multi(const SceneView<W, B>& scene, const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits,
                       uint32_t* counts, const TraceOptions& options, MultiHitMethod method) {
  if (max_hits < 1 || max_hits > kMaxMultiHit)
    throw Error(ExitCode::kUsage,
                "multi-hit: N = " + std::to_string(max_hits) + " is outside [1, " + std::to_string(kMaxMultiHit) + "]");
  const TraceStats stats = multi_kernel(scene, rays, n, max_hits, hits, counts, options, method == MultiHitMethod::kNodeCulling);
  name_merged_hits(scene, hits, n * size_t(max_hits));
  return stats;
}

template <int B>
void intersect_block(Isa isa, const fmt::LeafBlock<B>& block, const fmt::Ray& ray, BlockHits<B>* out) {
  switch (usable(isa)) {
    case Isa::kAvx512: return avx512::block_test<B>(block, ray, out);
    case Isa::kAvx2: return avx2::block_test<B>(block, ray, out);
    case Isa::kScalar: break;
  }
  scalar::block_test<B>(block, ray, out);
}

template <int W>
void intersect_node(Isa isa, const fmt::WideNode<W>& node, const fmt::Ray& ray, NodeHits<W>* out) {
  switch (usable(isa)) {
    case Isa::kAvx512: return avx512::node_test<W>(node, ray, out);
    case Isa::kAvx2: return avx2::node_test<W>(node, ray, out);
    case Isa::kScalar: break;
  }
  scalar::node_test<W>(node, ray, out);
}

#define RTP_INSTANTIATE_PUBLIC_WB(W, B)                                                                                     \
  template TraceStats trace_closest<W, B>(const SceneView<W, B>&, const fmt::Ray*, fmt::Hit*, size_t, const TraceOptions&); \
  template TraceStats trace_any<W, B>(const SceneView<W, B>&, const fmt::Ray*, uint8_t*, size_t, const TraceOptions&);      \
  template TraceStats trace_multi<W, B>(const SceneView<W, B>&, const fmt::Ray*, size_t, uint32_t, fmt::Hit*, uint32_t*,    \
                                        const TraceOptions&, MultiHitMethod);
RTP_INSTANTIATE_PUBLIC_WB(4, 4)
RTP_INSTANTIATE_PUBLIC_WB(8, 8)
RTP_INSTANTIATE_PUBLIC_WB(16, 16)
RTP_INSTANTIATE_PUBLIC_WB(8, 4)
RTP_INSTANTIATE_PUBLIC_WB(16, 8)

#define RTP_INSTANTIATE_PUBLIC_N(N)                                                                \
  template void intersect_block<N>(Isa, const fmt::LeafBlock<N>&, const fmt::Ray&, BlockHits<N>*); \
  template void intersect_node<N>(Isa, const fmt::WideNode<N>&, const fmt::Ray&, NodeHits<N>*);
RTP_INSTANTIATE_PUBLIC_N(4)
RTP_INSTANTIATE_PUBLIC_N(8)
RTP_INSTANTIATE_PUBLIC_N(16)

}  // namespace rtp
