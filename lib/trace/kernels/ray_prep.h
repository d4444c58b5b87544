#pragma once
// Per-ray set-up (see ray_setup.h for the structs): validity, the instance transform, the forms the
// kernels read. Inline in each ISA translation unit's own namespace: it runs once per ray and once
// per instance visit, too often for an out-of-line call.
#if defined(__AVX2__)
#include <immintrin.h>
#else
#include <xmmintrin.h>
#endif

#include <cfloat>
#include <cmath>
#include <cstddef>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"
#include "trace/kernels/ray_setup.h"
#include "layout/scene_view.h"

#ifndef RTP_ISA_NS
#error "define RTP_ISA_NS before including lib/trace kernel headers"
#endif

namespace rtp::RTP_ISA_NS {

RTP_KERNEL_INLINE bool ray_is_valid(const fmt::Ray& ray) {
#if defined(__AVX2__)
  // x − x is 0 exactly when x is finite (NaN for ±inf and NaN): the six components in one compare.
  // Lanes 3 and 7 are tnear and tfar (fmt::Ray's layout), checked below. Two 16-byte loads: a ray written
  // as two halves (the package tracer's per-point copies) forwards each from one store, which one 32-byte
  // load cannot (issue 11: a failed forward cost more than the check).
  const __m256 v = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(ray.org)), _mm_loadu_ps(ray.dir), 1);
  const int finite = _mm256_movemask_ps(_mm256_cmp_ps(_mm256_sub_ps(v, v), _mm256_setzero_ps(), _CMP_EQ_OQ));
  if ((finite & 0x77) != 0x77) return false;
#else
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(ray.org[a]) || !std::isfinite(ray.dir[a])) return false;
#endif
  // NaN fails both comparisons; tnear = +inf would leave only t = +inf, which is never a hit.
  return ray.tnear <= ray.tfar && ray.tnear < INFINITY;
}

RTP_KERNEL_INLINE bool direction_usable(const float dir[3]) {
  // One compare (issue 11: three scalar compares and branches ran per ray and per instance visit).
  return (_mm_movemask_ps(_mm_cmpneq_ps(_mm_setr_ps(dir[0], dir[1], dir[2], 0.0f), _mm_setzero_ps())) & 7) != 0;
}

// The three reciprocals in one SSE division (issue 11: three scalar divides ran per ray and per instance
// visit). IEEE division gives what the scalar form gave: ±inf for ±0 (sign kept), ±inf for a denormal
// whose reciprocal overflows, 1/x rounded to nearest otherwise; the signs come from the sign bits.
// The BoxRay is written as two 16-byte rows, (org, ·) then (rcp, tnear), as store_box_rays4 does (issue 11:
// field by field, the 16-byte loads that read it next — move_ray_by_axes's rcp, the compiler's merged
// loads of org — waited for a failed store-to-load forward; on far.glb's shadow rays, half of trace_one's
// time sat on one such load).
RTP_KERNEL_INLINE void setup_box_ray(const float org[3], const float dir[3], float tnear, detail::BoxRay* out) {
  static_assert(offsetof(detail::BoxRay, rcp) == 12 && offsetof(detail::BoxRay, tnear) == 24);
  const __m128 d = _mm_setr_ps(dir[0], dir[1], dir[2], 1.0f);
  const __m128 rcp = _mm_div_ps(_mm_set1_ps(1.0f), d);
  const __m128 rcp_t = _mm_shuffle_ps(rcp, _mm_unpackhi_ps(rcp, _mm_set1_ps(tnear)), _MM_SHUFFLE(1, 0, 1, 0));
  float* b = reinterpret_cast<float*>(out);
  _mm_storeu_ps(b, _mm_setr_ps(org[0], org[1], org[2], 0.0f));  // org, then rcp[0] (written next)
  _mm_storeu_ps(b + 3, rcp_t);                                  // rcp[0..2], tnear
  out->octant = static_cast<uint8_t>(_mm_movemask_ps(d) & 7);
}

