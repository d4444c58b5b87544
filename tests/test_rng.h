#pragma once
// The deterministic random source of the unit tests: splitmix64 (Steele, Lea and Flood 2014). Salt (the
// per-suite offset of the seed) and Real (the type range() computes its span in) are kept per suite so
// that each draws the numbers it always drew.
#include <cmath>
#include <cstdint>

namespace rtp::test {

template <uint64_t Salt, class Real>
struct SplitMix64 {
  uint64_t s;
  explicit SplitMix64(uint64_t seed) : s(seed * 0x9E3779B97F4A7C15ull + Salt) {}
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  // In [lo, hi).
  Real range(Real lo, Real hi) { return Real(lo + (hi - lo) * uniform()); }
  template <class T>
  T below(T n) {
    return T(next() % n);
  }
  // A multiple of 2^-bits in [a, b].
  double dyadic(double a, double b, int bits) { return std::ldexp(std::round(std::ldexp(range(a, b), bits)), -bits); }
};

}  // namespace rtp::test
