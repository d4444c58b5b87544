// CRC-32C (Castagnoli polynomial 0x82F63B78): SSE4.2 crc32 instruction when the CPU has it,
// a byte table otherwise (and as the reference the tests compare against).
#include <cstring>
#include <nmmintrin.h>

#include "layout/crc32c.h"

namespace rtp {
namespace {

struct Table {
  uint32_t t[256];
  Table() {
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;
      t[i] = c;
    }
  }
};

// Polynomial arithmetic in CRC-32C's reflected domain (as zlib's crc32_combine): a * b mod P, and
// x^(8n) mod P, the operator that moves a CRC register past n zero bytes.
uint32_t mult_mod_p(uint32_t a, uint32_t b) {
  uint32_t m = 1u << 31, p = 0;
  for (;;) {
    if (a & m) {
      p ^= b;
      if ((a & (m - 1)) == 0) break;
    }
    m >>= 1;
    b = (b & 1) ? (b >> 1) ^ 0x82F63B78u : b >> 1;
  }
  return p;
}

uint32_t x8n_mod_p(uint64_t n) {  // square-and-multiply over x^(2^k)
  uint32_t p = 1u << 31;          // x^0
  uint32_t x2k = 1u << 23;        // x^8: one byte
  for (; n; n >>= 1) {
    if (n & 1) p = mult_mod_p(x2k, p);
    x2k = mult_mod_p(x2k, x2k);
  }
  return p;
}

__attribute__((target("sse4.2"))) uint64_t crc_words(uint64_t c, const uint8_t* p, size_t words) {
  for (size_t i = 0; i < words; ++i) {
    uint64_t v;
    std::memcpy(&v, p + 8 * i, 8);
    c = _mm_crc32_u64(c, v);
  }
  return c;
}

// Large inputs as three interleaved streams: crc32 has a latency of 3 cycles and a throughput of 1, so
// one stream uses a third of the unit. Each stream's register (the second and third from 0) is moved past
// the bytes after it and the three are XORed: the CRC register is linear in the bytes (Intel, "Fast CRC
// Computation for iSCSI Polynomial Using CRC32 Instruction", 2011, §3).
__attribute__((target("sse4.2"))) uint32_t crc32c_hw(const uint8_t* p, size_t n, uint32_t crc) {
  uint64_t c = ~crc;
  constexpr size_t kStripe = 8 * 4096;  // bytes per stream per step: the shift operator computed once
  static const uint32_t shift = x8n_mod_p(kStripe);
  while (n >= 3 * kStripe) {
    uint64_t a = c, b = 0, d = 0;
    const uint8_t* q = p;
    for (size_t i = 0; i < kStripe / 8; ++i) {
      uint64_t va, vb, vd;
      std::memcpy(&va, q, 8);
      std::memcpy(&vb, q + kStripe, 8);
      std::memcpy(&vd, q + 2 * kStripe, 8);
      a = _mm_crc32_u64(a, va);
      b = _mm_crc32_u64(b, vb);
      d = _mm_crc32_u64(d, vd);
      q += 8;
    }
    c = mult_mod_p(shift, mult_mod_p(shift, uint32_t(a)) ^ uint32_t(b)) ^ uint32_t(d);
    p += 3 * kStripe;
    n -= 3 * kStripe;
  }
  c = crc_words(c, p, n / 8);
  p += n / 8 * 8;
  n %= 8;
  uint32_t c32 = uint32_t(c);
  while (n--) c32 = _mm_crc32_u8(c32, *p++);
  return ~c32;
}

}  // namespace

uint32_t crc32c_portable(const void* data, size_t size, uint32_t crc) {
  static const Table table;
  const uint8_t* p = static_cast<const uint8_t*>(data);
  uint32_t c = ~crc;
  for (size_t i = 0; i < size; ++i) c = table.t[(c ^ p[i]) & 0xFF] ^ (c >> 8);
  return ~c;
}

uint32_t crc32c(const void* data, size_t size, uint32_t crc) {
  static const bool hw = __builtin_cpu_supports("sse4.2");
  return hw ? crc32c_hw(static_cast<const uint8_t*>(data), size, crc) : crc32c_portable(data, size, crc);
}

}  // namespace rtp