// Woop, Benthin, Wald 2013 "Watertight Ray/Triangle Intersection" §3, per-ray pre-computation.
RTP_KERNEL_INLINE void setup_tri_ray(const float org[3], const float dir[3], float tnear, detail::TriRay* out) {
  const float ax = std::fabs(dir[0]), ay = std::fabs(dir[1]), az = std::fabs(dir[2]);
  int kz = 0;
  if (ay > ax) kz = 1;
  if (az > (kz == 0 ? ax : ay)) kz = 2;
  int kx = kz == 2 ? 0 : kz + 1;
  int ky = kx == 2 ? 0 : kx + 1;
  if (dir[kz] < 0.0f) {
    const int tmp = kx;
    kx = ky;
    ky = tmp;
  }
  out->kx = kx;
  out->ky = ky;
  out->kz = kz;
  out->org_k[0] = org[kx];
  out->org_k[1] = org[ky];
  out->org_k[2] = org[kz];
  out->dir_k[0] = dir[kx];
  out->dir_k[1] = dir[ky];
  out->dir_k[2] = dir[kz];
  // dir[kz] != 0: callers check direction_usable().
  out->sx = dir[kx] / dir[kz];
  out->sy = dir[ky] / dir[kz];
  out->tnear = tnear;
}

// A record that moves no ray: T = 0 and L^-1 = I exactly. transform_ray would return the world ray bit
// for bit (x - 0 and 1·x + 0·y + 0·z are exact in double), so walks skip it (glTF nodes without a
// transform are most instances of many scenes).
RTP_KERNEL_INLINE bool moves_no_ray(const fmt::InstanceRecord& inst) {
#if defined(__AVX2__)
  // The same twelve comparisons in three vector compares (reads stay inside the record: the fourth double
  // of the translation load is inverse_linear[0..1], masked out).
  const __m256d t = _mm256_cmp_pd(_mm256_loadu_pd(inst.translation), _mm256_setzero_pd(), _CMP_EQ_OQ);
  const __m256 l = _mm256_cmp_ps(_mm256_loadu_ps(inst.inverse_linear), _mm256_setr_ps(1, 0, 0, 0, 1, 0, 0, 0), _CMP_EQ_OQ);
  return (_mm256_movemask_pd(t) & 7) == 7 && _mm256_movemask_ps(l) == 0xFF && inst.inverse_linear[8] == 1.0f;
#else
  const float* m = inst.inverse_linear;
  return inst.translation[0] == 0 && inst.translation[1] == 0 && inst.translation[2] == 0 && m[0] == 1.0f && m[4] == 1.0f &&
         m[8] == 1.0f && m[1] == 0.0f && m[2] == 0.0f && m[3] == 0.0f && m[5] == 0.0f && m[6] == 0.0f && m[7] == 0.0f;
#endif
}

#if defined(__AVX2__)
// transform_ray's operands in registers: the columns of L^-1 in double and T. Built once per instance
// visit, so a packet moves its rays with the record's loads, transpose and conversions done once
// (issue 11: per lane they were repeated, the stores to the lanes' rays keeping the compiler from
// hoisting them). apply() is transform_ray's AVX2 form, the same operations lane by lane.
struct InstanceMove {
  __m256d c0, c1, c2, t;
  RTP_KERNEL_INLINE explicit InstanceMove(const fmt::InstanceRecord& inst) {
    // Reads stay inside the record (rows of 4 floats from 24, 36, 48; the last one's fourth is `mesh`).
    const float* m = inst.inverse_linear;
    __m128 r0 = _mm_loadu_ps(m), r1 = _mm_loadu_ps(m + 3), r2 = _mm_loadu_ps(m + 6), r3 = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);  // r0..r2: the columns (m[c], m[3+c], m[6+c], garbage)
    c0 = _mm256_cvtps_pd(r0), c1 = _mm256_cvtps_pd(r1), c2 = _mm256_cvtps_pd(r2);
    t = _mm256_setr_pd(inst.translation[0], inst.translation[1], inst.translation[2], 0.0);
  }
  // Lane r computes (m[3r]·x + m[3r+1]·y) + m[3r+2]·z in double, then rounds to float, exactly as the
  // scalar form of transform_ray (issue 11: that form cost ~75 instructions per instance visit).
  // out_org and out_dir get 4 floats each, the 4th 0.
  RTP_KERNEL_INLINE bool apply(const float org[3], const float dir[3], float out_org[4], float out_dir[4]) const {
    const __m256d rel = _mm256_sub_pd(_mm256_cvtps_pd(_mm_setr_ps(org[0], org[1], org[2], 0.0f)), t);
    const __m256d d = _mm256_cvtps_pd(_mm_setr_ps(dir[0], dir[1], dir[2], 0.0f));
    const __m256d o = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(c0, _mm256_permute4x64_pd(rel, 0x00)), _mm256_mul_pd(c1, _mm256_permute4x64_pd(rel, 0x55))),
        _mm256_mul_pd(c2, _mm256_permute4x64_pd(rel, 0xAA)));
    const __m256d v = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(c0, _mm256_permute4x64_pd(d, 0x00)), _mm256_mul_pd(c1, _mm256_permute4x64_pd(d, 0x55))),
        _mm256_mul_pd(c2, _mm256_permute4x64_pd(d, 0xAA)));
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    const __m256d limit = _mm256_set1_pd(double(FLT_MAX));
    const int in_range = _mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(o, abs_mask), limit, _CMP_LE_OQ)) &
                         _mm256_movemask_pd(_mm256_cmp_pd(_mm256_and_pd(v, abs_mask), limit, _CMP_LE_OQ));
    if ((in_range & 7) != 7) return false;  // also NaN
    // Whole rows, lane 3 masked to +0 (it holds ±0 products), so that the loads that read them next are
    // forwarded from one store (see setup_box_ray).
    const __m128 keep3 = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
    const __m128 fdv = _mm_and_ps(_mm256_cvtpd_ps(v), keep3);
    _mm_storeu_ps(out_org, _mm_and_ps(_mm256_cvtpd_ps(o), keep3));
    _mm_storeu_ps(out_dir, fdv);
    return (_mm_movemask_ps(_mm_cmpneq_ps(fdv, _mm_setzero_ps())) & 7) != 0;  // direction_usable
  }
};

