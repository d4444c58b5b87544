// AVX2 path (built with -mavx2 -mfma ...): 4 lanes in SSE, 8 in AVX, 16 as two AVX halves.
// No FMA contraction: the scalar reference rounds every product, and so must we.
#if defined(__clang__)
#pragma clang fp contract(off)
#else
#pragma GCC optimize("fp-contract=off")
#endif
#define RTP_ISA_NS avx2
#include "trace/kernels/kernels_simd.h"
#include "trace/kernels/multi_hit.h"
#include "trace/kernels/trace_packet.h"

namespace rtp::avx2 {
using Avx2Kernels = SimdKernels<F4, F8, F8>;
}  // namespace rtp::avx2

RTP_DEFINE_ISA_ENTRY_POINTS(Avx2Kernels)
RTP_DEFINE_PACKET_ENTRY_POINTS(Avx2Kernels)
