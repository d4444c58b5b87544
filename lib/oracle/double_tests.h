#pragma once
// The double-precision ray tests both exact references share (reference.cpp, instance_reference.cpp).
#include <algorithm>
#include <cmath>
#include <utility>

namespace rtp::oracle_detail {

// Slab test in double on a padded box, widened by a relative 1e-9 in t: true when the ray may pass the
// box within [t0, t1]. Conservative: it only skips work, so it must never cut a hit.
inline bool slab_may_hit(const double o[3], const double d[3], const double lo[3], const double hi[3], double t0, double t1) {
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    if (std::isnan(ta) || std::isnan(tb)) continue;  // inf box vs inf ray: do not cull
    const double slack = 1e-9 * (std::abs(ta) + std::abs(tb)) + 1e-300;
    t0 = std::max(t0, ta - slack);
    t1 = std::min(t1, tb + slack);
    if (t0 > t1) return false;
  }
  return true;
}

// Pads a double box by a relative 1e-9 of its coordinates and extent (conservative culling boxes).
inline void pad_box(double lo[3], double hi[3]) {
  for (int a = 0; a < 3; ++a) {
    const double pad = 1e-9 * (std::abs(lo[a]) + std::abs(hi[a]) + (hi[a] - lo[a])) + 1e-300;
    lo[a] -= pad;
    hi[a] += pad;
  }
}

// Moller & Trumbore 1997 "Fast, Minimum Storage Ray/Triangle Intersection" §2, in double, two-sided:
// the hit (t, u, v) with u, v the weights of v0 + e1, v0 + e2, when t is in [tnear, tfar].
inline bool moller_trumbore(const double o[3], const double d[3], const double v0[3], const double e1[3], const double e2[3],
                            double tnear, double tfar, double* t_out, double* u_out, double* v_out) {
  const double px = d[1] * e2[2] - d[2] * e2[1];
  const double py = d[2] * e2[0] - d[0] * e2[2];
  const double pz = d[0] * e2[1] - d[1] * e2[0];
  const double det = e1[0] * px + e1[1] * py + e1[2] * pz;
  if (det == 0 || !std::isfinite(det)) return false;
  const double inv = 1.0 / det;
  const double sx = o[0] - v0[0], sy = o[1] - v0[1], sz = o[2] - v0[2];
  const double u = (sx * px + sy * py + sz * pz) * inv;
  if (!(u >= 0 && u <= 1)) return false;
  const double qx = sy * e1[2] - sz * e1[1];
  const double qy = sz * e1[0] - sx * e1[2];
  const double qz = sx * e1[1] - sy * e1[0];
  const double v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv;
  if (!(v >= 0 && u + v <= 1)) return false;
  const double t = (e2[0] * qx + e2[1] * qy + e2[2] * qz) * inv;
  if (!(t >= tnear && t <= tfar)) return false;
  *t_out = t, *u_out = u, *v_out = v;
  return true;
}

}  // namespace rtp::oracle_detail