// Four fmt::Rays ({org[3], tnear, dir[3], tfar}: two rows of four each) transposed to SoA: lane k of
// every vector is ray k.
struct Rays4 {
  __m128 o[3], tnear, d[3], tfar;
};
RTP_KERNEL_INLINE Rays4 load_rays4(const fmt::Ray* rays) {
  Rays4 r;
  r.o[0] = _mm_loadu_ps(rays[0].org), r.o[1] = _mm_loadu_ps(rays[1].org);
  r.o[2] = _mm_loadu_ps(rays[2].org), r.tnear = _mm_loadu_ps(rays[3].org);
  _MM_TRANSPOSE4_PS(r.o[0], r.o[1], r.o[2], r.tnear);
  r.d[0] = _mm_loadu_ps(rays[0].dir), r.d[1] = _mm_loadu_ps(rays[1].dir);
  r.d[2] = _mm_loadu_ps(rays[2].dir), r.tfar = _mm_loadu_ps(rays[3].dir);
  _MM_TRANSPOSE4_PS(r.d[0], r.d[1], r.d[2], r.tfar);
  return r;
}

// setup_box_ray for four rays given in SoA (origins o, directions d, tnear): one IEEE division per axis
// and the sign bits for the octant, so each BoxRay gets setup_box_ray's bits. Also, when given, each
// ray's octant into octants[k] and its origin and direction as rows (x, y, z, 0) into org[k], dir[k].
RTP_KERNEL_INLINE void store_box_rays4(const __m128 o[3], const __m128 d[3], __m128 tnear, detail::BoxRay* box, uint8_t* octants,
                                       float (*org)[4] = nullptr, float (*dir)[4] = nullptr) {
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
  __m128 rcp0 = _mm_div_ps(one, d[0]), rcp1 = _mm_div_ps(one, d[1]), rcp2 = _mm_div_ps(one, d[2]);
  const __m128i sign0 = _mm_srli_epi32(_mm_castps_si128(d[0]), 31);
  const __m128i sign1 = _mm_slli_epi32(_mm_srli_epi32(_mm_castps_si128(d[1]), 31), 1);
  const __m128i sign2 = _mm_slli_epi32(_mm_srli_epi32(_mm_castps_si128(d[2]), 31), 2);
  alignas(16) uint32_t octant[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(octant), _mm_or_si128(_mm_or_si128(sign0, sign1), sign2));
  __m128 ox = o[0], oy = o[1], oz = o[2], ow = zero;
  __m128 vx = d[0], vy = d[1], vz = d[2], vw = zero;
  _MM_TRANSPOSE4_PS(ox, oy, oz, ow);  // rows: ray 0..3's (x, y, z, 0)
  _MM_TRANSPOSE4_PS(vx, vy, vz, vw);
  _MM_TRANSPOSE4_PS(rcp0, rcp1, rcp2, tnear);  // rows: ray 0..3's (1/x, 1/y, 1/z, tnear)
  const __m128 orow[4] = {ox, oy, oz, ow}, vrow[4] = {vx, vy, vz, vw}, rrow[4] = {rcp0, rcp1, rcp2, tnear};
  static_assert(offsetof(detail::BoxRay, rcp) == 12 && offsetof(detail::BoxRay, tnear) == 24 &&
                offsetof(detail::BoxRay, octant) == 28 && sizeof(detail::BoxRay) == 32);
  for (int k = 0; k < 4; ++k) {
    float* b = reinterpret_cast<float*>(&box[k]);
    _mm_storeu_ps(b, orow[k]);      // org, then rcp[0] (written next)
    _mm_storeu_ps(b + 3, rrow[k]);  // rcp, tnear
    box[k].octant = uint8_t(octant[k]);
    if (octants) octants[k] = uint8_t(octant[k]);
    if (org) _mm_storeu_ps(org[k], orow[k]);
    if (dir) _mm_storeu_ps(dir[k], vrow[k]);
  }
}

