// Scalar reference path: the kernels every SIMD path must match bit for bit.
#if defined(__clang__)
#pragma clang fp contract(off)  // keep a*b+c as two roundings, as in the SIMD paths
#else
#pragma GCC optimize("fp-contract=off")
#endif
#define RTP_ISA_NS scalar
#include "trace/kernels/kernels_scalar.h"
#include "trace/kernels/multi_hit.h"

RTP_DEFINE_ISA_ENTRY_POINTS(ScalarKernels)
