#pragma once
// Per-ray set-up (see ray_setup.h for the structs): validity, the instance transform, the forms the
// kernels read. Inline in each ISA translation unit's own namespace: it runs once per ray and once
// per instance visit, too often for an out-of-line call.
#include <cfloat>
#include <cmath>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"
#include "trace/ray_setup.h"

#ifndef RTP_ISA_NS
#error "define RTP_ISA_NS before including lib/trace kernel headers"
#endif

namespace rtp::RTP_ISA_NS {

RTP_KERNEL_INLINE bool ray_is_valid(const fmt::Ray& ray) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(ray.org[a]) || !std::isfinite(ray.dir[a])) return false;
  // NaN fails both comparisons; tnear = +inf would leave only t = +inf, which is never a hit.
  return ray.tnear <= ray.tfar && ray.tnear < INFINITY;
}

RTP_KERNEL_INLINE bool direction_usable(const float dir[3]) { return dir[0] != 0.0f || dir[1] != 0.0f || dir[2] != 0.0f; }

RTP_KERNEL_INLINE void setup_box_ray(const float org[3], const float dir[3], float tnear, detail::BoxRay* out) {
  out->octant = 0;
  for (int a = 0; a < 3; ++a) {
    out->org[a] = org[a];
    const bool neg = std::signbit(dir[a]);
    // ±0 gives ±inf without dividing by zero; a denormal may round to ±inf, the same limit.
    out->rcp[a] = dir[a] == 0.0f ? (neg ? -INFINITY : INFINITY) : 1.0f / dir[a];
    out->neg[a] = neg ? 1 : 0;
    out->octant = static_cast<uint8_t>(out->octant | (neg ? 1u << a : 0u));
  }
  out->tnear = tnear;
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
  const float* m = inst.inverse_linear;
  return inst.translation[0] == 0 && inst.translation[1] == 0 && inst.translation[2] == 0 && m[0] == 1.0f &&
         m[4] == 1.0f && m[8] == 1.0f && m[1] == 0.0f && m[2] == 0.0f && m[3] == 0.0f && m[5] == 0.0f && m[6] == 0.0f &&
         m[7] == 0.0f;
}

// SPEC §2.4: org' = L^-1 (org - T), dir' = L^-1 dir in double, T the double translation kept apart
// (issue 11: a float 3x4 inverse put a small instance at 3e6 up to 0.25 units off). org - T is exact
// to 2^-53 of the larger magnitude and products of floats are exact in double, so the only rounding
// that matters is the final one to float, relative to the local coordinates.
RTP_KERNEL_INLINE bool transform_ray(const fmt::InstanceRecord& inst, const float org[3], const float dir[3], float out_org[3],
                          float out_dir[3]) {
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
  return direction_usable(out_dir);
}

}  // namespace rtp::RTP_ISA_NS