// ray_is_valid, direction_usable and setup_box_ray for four world rays at once, in SoA (issue 11: a
// packet's lanes were set up one by one, ≈40 instructions each): the same compares, and store_box_rays4,
// so each valid lane's BoxRay has setup_box_ray's bits (the boxes of invalid lanes are not to be read).
// Returns bit k: ray k is valid with a usable direction; *invalid gets bit k for a ray that is not
// valid; octants[k] = box[k].octant.
RTP_KERNEL_INLINE uint32_t setup_box_rays4(const fmt::Ray* rays, detail::BoxRay* box, uint32_t* invalid, uint8_t octants[4]) {
  const Rays4 r = load_rays4(rays);
  const __m128 zero = _mm_setzero_ps();
  auto finite = [&](__m128 x) { return _mm_cmpeq_ps(_mm_sub_ps(x, x), zero); };  // x - x == 0 exactly
  // ray_is_valid: every component finite; tnear <= tfar and tnear < inf (NaN fails both).
  __m128 ok = _mm_and_ps(_mm_and_ps(finite(r.o[0]), finite(r.o[1])), _mm_and_ps(finite(r.o[2]), finite(r.d[0])));
  ok = _mm_and_ps(ok, _mm_and_ps(finite(r.d[1]), finite(r.d[2])));
  ok = _mm_and_ps(ok, _mm_and_ps(_mm_cmple_ps(r.tnear, r.tfar), _mm_cmplt_ps(r.tnear, _mm_set1_ps(INFINITY))));
  const int valid = _mm_movemask_ps(ok);
  const int usable = _mm_movemask_ps(
      _mm_or_ps(_mm_or_ps(_mm_cmpneq_ps(r.d[0], zero), _mm_cmpneq_ps(r.d[1], zero)), _mm_cmpneq_ps(r.d[2], zero)));
  store_box_rays4(r.o, r.d, r.tnear, box, octants);
  *invalid = uint32_t(~valid & 0xF);
  return uint32_t(valid & usable);
}

