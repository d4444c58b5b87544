// Scalar reference path: the kernels every SIMD path must match bit for bit.
#pragma GCC optimize("fp-contract=off")  // keep a*b+c as two roundings, as in the SIMD paths
#define RTP_ISA_NS scalar
#include "trace/kernels_scalar.h"
#include "trace/trace_ray.h"

RTP_DEFINE_ISA_ENTRY_POINTS(ScalarKernels)
