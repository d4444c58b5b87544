#pragma once
// The instruction sets rtpack's SIMD code is built for (scalar reference, AVX2, AVX-512) and which of
// them this CPU runs: the kernels (lib/trace/kernels) and the voxelizer (lib/voxel) choose at run time.
namespace rtp {

enum class Isa { kScalar, kAvx2, kAvx512 };
Isa detect_isa();               // the best this CPU supports (cpuid + OS support), computed once
const char* isa_name(Isa isa);  // "scalar", "avx2", "avx512"

}  // namespace rtp