// InstanceMove::apply and setup_box_ray for four rays at once, the rays in SoA: L^-1's entries and T
// broadcast, lane k of every vector is ray k (issue 11: a packet through a moved instance spent ≈100
// instructions per lane moving its rays one at a time — the transpose, the permutes, the scalar
// stores). Row r is (m[3r]·x + m[3r+1]·y) + m[3r+2]·z in double as in apply(), the same products and sums
// in the same order, then rounded to float; the reciprocals are one IEEE division as in setup_box_ray.
// So every lane gets apply's and setup_box_ray's bits.
struct InstanceMove4 {
  __m256d m[9], t[3];
  RTP_KERNEL_INLINE explicit InstanceMove4(const fmt::InstanceRecord& inst) {
    for (int k = 0; k < 9; ++k) m[k] = _mm256_set1_pd(double(inst.inverse_linear[k]));
    for (int a = 0; a < 3; ++a) t[a] = _mm256_set1_pd(inst.translation[a]);
  }
  // Moves rays[0..3] into org[0..3], dir[0..3] (rows of 4 floats, the 4th is 0) and box[0..3]. Bit k of
  // the result: ray k's local form is in float range with a usable direction (apply() returned true); the
  // rows of the others are not to be read.
  RTP_KERNEL_INLINE uint32_t apply(const fmt::Ray* rays, float (*org)[4], float (*dir)[4], detail::BoxRay* box) const {
    const Rays4 w = load_rays4(rays);
    const __m256d rx = _mm256_sub_pd(_mm256_cvtps_pd(w.o[0]), t[0]), ry = _mm256_sub_pd(_mm256_cvtps_pd(w.o[1]), t[1]),
                  rz = _mm256_sub_pd(_mm256_cvtps_pd(w.o[2]), t[2]);
    const __m256d dx = _mm256_cvtps_pd(w.d[0]), dy = _mm256_cvtps_pd(w.d[1]), dz = _mm256_cvtps_pd(w.d[2]);
    const __m256d abs_mask = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL));
    const __m256d limit = _mm256_set1_pd(double(FLT_MAX));
    __m256d in_range = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    __m128 fo[3], fd[3];
    for (int r = 0; r < 3; ++r) {
      const __m256d o = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(m[3 * r], rx), _mm256_mul_pd(m[3 * r + 1], ry)),
                                      _mm256_mul_pd(m[3 * r + 2], rz));
      const __m256d v = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(m[3 * r], dx), _mm256_mul_pd(m[3 * r + 1], dy)),
                                      _mm256_mul_pd(m[3 * r + 2], dz));
      in_range = _mm256_and_pd(in_range, _mm256_cmp_pd(_mm256_and_pd(o, abs_mask), limit, _CMP_LE_OQ));
      in_range = _mm256_and_pd(in_range, _mm256_cmp_pd(_mm256_and_pd(v, abs_mask), limit, _CMP_LE_OQ));
      fo[r] = _mm256_cvtpd_ps(o);
      fd[r] = _mm256_cvtpd_ps(v);
    }
    const __m128 zero = _mm_setzero_ps();
    const int usable =
        _mm_movemask_ps(_mm_or_ps(_mm_or_ps(_mm_cmpneq_ps(fd[0], zero), _mm_cmpneq_ps(fd[1], zero)), _mm_cmpneq_ps(fd[2], zero)));
    store_box_rays4(fo, fd, w.tnear, box, nullptr, org, dir);
    return uint32_t(_mm256_movemask_pd(in_range) & usable);
  }
};
#endif

// SPEC §2.4: org' = L^-1 (org - T), dir' = L^-1 dir in double, T the double translation kept apart
// (issue 11: a float 3x4 inverse put a small instance at 3e6 up to 0.25 units off). org - T is exact
// to 2^-53 of the larger magnitude and products of floats are exact in double, so the only rounding
// that matters is the final one to float, relative to the local coordinates.
RTP_KERNEL_INLINE bool transform_ray(const fmt::InstanceRecord& inst, const float org[3], const float dir[3], float out_org[4],
                                     float out_dir[4]) {
#if defined(__AVX2__)
  return InstanceMove(inst).apply(org, dir, out_org, out_dir);
#else
  const double rel[3] = {double(org[0]) - inst.translation[0], double(org[1]) - inst.translation[1],
                         double(org[2]) - inst.translation[2]};
  const float* m = inst.inverse_linear;
  for (int r = 0; r < 3; ++r) {
    const double o = double(m[3 * r]) * rel[0] + double(m[3 * r + 1]) * rel[1] + double(m[3 * r + 2]) * rel[2];
    const double d = double(m[3 * r]) * dir[0] + double(m[3 * r + 1]) * dir[1] + double(m[3 * r + 2]) * dir[2];
    if (!(std::fabs(o) <= FLT_MAX) || !(std::fabs(d) <= FLT_MAX)) return false;  // also NaN
    out_org[r] = static_cast<float>(o);
    out_dir[r] = static_cast<float>(d);
  }
  out_org[3] = 0.0f, out_dir[3] = 0.0f;
  return direction_usable(out_dir);
#endif
}

