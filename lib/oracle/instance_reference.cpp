#include "oracle/instance_reference.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "oracle/double_tests.h"

namespace rtp {
namespace instance_ref {  // named: unity builds merge this module's files

constexpr uint32_t kRun = 32;
constexpr double kInfD = std::numeric_limits<double>::infinity();

void empty_box(double lo[3], double hi[3]) {
  for (int a = 0; a < 3; ++a) lo[a] = kInfD, hi[a] = -kInfD;
}

void grow(double lo[3], double hi[3], const Vec3d& p) {
  for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
}

// The box of the eight corners of a local box moved to world space in double, padded; a non-finite
// corner gives the infinite box (never culls).
void world_box(const Affine3x4& m, const double lo[3], const double hi[3], double out_lo[3], double out_hi[3]) {
  empty_box(out_lo, out_hi);
  bool finite = true;
  for (int c = 0; c < 8; ++c) {
    const Vec3d w = m.apply(Vec3d{(c & 1) ? hi[0] : lo[0], (c & 2) ? hi[1] : lo[1], (c & 4) ? hi[2] : lo[2]});
    for (int a = 0; a < 3; ++a) finite = finite && std::isfinite(w[a]);
    grow(out_lo, out_hi, w);
  }
  oracle_detail::pad_box(out_lo, out_hi);
  if (!finite) empty_box(out_hi, out_lo);  // lo = -inf, hi = +inf
}

}  // namespace instance_ref

InstanceReference::InstanceReference(const Scene& scene) : scene_(scene) {
  runs_.resize(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    const uint32_t n = uint32_t(mesh.indices.size() / 3);
    for (uint32_t first = 0; first < n; first += instance_ref::kRun) {
      Run r;
      r.first = first;
      r.count = std::min(instance_ref::kRun, n - first);
      instance_ref::empty_box(r.lo, r.hi);
      for (uint32_t p = first; p < first + r.count; ++p)
        for (int k = 0; k < 3; ++k) instance_ref::grow(r.lo, r.hi, to_d(mesh.positions[mesh.indices[3 * size_t(p) + k]]));
      runs_[m].push_back(r);
    }
  }
  boxes_.resize(scene.instances.size());
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    WorldBox& b = boxes_[i];
    b.usable = inst.mesh < scene.meshes.size() && !runs_[inst.mesh].empty();
    if (!b.usable) continue;
    double lo[3], hi[3];
    instance_ref::empty_box(lo, hi);
    for (const Run& r : runs_[inst.mesh])
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], r.lo[a]), hi[a] = std::max(hi[a], r.hi[a]);
    instance_ref::world_box(inst.transform, lo, hi, b.lo, b.hi);
  }
}

template <bool kAny>
bool InstanceReference::trace(const fmt::Ray& ray, fmt::Hit* hit) const {
  const double o[3] = {ray.org[0], ray.org[1], ray.org[2]};
  const double d[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
  const double tnear = ray.tnear, tfar = ray.tfar;
  double best = instance_ref::kInfD, best_u = 0, best_v = 0;
  uint32_t best_inst = fmt::Hit::kNone, best_prim = fmt::Hit::kNone;
  for (size_t i = 0; i < boxes_.size(); ++i) {
    const WorldBox& b = boxes_[i];
    if (!b.usable || !oracle_detail::slab_may_hit(o, d, b.lo, b.hi, tnear, std::min(tfar, best))) continue;
    const Instance& inst = scene_.instances[i];
    const Mesh& mesh = scene_.meshes[inst.mesh];
    for (const Run& r : runs_[inst.mesh]) {
      double lo[3], hi[3];
      instance_ref::world_box(inst.transform, r.lo, r.hi, lo, hi);
      if (!oracle_detail::slab_may_hit(o, d, lo, hi, tnear, std::min(tfar, best))) continue;
      for (uint32_t p = r.first; p < r.first + r.count; ++p) {
        Vec3d w[3];
        for (int k = 0; k < 3; ++k) w[k] = inst.transform.apply(to_d(mesh.positions[mesh.indices[3 * size_t(p) + k]]));
        const double v0[3] = {w[0][0], w[0][1], w[0][2]};
        const double e1[3] = {w[1][0] - w[0][0], w[1][1] - w[0][1], w[1][2] - w[0][2]};
        const double e2[3] = {w[2][0] - w[0][0], w[2][1] - w[0][1], w[2][2] - w[0][2]};
        double t, u, v;
        if (!oracle_detail::moller_trumbore(o, d, v0, e1, e2, tnear, tfar, &t, &u, &v)) continue;
        if constexpr (kAny) return true;
        const uint32_t id = uint32_t(i);
        if (t < best || (t == best && (id < best_inst || (id == best_inst && p < best_prim)))) {
          best = t, best_inst = id, best_prim = p, best_u = u, best_v = v;
        }
      }
    }
  }
  if constexpr (!kAny) {
    if (best_inst == fmt::Hit::kNone)
      *hit = {std::numeric_limits<float>::infinity(), fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
    else
      *hit = {float(best), best_inst, best_prim, float(best_u), float(best_v)};
  }
  return best_inst != fmt::Hit::kNone;
}

bool InstanceReference::trace_ray(const fmt::Ray& ray, fmt::Hit* hit) const {
  return hit ? trace<false>(ray, hit) : trace<true>(ray, nullptr);
}

}  // namespace rtp
