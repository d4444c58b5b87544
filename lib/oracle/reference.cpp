#include "oracle/reference.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/error.h"
#include "oracle/double_tests.h"
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
    // Pad generously (relative 1e-9): the box only skips work and must never cut a hit.
    oracle_detail::pad_box(c.lo, c.hi);
    for (int a = 0; a < 3; ++a) {
      c.lo[a] = finite ? c.lo[a] : -kInfD;
      c.hi[a] = finite ? c.hi[a] : kInfD;
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
    if (!oracle_detail::slab_may_hit(o, d, c.lo, c.hi, tnear, std::min(tfar, best))) continue;
    for (uint32_t k = c.first; k < c.first + c.count; ++k) {
      const Tri& tr = tris_[k];
      double t, u, v;
      if (!oracle_detail::moller_trumbore(o, d, tr.v0, tr.e1, tr.e2, tnear, tfar, &t, &u, &v)) continue;
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

void ExactReference::closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n) const {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      if (ray_status(rays[i]) == RayStatus::kInvalid) {
        hits[i] = {std::numeric_limits<float>::infinity(), fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
        continue;
      }
      trace_ray(rays[i], &hits[i]);
    }
  });
}

void ExactReference::occluded(const fmt::Ray* rays, uint8_t* occluded, size_t n) const {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i)
      occluded[i] = ray_status(rays[i]) != RayStatus::kInvalid && trace_ray(rays[i], nullptr) ? 1 : 0;
  });
}

bool BruteForceReference::trace_ray(const fmt::Ray& ray, fmt::Hit* hit) const {
  return hit ? trace<false>(ray, hit) : trace<true>(ray, nullptr);
}

}  // namespace rtp
