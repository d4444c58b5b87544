#pragma once
// The deterministic random source of the lib/voxel unit tests (test_voxel.cpp, test_voxel_dag.cpp).
#include <cmath>
#include <cstdint>

namespace rtp::test {

// Counter-free deterministic generator (splitmix64).
struct Rng {
  uint64_t s;
  explicit Rng(uint64_t seed) : s(seed * 0x9E3779B97F4A7C15ull + 12345) {}
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double range(double a, double b) { return a + (b - a) * uniform(); }
  uint32_t below(uint32_t n) { return uint32_t(next() % n); }
  // A multiple of 2^-bits in [a, b].
  double dyadic(double a, double b, int bits) { return std::ldexp(std::round(std::ldexp(range(a, b), bits)), -bits); }
};

}  // namespace rtp::test
