#include "core/math.h"
#include "oracle/compare.h"

#include <algorithm>
#include <bit>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <limits>

#include "oracle/embree_oracle.h"
#include "oracle/reference.h"

namespace rtp {
namespace {

bool is_hit(const fmt::Hit& h) { return h.t < kInf; }  // NaN t is rejected first by classify_hit

std::string hit_str(const fmt::Hit& h) {
  char buf[200];
  if (!(h.t < kInf) && !std::isnan(h.t))
    std::snprintf(buf, sizeof buf, "miss (t=%.9g inst=%" PRIu32 " prim=%" PRIu32 ")", double(h.t), h.instance, h.prim);
  else
    std::snprintf(buf, sizeof buf, "t=%.9g inst=%" PRIu32 " prim=%" PRIu32 " u=%.9g v=%.9g (1-u-v=%.3g)", double(h.t), h.instance,
                  h.prim, double(h.u), double(h.v), 1.0 - double(h.u) - double(h.v));
  return buf;
}

void keep(std::vector<RayDiff>& list, size_t max, const RayDiff& d) {
  if (list.size() < max) list.push_back(d);
}

}  // namespace

const char* verdict_name(Verdict v) {
  switch (v) {
    case Verdict::kAgree: return "agree";
    case Verdict::kEdgeTie: return "edge-tie";
    case Verdict::kPrecisionTie: return "precision-tie";
    case Verdict::kFail: return "FAIL";
    case Verdict::kSkipped: return "skipped";
  }
  return "?";
}

bool near_edge(const fmt::Hit& h, double eps) {
  const double u = h.u, v = h.v, w = 1.0 - u - v;
  const double m = std::min({u, v, w});
  return m <= eps;  // false for NaN
}

namespace {

double inf_norm(const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// A hit's triangle in world space (double) and the coordinate magnitude M its float computation saw:
// ray origin, hit point, instance translation + scaled local vertices.
struct HitGeometry {
  Vec3d w[3];
  Vec3d p;  // ray point at the hit's t
  double mag = 0;
};

bool hit_geometry(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& h, HitGeometry& g) {
  if (!is_hit(h) || h.instance >= scene.instances.size()) return false;
  const Instance& inst = scene.instances[h.instance];
  if (inst.mesh >= scene.meshes.size()) return false;
  const Mesh& m = scene.meshes[inst.mesh];
  if (uint64_t(h.prim) >= m.triangle_count()) return false;
  double local = 0;
  for (int k = 0; k < 3; ++k) {
    const Vec3f& p = m.positions[m.indices[3 * size_t(h.prim) + k]];
    g.w[k] = inst.transform.apply(to_d(p));
    local = std::max(local, inf_norm(to_d(p)));
  }
  const Vec3d o = {ray.org[0], ray.org[1], ray.org[2]};
  g.p = o + Vec3d{ray.dir[0], ray.dir[1], ray.dir[2]} * double(h.t);
  const Vec3d translation = {inst.transform(0, 3), inst.transform(1, 3), inst.transform(2, 3)};
  g.mag = std::max({inf_norm(o), inf_norm(g.p), inf_norm(translation) + inst.transform.max_scale() * local});
  return true;
}

// Distance of point q from the plane of triangle w (infinite for a degenerate triangle).
double plane_distance(const Vec3d w[3], const Vec3d& q) {
  const Vec3d n = cross(w[1] - w[0], w[2] - w[0]);
  const double len = length(n);
  if (!(len > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(dot(q - w[0], n)) / len;
}

}  // namespace

bool near_edge_in_precision(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& h, double rel) {
  HitGeometry g;
  if (!hit_geometry(scene, ray, h, g)) return false;
  const double delta = rel * g.mag;
  // Distance to the edge opposite vertex i = barycentric_i * altitude_i, altitude_i = 2 area / |edge_i|.
  const double area2 = length(cross(g.w[1] - g.w[0], g.w[2] - g.w[0]));
  const double bary[3] = {1.0 - double(h.u) - double(h.v), double(h.u), double(h.v)};
  for (int i = 0; i < 3; ++i) {
    const double edge = length(g.w[(i + 2) % 3] - g.w[(i + 1) % 3]);
    const double dist = edge > 0 ? std::abs(bary[i]) * area2 / edge : 0.0;
    if (!(dist > delta)) return true;  // also for NaN
  }
  return false;
}

bool same_surface_in_precision(const Scene& scene, const fmt::Ray& ray, const fmt::Hit& ref, const fmt::Hit& got, double rel) {
  HitGeometry a, b;
  if (!hit_geometry(scene, ray, ref, a) || !hit_geometry(scene, ray, got, b)) return false;
  const double delta = rel * std::max(a.mag, b.mag);
  return plane_distance(a.w, b.p) <= delta && plane_distance(b.w, a.p) <= delta;
}

Verdict classify_hit(const fmt::Ray& ray, const fmt::Hit& ref, const fmt::Hit& got, const CompareOptions& o) {
  if (std::isnan(got.t) || std::isnan(ref.t)) return Verdict::kFail;
  const bool rh = is_hit(ref), gh = is_hit(got);
  if (!rh && !gh) return Verdict::kAgree;
  if (rh && gh && std::abs(double(got.t) - double(ref.t)) <= o.rel_tol * std::max(1.0, std::abs(double(ref.t))))
    return Verdict::kAgree;
  if ((rh && near_edge(ref, o.edge_eps)) || (gh && near_edge(got, o.edge_eps))) return Verdict::kEdgeTie;
  if (o.scene && ((rh && near_edge_in_precision(*o.scene, ray, ref, o.precision_rel)) ||
                  (gh && near_edge_in_precision(*o.scene, ray, got, o.precision_rel)) ||
                  (rh && gh && same_surface_in_precision(*o.scene, ray, ref, got, o.precision_rel))))
    return Verdict::kPrecisionTie;
  return Verdict::kFail;
}

std::array<uint32_t, 8> ray_bits(const fmt::Ray& r) {
  return {std::bit_cast<uint32_t>(r.org[0]), std::bit_cast<uint32_t>(r.org[1]), std::bit_cast<uint32_t>(r.org[2]),
          std::bit_cast<uint32_t>(r.tnear),  std::bit_cast<uint32_t>(r.dir[0]), std::bit_cast<uint32_t>(r.dir[1]),
          std::bit_cast<uint32_t>(r.dir[2]), std::bit_cast<uint32_t>(r.tfar)};
}

fmt::Ray ray_from_bits(const std::array<uint32_t, 8>& b) {
  fmt::Ray r;
  r.org[0] = std::bit_cast<float>(b[0]);
  r.org[1] = std::bit_cast<float>(b[1]);
  r.org[2] = std::bit_cast<float>(b[2]);
  r.tnear = std::bit_cast<float>(b[3]);
  r.dir[0] = std::bit_cast<float>(b[4]);
  r.dir[1] = std::bit_cast<float>(b[5]);
  r.dir[2] = std::bit_cast<float>(b[6]);
  r.tfar = std::bit_cast<float>(b[7]);
  return r;
}

std::string RayDiff::describe() const {
  char buf[512];
  const auto b = ray_bits(ray);
  std::snprintf(buf, sizeof buf,
                "ray #%zu [%s]\n  org=(%.9g, %.9g, %.9g) dir=(%.9g, %.9g, %.9g) tnear=%.9g tfar=%.9g\n"
                "  bits={0x%08" PRIx32 ", 0x%08" PRIx32 ", 0x%08" PRIx32 ", 0x%08" PRIx32 ", 0x%08" PRIx32 ", 0x%08" PRIx32
                ", 0x%08" PRIx32 ", 0x%08" PRIx32 "}  (rtp::ray_from_bits)\n",
                index, verdict_name(verdict), double(ray.org[0]), double(ray.org[1]), double(ray.org[2]), double(ray.dir[0]),
                double(ray.dir[1]), double(ray.dir[2]), double(ray.tnear), double(ray.tfar), b[0], b[1], b[2], b[3], b[4], b[5],
                b[6], b[7]);
  return std::string(buf) + "  ref: " + hit_str(ref) + "\n  got: " + hit_str(got) + "\n";
}

void CompareReport::merge(const CompareReport& o, size_t max_examples) {
  rays += o.rays;
  skipped += o.skipped;
  both_miss += o.both_miss;
  both_hit += o.both_hit;
  same_t_other_prim += o.same_t_other_prim;
  edge_ties += o.edge_ties;
  precision_ties += o.precision_ties;
  failures += o.failures;
  fail_missed += o.fail_missed;
  fail_extra += o.fail_extra;
  fail_t += o.fail_t;
  reference_errors += o.reference_errors;
  for (const RayDiff& d : o.first_failures) keep(first_failures, max_examples, d);
  for (const RayDiff& d : o.first_ties) keep(first_ties, max_examples, d);
}

std::string CompareReport::summary() const {
  char buf[500];
  std::snprintf(buf, sizeof buf,
                "%" PRIu64 " rays: %" PRIu64 " agree (%" PRIu64 " both miss, %" PRIu64 " both hit, %" PRIu64
                " of them other prim at same t), %" PRIu64 " edge ties, %" PRIu64 " precision ties, %" PRIu64
                " FAILURES (%" PRIu64 " missed, %" PRIu64 " extra, %" PRIu64 " other t), %" PRIu64 " skipped, %" PRIu64
                " reference errors settled by the double reference",
                rays, agree(), both_miss, both_hit, same_t_other_prim, edge_ties, precision_ties, failures, fail_missed,
                fail_extra, fail_t, skipped, reference_errors);
  return buf;
}

std::string CompareReport::details() const {
  std::string s = summary() + "\n";
  for (const RayDiff& d : first_failures) s += d.describe();
  for (const RayDiff& d : first_ties) s += d.describe();
  return s;
}

CompareReport compare_closest(const fmt::Ray* rays, const fmt::Hit* ref, const fmt::Hit* got, size_t n, const CompareOptions& o,
                              const uint8_t* skip) {
  CompareReport rep;
  rep.rays = n;
  std::vector<Verdict> verdict(n, Verdict::kSkipped);
  std::vector<size_t> disputed;
  for (size_t i = 0; i < n; ++i)
    if (!(skip && skip[i])) {
      verdict[i] = classify_hit(rays[i], ref[i], got[i], o);
      if (verdict[i] != Verdict::kAgree) disputed.push_back(i);
    }
  // TESTING.md "The oracle": the double reference decides the disputed rays (one batch: it is slow).
  std::vector<fmt::Hit> judge(n);
  std::vector<uint8_t> judged(n, 0);
  if (o.exact && !disputed.empty()) {
    std::vector<fmt::Ray> dr(disputed.size());
    std::vector<fmt::Hit> dh(disputed.size());
    for (size_t k = 0; k < disputed.size(); ++k) dr[k] = rays[disputed[k]];
    o.exact->closest(dr.data(), dh.data(), dr.size());
    for (size_t k = 0; k < disputed.size(); ++k) judge[disputed[k]] = dh[k], judged[disputed[k]] = 1;
  }
  for (size_t i = 0; i < n; ++i) {
    if (verdict[i] == Verdict::kSkipped) {
      ++rep.skipped;
      continue;
    }
    Verdict v = verdict[i];
    const fmt::Hit& r = judged[i] ? judge[i] : ref[i];
    if (judged[i]) {
      v = classify_hit(rays[i], r, got[i], o);
      if (v == Verdict::kAgree) {
        ++rep.reference_errors;
        continue;
      }
    }
    const bool rh = is_hit(r), gh = is_hit(got[i]);
    switch (v) {
      case Verdict::kAgree:
        if (!rh) {
          ++rep.both_miss;
        } else {
          ++rep.both_hit;
          if (r.instance != got[i].instance || r.prim != got[i].prim) ++rep.same_t_other_prim;
        }
        break;
      case Verdict::kEdgeTie:
      case Verdict::kPrecisionTie:
        ++(v == Verdict::kEdgeTie ? rep.edge_ties : rep.precision_ties);
        keep(rep.first_ties, o.max_examples, {i, v, rays[i], r, got[i]});
        break;
      default:
        ++rep.failures;
        if (rh && !gh)
          ++rep.fail_missed;
        else if (!rh && gh)
          ++rep.fail_extra;
        else
          ++rep.fail_t;
        keep(rep.first_failures, o.max_examples, {i, Verdict::kFail, rays[i], r, got[i]});
        break;
    }
  }
  return rep;
}

void AnyHitReport::merge(const AnyHitReport& o, size_t max_examples) {
  rays += o.rays;
  skipped += o.skipped;
  consistent += o.consistent;
  edge_ties += o.edge_ties;
  precision_ties += o.precision_ties;
  failures += o.failures;
  reference_errors += o.reference_errors;
  for (const RayDiff& d : o.first_failures) keep(first_failures, max_examples, d);
}

std::string AnyHitReport::summary() const {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%" PRIu64 " rays: %" PRIu64 " any-hit consistent with closest-hit, %" PRIu64 " edge ties, %" PRIu64
                " precision ties, %" PRIu64 " FAILURES, %" PRIu64 " skipped, %" PRIu64
                " reference errors settled by the double reference",
                rays, consistent, edge_ties, precision_ties, failures, skipped, reference_errors);
  return buf;
}

std::string AnyHitReport::details() const {
  std::string s = summary() + "\n";
  for (const RayDiff& d : first_failures) s += d.describe();
  return s;
}

AnyHitReport check_any_hit(const fmt::Ray* rays, const fmt::Hit* closest, const uint8_t* occluded, size_t n,
                           const CompareOptions& o, const uint8_t* skip, const fmt::Hit* own_closest) {
  AnyHitReport rep;
  rep.rays = n;
  // TESTING.md "The oracle": inconsistent rays are judged against the double reference's closest hit.
  std::vector<size_t> disputed;
  for (size_t i = 0; i < n; ++i)
    if (!(skip && skip[i]) && is_hit(closest[i]) != (occluded[i] != 0)) disputed.push_back(i);
  std::vector<fmt::Hit> exact(o.exact ? disputed.size() : 0);
  if (o.exact && !disputed.empty()) {
    std::vector<fmt::Ray> dr(disputed.size());
    for (size_t k = 0; k < disputed.size(); ++k) dr[k] = rays[disputed[k]];
    o.exact->closest(dr.data(), exact.data(), dr.size());
  }
  size_t next = 0;
  for (size_t i = 0; i < n; ++i) {
    if (skip && skip[i]) {
      ++rep.skipped;
      continue;
    }
    const bool judged = next < exact.size() && disputed[next] == i;
    const fmt::Hit& c = judged ? exact[next++] : closest[i];
    const bool hit = is_hit(c);
    const bool occ = occluded[i] != 0;
    if (hit == occ) {
      ++(judged ? rep.reference_errors : rep.consistent);
    } else if (hit && near_edge(c, o.edge_eps)) {
      ++rep.edge_ties;
    } else if (hit && o.scene && near_edge_in_precision(*o.scene, rays[i], c, o.precision_rel)) {
      ++rep.precision_ties;
    } else if (!hit && own_closest && classify_hit(rays[i], c, own_closest[i], o) == Verdict::kEdgeTie) {
      ++rep.edge_ties;
    } else if (!hit && own_closest && classify_hit(rays[i], c, own_closest[i], o) == Verdict::kPrecisionTie) {
      ++rep.precision_ties;
    } else {
      ++rep.failures;
      fmt::Hit g{occ ? 0.0f : kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
      keep(rep.first_failures, o.max_examples, {i, Verdict::kFail, rays[i], c, g});
    }
  }
  return rep;
}

std::vector<uint8_t> unsupported_mask(const fmt::Ray* rays, size_t n) {
  std::vector<uint8_t> m(n);
  for (size_t i = 0; i < n; ++i) m[i] = ray_status(rays[i]) == RayStatus::kUnsupported ? 1 : 0;
  return m;
}

}  // namespace rtp
