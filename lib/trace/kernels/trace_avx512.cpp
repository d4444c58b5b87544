// AVX-512 path (built with -mavx512f/vl/bw/dq): 16 lanes in one zmm, 4 and 8 in xmm/ymm.
// No FMA contraction: the scalar reference rounds every product, and so must we.
#if defined(__clang__)
#pragma clang fp contract(off)
#else
#pragma GCC optimize("fp-contract=off")
#endif
#define RTP_ISA_NS avx512
#include "trace/kernels/kernels_simd.h"
#include "trace/kernels/simd_avx512.h"
#include "trace/kernels/multi_hit.h"
#include "trace/kernels/trace_packet.h"

namespace rtp::avx512 {
using Avx512Kernels = SimdKernels<F4, F8, F16>;
}  // namespace rtp::avx512

RTP_DEFINE_ISA_ENTRY_POINTS(Avx512Kernels)
RTP_DEFINE_PACKET_ENTRY_POINTS(Avx512Kernels)