// An instance whose L^-1 is a signed permutation (AxisMove::kAxes): the local ray and its box form from
// the world ray's without the double products or the division (issue 11: ≈75 instructions per visit of
// such an instance). Row r of transform_ray is ±rel[axis[r]] plus two products 0·x: exact, and equal to
// it bit for bit unless a component is zero (then the zeros' signs could differ), so a ray with a zero
// component of org − T or of dir takes transform_ray (kGeneral). 1/(±d) = ±(1/d) exactly, so the
// reciprocals are the world's, permuted. kSkip where transform_ray returns false (out of float range).
enum class AxisMoveResult { kMoved, kSkip, kGeneral };

RTP_KERNEL_INLINE AxisMoveResult move_ray_by_axes(const fmt::InstanceRecord& inst, const AxisMove& mv, const fmt::Ray& ray,
                                                  const detail::BoxRay& world, float org[4], float dir[4], detail::BoxRay* box) {
#if defined(__AVX2__)
  // Lanes 0..2; lane 3 reads tnear (fmt::Ray, BoxRay) or the record's next bytes and is masked out.
  const __m256d rel = _mm256_sub_pd(_mm256_cvtps_pd(_mm_loadu_ps(ray.org)), _mm256_loadu_pd(inst.translation));
  const __m128 d = _mm_loadu_ps(ray.dir);
  const int rel_zero = _mm256_movemask_pd(_mm256_cmp_pd(rel, _mm256_setzero_pd(), _CMP_EQ_OQ));
  const int dir_zero = _mm_movemask_ps(_mm_cmpeq_ps(d, _mm_setzero_ps()));
  if ((rel_zero | dir_zero) & 7) return AxisMoveResult::kGeneral;
  const __m256d abs_rel = _mm256_and_pd(rel, _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffffLL)));
  if ((_mm256_movemask_pd(_mm256_cmp_pd(abs_rel, _mm256_set1_pd(double(FLT_MAX)), _CMP_LE_OQ)) & 7) != 7)
    return AxisMoveResult::kSkip;  // also NaN
  int32_t axes;
  __builtin_memcpy(&axes, mv.axis, 4);  // axis[0..2], neg (the index's low two bits are read)
  const __m128i idx = _mm_cvtepu8_epi32(_mm_cvtsi32_si128(axes));
  const __m128i bit = _mm_setr_epi32(1, 2, 4, 0);
  const __m128 sign = _mm_castsi128_ps(_mm_slli_epi32(_mm_cmpeq_epi32(_mm_and_si128(_mm_set1_epi32(mv.neg), bit), bit), 31));
  const __m128 o = _mm_xor_ps(_mm_permutevar_ps(_mm256_cvtpd_ps(rel), idx), sign);
  const __m128 v = _mm_xor_ps(_mm_permutevar_ps(d, idx), sign);
  const __m128 rcp = _mm_xor_ps(_mm_permutevar_ps(_mm_loadu_ps(world.rcp), idx), sign);
  _mm_storeu_ps(org, o);
  _mm_storeu_ps(dir, v);
  _mm_storeu_ps(box->org, o);    // org[0..2] and rcp[0], which the next store writes
  _mm_storeu_ps(box->rcp, rcp);  // rcp[0..2] and tnear, written next
  box->tnear = ray.tnear;
  box->octant = static_cast<uint8_t>(_mm_movemask_ps(v) & 7);
#else
  double rel[3];
  for (int a = 0; a < 3; ++a) {
    rel[a] = double(ray.org[a]) - inst.translation[a];
    if (rel[a] == 0 || ray.dir[a] == 0.0f) return AxisMoveResult::kGeneral;
  }
  for (int a = 0; a < 3; ++a)
    if (!(std::fabs(rel[a]) <= FLT_MAX)) return AxisMoveResult::kSkip;  // also NaN
  uint8_t octant = 0;
  for (int r = 0; r < 3; ++r) {
    const int a = mv.axis[r];
    const bool neg = (mv.neg >> r) & 1u;
    const float o = static_cast<float>(rel[a]);
    org[r] = neg ? -o : o;
    dir[r] = neg ? -ray.dir[a] : ray.dir[a];
    box->org[r] = org[r];
    box->rcp[r] = neg ? -world.rcp[a] : world.rcp[a];
    octant |= uint8_t((std::signbit(dir[r]) ? 1u : 0u) << r);
  }
  box->tnear = ray.tnear;
  box->octant = octant;
#endif
  return AxisMoveResult::kMoved;
}

}  // namespace rtp::RTP_ISA_NS
