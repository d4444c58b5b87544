#include "oracle/reference.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "oracle/embree_oracle.h"

namespace rtp {
namespace {

constexpr uint32_t kClusterSize = 32;
constexpr double kInfD = std::numeric_limits<double>::infinity();

}  // namespace

BruteForceReference::BruteForceReference(const Scene& scene, uint64_t max_triangles) {
  const uint64_t total = scene.instanced_triangles();
  if (total > max_triangles)
    throw Error(ExitCode::kInputInvalid, "brute-force reference: " + std::to_string(total) +
                                             " instanced triangles exceed the limit of " + std::to_string(max_triangles));
  tris_.reserve(total);
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh >= scene.meshes.size()) continue;
    const Mesh& mesh = scene.meshes[inst.mesh];
    const size_t n = mesh.indices.size() / 3;
    for (size_t p = 0; p < n; ++p) {
      Vec3d w[3];
      for (int k = 0; k < 3; ++k) w[k] = inst.transform.apply(to_d(mesh.positions[mesh.indices[3 * p + k]]));
      Tri t;
      for (int a = 0; a < 3; ++a) {
        t.v0[a] = w[0][a];
        t.e1[a] = w[1][a] - w[0][a];
        t.e2[a] = w[2][a] - w[0][a];
      }
      t.instance = uint32_t(i);
      t.prim = uint32_t(p);
      tris_.push_back(t);
    }
  }
  for (uint32_t first = 0; first < tris_.size(); first += kClusterSize) {
    Cluster c;
    c.first = first;
    c.count = std::min<uint32_t>(kClusterSize, uint32_t(tris_.size()) - first);
    for (int a = 0; a < 3; ++a) {
      c.lo[a] = kInfD;
      c.hi[a] = -kInfD;
    }
    bool finite = true;
    for (uint32_t k = first; k < first + c.count; ++k) {
      const Tri& t = tris_[k];
      for (int a = 0; a < 3; ++a) {
        const double p[3] = {t.v0[a], t.v0[a] + t.e1[a], t.v0[a] + t.e2[a]};
        for (double x : p) {
          finite = finite && std::isfinite(x);
          c.lo[a] = std::min(c.lo[a], x);
          c.hi[a] = std::max(c.hi[a], x);
        }
      }
    }
    for (int a = 0; a < 3; ++a) {
      // Pad generously (relative 1e-9): the box only skips work and must never cut a hit.
      const double pad = 1e-9 * (std::abs(c.lo[a]) + std::abs(c.hi[a]) + (c.hi[a] - c.lo[a])) + 1e-300;
      c.lo[a] = finite ? c.lo[a] - pad : -kInfD;
      c.hi[a] = finite ? c.hi[a] + pad : kInfD;
    }
    clusters_.push_back(c);
  }
}

template <bool kAny>
bool BruteForceReference::trace(const fmt::Ray& ray, fmt::Hit* hit) const {
  const double o[3] = {ray.org[0], ray.org[1], ray.org[2]};
  const double d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
  const double tnear = ray.tnear, tfar = ray.tfar;
  double best = kInfD;
  uint32_t best_inst = fmt::Hit::kNone, best_prim = fmt::Hit::kNone;
  double best_u = 0, best_v = 0;
  for (const Cluster& c : clusters_) {
    // Slab test in double on the padded box, widened by a relative 1e-9 in t.
    double t0 = tnear, t1 = std::min(tfar, best);
    bool reject = false;
    for (int a = 0; a < 3 && !reject; ++a) {
      if (d[a] == 0) {
        reject = o[a] < c.lo[a] || o[a] > c.hi[a];
        continue;
      }
      double ta = (c.lo[a] - o[a]) / d[a], tb = (c.hi[a] - o[a]) / d[a];
      if (ta > tb) std::swap(ta, tb);
      if (std::isnan(ta) || std::isnan(tb)) continue;  // inf box vs inf ray: do not cull
      const double slack = 1e-9 * (std::abs(ta) + std::abs(tb)) + 1e-300;
      t0 = std::max(t0, ta - slack);
      t1 = std::min(t1, tb + slack);
      reject = t0 > t1;
    }
    if (reject) continue;
    for (uint32_t k = c.first; k < c.first + c.count; ++k) {
      const Tri& tr = tris_[k];
      const double px = d[1] * tr.e2[2] - d[2] * tr.e2[1];
      const double py = d[2] * tr.e2[0] - d[0] * tr.e2[2];
      const double pz = d[0] * tr.e2[1] - d[1] * tr.e2[0];
      const double det = tr.e1[0] * px + tr.e1[1] * py + tr.e1[2] * pz;
      if (det == 0 || !std::isfinite(det)) continue;
      const double inv = 1.0 / det;
      const double sx = o[0] - tr.v0[0], sy = o[1] - tr.v0[1], sz = o[2] - tr.v0[2];
      const double u = (sx * px + sy * py + sz * pz) * inv;
      if (!(u >= 0 && u <= 1)) continue;
      const double qx = sy * tr.e1[2] - sz * tr.e1[1];
      const double qy = sz * tr.e1[0] - sx * tr.e1[2];
      const double qz = sx * tr.e1[1] - sy * tr.e1[0];
      const double v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv;
      if (!(v >= 0 && u + v <= 1)) continue;
      const double t = (tr.e2[0] * qx + tr.e2[1] * qy + tr.e2[2] * qz) * inv;
      if (!(t >= tnear && t <= tfar)) continue;
      if constexpr (kAny) {
        return true;
      } else {
        if (t < best || (t == best && (tr.instance < best_inst || (tr.instance == best_inst && tr.prim < best_prim)))) {
          best = t;
          best_inst = tr.instance;
          best_prim = tr.prim;
          best_u = u;
          best_v = v;
        }
      }
    }
  }
  if constexpr (!kAny) {
    if (best_inst == fmt::Hit::kNone) {
      *hit = {std::numeric_limits<float>::infinity(), fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
    } else {
      *hit = {float(best), best_inst, best_prim, float(best_u), float(best_v)};
    }
  }
  return best_inst != fmt::Hit::kNone;
}

void BruteForceReference::closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n) const {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      if (ray_status(rays[i]) == RayStatus::kInvalid) {
        hits[i] = {std::numeric_limits<float>::infinity(), fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
        continue;
      }
      trace<false>(rays[i], &hits[i]);
    }
  });
}

void BruteForceReference::occluded(const fmt::Ray* rays, uint8_t* occluded, size_t n) const {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i)
      occluded[i] = ray_status(rays[i]) != RayStatus::kInvalid && trace<true>(rays[i], nullptr) ? 1 : 0;
  });
}

}  // namespace rtp
