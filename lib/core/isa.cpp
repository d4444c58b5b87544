// Run-time choice of ISA (baseline x86-64 code: only cpuid/xgetbv through __builtin_cpu_supports).
#include "core/isa.h"

namespace rtp {
namespace {

Isa detect_isa_uncached() {
  __builtin_cpu_init();
  // __builtin_cpu_supports checks both cpuid and that the OS saves the YMM/ZMM state (xgetbv).
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi") &&
                    __builtin_cpu_supports("bmi2") && __builtin_cpu_supports("popcnt");
  const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
  return avx512 ? Isa::kAvx512 : (avx2 ? Isa::kAvx2 : Isa::kScalar);
}

}  // namespace

Isa detect_isa() {
  static const Isa isa = detect_isa_uncached();
  return isa;
}

const char* isa_name(Isa isa) {
  switch (isa) {
    case Isa::kScalar: return "scalar";
    case Isa::kAvx2: return "avx2";
    case Isa::kAvx512: return "avx512";
  }
  return "unknown";
}

}  // namespace rtp
