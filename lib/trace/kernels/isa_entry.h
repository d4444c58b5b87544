#pragma once
// The entry points each ISA translation unit (trace_scalar.cpp, trace_avx2.cpp, trace_avx512.cpp)
// defines in its own namespace; trace.cpp chooses among them at run time.
#include <cstddef>
#include <cstdint>

#include "trace/kernels/kernels.h"
#include "trace/trace.h"

#define RTP_DECLARE_ISA_ENTRY_POINTS(ns)                                                                                       \
  namespace rtp::ns {                                                                                                          \
  template <int W, int B>                                                                                                      \
  TraceStats closest(const SceneView<W, B>& scene, const fmt::Ray* rays, fmt::Hit* hits, size_t n, TraversalOrder order);      \
  template <int W, int B>                                                                                                      \
  TraceStats any(const SceneView<W, B>& scene, const fmt::Ray* rays, uint8_t* occluded, size_t n, TraversalOrder order);       \
  template <int W, int B>                                                                                                      \
  TraceStats multi(const SceneView<W, B>& scene, const fmt::Ray* rays, size_t n, uint32_t max_hits, bool cull, fmt::Hit* hits, \
                   uint32_t* counts, TraversalOrder order);                                                                    \
  template <int B>                                                                                                             \
  void block_test(const fmt::LeafBlock<B>& block, const fmt::Ray& ray, BlockHits<B>* out);                                     \
  template <int W>                                                                                                             \
  void node_test(const fmt::WideNode<W>& node, const fmt::Ray& ray, NodeHits<W>* out);                                         \
  }

// Coherent packets of P in {4, 8, 16} consecutive rays (trace_packet.h): SIMD ISAs only.
#define RTP_DECLARE_PACKET_ENTRY_POINTS(ns)                                                                                  \
  namespace rtp::ns {                                                                                                        \
  template <int W, int B>                                                                                                    \
  TraceStats closest_packets(const SceneView<W, B>& scene, const fmt::Ray* rays, fmt::Hit* hits, size_t n, uint32_t packet); \
  template <int W, int B>                                                                                                    \
  TraceStats any_packets(const SceneView<W, B>& scene, const fmt::Ray* rays, uint8_t* occluded, size_t n, uint32_t packet);  \
  }

RTP_DECLARE_ISA_ENTRY_POINTS(scalar)
RTP_DECLARE_ISA_ENTRY_POINTS(avx2)
RTP_DECLARE_ISA_ENTRY_POINTS(avx512)
RTP_DECLARE_PACKET_ENTRY_POINTS(avx2)
RTP_DECLARE_PACKET_ENTRY_POINTS(avx512)
