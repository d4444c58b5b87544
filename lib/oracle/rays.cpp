#include "core/math.h"
#include "oracle/rays.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <cstring>
#include <unordered_map>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace rtp {
namespace {

constexpr double kPi = std::numbers::pi;

// Counter-based randomness: one independent stream per (seed, stream tag, index).
class Rng {
 public:
  Rng(uint64_t seed, uint64_t tag, uint64_t index) {
    state_ = mix(seed ^ mix(tag * 0xD1B54A32D192ED03ull + 0x8CB92BA72F3D8DD7ull) ^ mix(index + 0x632BE59BD9B4E019ull));
  }
  uint64_t next() {
    state_ += 0x9E3779B97F4A7C15ull;
    return mix(state_);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)

 private:
  static uint64_t mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  uint64_t state_;
};

// Stream tags: one per kind, plus the base rays of the hit-based kinds and the fallbacks.
uint64_t tag(RayKind k) { return uint64_t(k) + 1; }
constexpr uint64_t kTagBase = 100;      // base rays of the hit-based kinds (+50: short rays)
constexpr uint64_t kTagFallback = 200;  // + kind

Vec3d normalize(const Vec3d& v) {
  const double l = length(v);
  return l > 0 ? v * (1.0 / l) : Vec3d{0, 0, 1};
}

Vec3d uniform_sphere(Rng& rng) {
  const double z = 1 - 2 * rng.uniform();
  const double phi = 2 * kPi * rng.uniform();
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Orthonormal basis around n (Duff et al. 2017).
void basis(const Vec3d& n, Vec3d& t, Vec3d& b) {
  const double sign = std::copysign(1.0, n.z);
  const double a = -1.0 / (sign + n.z);
  const double c = n.x * n.y * a;
  t = {1 + sign * n.x * n.x * a, sign * c, -sign * n.x};
  b = {c, sign + n.y * n.y * a, -n.y};
}

fmt::Ray make_ray(const Vec3d& o, const Vec3d& d, double tnear = 0, double tfar = kInf) {
  fmt::Ray r;
  for (int i = 0; i < 3; ++i) {
    r.org[i] = float(o[i]);
    r.dir[i] = float(d[i]);
  }
  r.tnear = float(tnear);
  r.tfar = float(tfar);
  return r;
}

struct Frame {
  Vec3d center;
  double radius;  // half the diagonal, > 0
  Aabb box;       // non-empty
};

Frame frame_of(const Scene& scene) {
  Frame f;
  if (scene.bounds.empty()) {
    f.box.lo = {-1, -1, -1};
    f.box.hi = {1, 1, 1};
  } else {
    f.box = scene.bounds;
  }
  f.center = f.box.center();
  f.radius = 0.5 * length(f.box.extent());
  if (!(f.radius > 0)) {
    const double m = std::max({std::abs(f.center.x), std::abs(f.center.y), std::abs(f.center.z), 1.0});
    f.radius = 1e-3 * m;
    f.box.lo = f.center - Vec3d{f.radius, f.radius, f.radius};
    f.box.hi = f.center + Vec3d{f.radius, f.radius, f.radius};
  }
  return f;
}

Vec3d apply_linear(const Affine3x4& m, const Vec3d& v) {
  Vec3d o;
  for (int r = 0; r < 3; ++r) o[r] = double(m(r, 0)) * v.x + double(m(r, 1)) * v.y + double(m(r, 2)) * v.z;
  return o;
}

double camera_aspect(const Camera& c) {
  if (c.type == Camera::Type::kOrthographic) {
    const double xm = c.xmag != 0 ? std::abs(c.xmag) : 1, ym = c.ymag != 0 ? std::abs(c.ymag) : 1;
    return xm / ym;
  }
  return c.aspect_ratio > 0 ? c.aspect_ratio : 1.5;
}

// (sx, sy) in [0,1]^2, (0,0) = top left of the image.
fmt::Ray camera_ray(const Camera& c, double sx, double sy) {
  const double x = 2 * sx - 1, y = 1 - 2 * sy;
  if (c.type == Camera::Type::kOrthographic) {
    const double xm = c.xmag != 0 ? std::abs(c.xmag) : 1, ym = c.ymag != 0 ? std::abs(c.ymag) : 1;
    const Vec3d o = c.world.apply({x * xm, y * ym, 0});
    return make_ray(o, normalize(apply_linear(c.world, {0, 0, -1})));
  }
  const double yfov = c.yfov > 0 && c.yfov < kPi ? c.yfov : 0.8;
  const double th = std::tan(0.5 * yfov);
  const Vec3d d = apply_linear(c.world, {x * camera_aspect(c) * th, y * th, -1});
  return make_ray(c.world.apply({0, 0, 0}), normalize(d));
}

// A jittered random pixel of a random camera.
fmt::Ray random_camera_ray(const std::vector<Camera>& cams, Rng& rng) {
  const size_t k = std::min(cams.size() - 1, size_t(rng.uniform() * double(cams.size())));
  const double sx = rng.uniform(), sy = rng.uniform();
  return camera_ray(cams[k], sx, sy);
}

fmt::Ray random_ray(const Frame& f, Rng& rng) {
  const double scale = std::exp2(4 * rng.uniform() - 2);  // |dir| in [0.25, 4)
  const Vec3d inside = {f.box.lo.x + rng.uniform() * (f.box.hi.x - f.box.lo.x),
                        f.box.lo.y + rng.uniform() * (f.box.hi.y - f.box.lo.y),
                        f.box.lo.z + rng.uniform() * (f.box.hi.z - f.box.lo.z)};
  if (rng.next() & 1) {
    const Vec3d o = f.center + uniform_sphere(rng) * (1.5 * f.radius);
    return make_ray(o, normalize(inside - o) * scale);
  }
  return make_ray(inside, uniform_sphere(rng) * scale);
}

// Slab test in double: the parameter interval of the ray inside the box, false if none.
bool ray_box(const fmt::Ray& r, const Aabb& b, double& t0, double& t1) {
  t0 = 0;
  t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double o = r.org[a], d = r.dir[a];
    if (d == 0) {
      if (o < b.lo[a] || o > b.hi[a]) return false;
      continue;
    }
    double ta = (b.lo[a] - o) / d, tb = (b.hi[a] - o) / d;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1;
}

struct SurfacePoint {
  Vec3d p;       // offset off the surface, toward the side the ray came from
  Vec3d normal;  // facing the incoming ray
};

// The hit point of a valid hit, offset along the geometric normal. False for unusable hits.
bool surface_point(const Scene& scene, const Frame& f, const fmt::Ray& r, const fmt::Hit& h, SurfacePoint& out) {
  if (!(h.t < kInf) || h.instance >= scene.instances.size()) return false;
  const Instance& inst = scene.instances[h.instance];
  if (inst.mesh >= scene.meshes.size()) return false;
  const Mesh& m = scene.meshes[inst.mesh];
  if (uint64_t(h.prim) >= m.triangle_count()) return false;
  Vec3d w[3];
  for (int k = 0; k < 3; ++k) w[k] = inst.transform.apply(to_d(m.positions[m.indices[3 * size_t(h.prim) + k]]));
  Vec3d n = cross(w[1] - w[0], w[2] - w[0]);
  const double len = length(n);
  if (!(len > 0) || !std::isfinite(len)) return false;
  n = n * (1.0 / len);
  const Vec3d d = {r.dir[0], r.dir[1], r.dir[2]};
  if (dot(n, d) > 0) n = n * -1.0;
  const Vec3d p = Vec3d{r.org[0], r.org[1], r.org[2]} + d * double(h.t);
  const double mag = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  // Far enough that float rounding of the origin (and either tracer's error) cannot put it behind the
  // surface: 1e-5 of the scene diagonal plus ~8 ulp of the coordinates.
  const double eps = 2e-5 * f.radius + 1e-6 * mag;
  out.p = p + n * eps;
  out.normal = n;
  return true;
}

// Connected parts of a mesh (vertices welded by exact position) and whether each is closed (every
// edge shared by exactly two triangles of the part). Returns the area-weighted surface centroids.
void mesh_part_centroids(const Mesh& m, std::vector<Vec3d>& closed, std::vector<Vec3d>& all) {
  const size_t nt = m.indices.size() / 3;
  if (nt == 0) return;
  struct KeyHash {
    size_t operator()(const Vec3f& v) const {
      uint32_t b[3];
      std::memcpy(b, &v, sizeof b);
      return size_t(b[0] * 0x9E3779B1u) ^ (size_t(b[1]) * 0x85EBCA77u << 1) ^ (size_t(b[2]) * 0xC2B2AE3Du << 2);
    }
  };
  std::unordered_map<Vec3f, uint32_t, KeyHash> weld;
  std::vector<uint32_t> wid(m.positions.size());
  for (size_t i = 0; i < m.positions.size(); ++i) {
    Vec3f p = m.positions[i];
    for (int a = 0; a < 3; ++a)
      if (p[a] == 0) p[a] = 0;  // -0 == +0
    wid[i] = weld.emplace(p, uint32_t(weld.size())).first->second;
  }
  std::vector<uint32_t> parent(weld.size());
  for (uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::unordered_map<uint64_t, uint32_t> edges;
  edges.reserve(nt * 3);
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t a = wid[m.indices[3 * t]], b = wid[m.indices[3 * t + 1]], c = wid[m.indices[3 * t + 2]];
    parent[find(a)] = find(b);
    parent[find(b)] = find(c);
    const uint32_t e[3][2] = {{a, b}, {b, c}, {c, a}};
    for (const auto& ed : e) {
      const uint64_t key = (uint64_t(std::min(ed[0], ed[1])) << 32) | std::max(ed[0], ed[1]);
      ++edges[key];
    }
  }
  struct Part {
    Vec3d sum;
    double area = 0;
    Vec3d vsum;
    double tris = 0;
    bool closed = true;
  };
  std::unordered_map<uint32_t, Part> parts;
  std::vector<uint32_t> order;  // parts in order of first triangle (deterministic)
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t a = wid[m.indices[3 * t]], b = wid[m.indices[3 * t + 1]], c = wid[m.indices[3 * t + 2]];
    const uint32_t root = find(a);
    auto [it, fresh] = parts.try_emplace(root);
    if (fresh) order.push_back(root);
    Part& part = it->second;
    const Vec3d p0 = to_d(m.positions[m.indices[3 * t]]), p1 = to_d(m.positions[m.indices[3 * t + 1]]),
                p2 = to_d(m.positions[m.indices[3 * t + 2]]);
    const double area = 0.5 * length(cross(p1 - p0, p2 - p0));
    const Vec3d centroid = (p0 + p1 + p2) * (1.0 / 3.0);
    if (std::isfinite(area)) {
      part.sum = part.sum + centroid * area;
      part.area += area;
      part.vsum = part.vsum + centroid;
      part.tris += 1;
    }
    const uint32_t e[3][2] = {{a, b}, {b, c}, {c, a}};
    for (const auto& ed : e) {
      const uint64_t key = (uint64_t(std::min(ed[0], ed[1])) << 32) | std::max(ed[0], ed[1]);
      if (edges[key] != 2) part.closed = false;
    }
  }
  for (uint32_t root : order) {
    const Part& part = parts[root];
    if (part.tris == 0) continue;
    const Vec3d c = part.area > 0 ? part.sum * (1.0 / part.area) : part.vsum * (1.0 / part.tris);
    all.push_back(c);
    if (part.closed) closed.push_back(c);
  }
}

std::vector<fmt::Ray> inside_rays(const Scene& scene, const Frame& f, size_t count, uint64_t seed, RayGenInfo& info) {
  std::vector<std::vector<Vec3d>> closed(scene.meshes.size()), all(scene.meshes.size());
  std::vector<uint8_t> used(scene.meshes.size(), 0);
  for (const Instance& inst : scene.instances)
    if (inst.mesh < used.size()) used[inst.mesh] = 1;
  for (size_t m = 0; m < scene.meshes.size(); ++m)
    if (used[m]) mesh_part_centroids(scene.meshes[m], closed[m], all[m]);
  bool any_closed = false;
  for (size_t m = 0; m < closed.size(); ++m) any_closed = any_closed || !closed[m].empty();
  const auto& parts = any_closed ? closed : all;
  std::vector<uint32_t> candidates;  // instances whose mesh has usable parts
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const uint32_t m = scene.instances[i].mesh;
    if (m < parts.size() && !parts[m].empty()) candidates.push_back(uint32_t(i));
  }
  std::vector<fmt::Ray> rays(count);
  if (candidates.empty()) {
    for (size_t i = 0; i < count; ++i) {
      Rng rng(seed, kTagFallback + tag(RayKind::kInside), i);
      rays[i] = random_ray(f, rng);
    }
    info.fallback = count;
    info.note = "no triangles: random rays instead";
    return rays;
  }
  if (!any_closed) {
    info.fallback = count;
    info.note = "no closed mesh part: centroids of open parts used";
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      Rng rng(seed, tag(RayKind::kInside), i);
      const uint32_t inst = candidates[std::min(candidates.size() - 1, size_t(rng.uniform() * double(candidates.size())))];
      const auto& list = parts[scene.instances[inst].mesh];
      const Vec3d local = list[std::min(list.size() - 1, size_t(rng.uniform() * double(list.size())))];
      rays[i] = make_ray(scene.instances[inst].transform.apply(local), uniform_sphere(rng));
    }
  });
  return rays;
}

// Bounce and shadow rays: from hits of random camera rays. Rounds of base rays sized by the hit rate
// seen so far (many camera rays of a sparse scene miss), at most max(count, 2^20) per round and 64 per
// wanted ray in all.
std::vector<fmt::Ray> from_primary_hits(const Scene& scene, const Frame& f, RayKind kind, size_t count, const RayGenOptions& opt,
                                        RayGenInfo& info) {
  const std::vector<Camera> cams = ray_cameras(scene);
  const Vec3d light = shadow_light(scene);
  std::vector<fmt::Ray> out;
  out.reserve(count);
  std::vector<fmt::Ray> base;
  std::vector<fmt::Hit> hits;
  const uint64_t budget = 64 * uint64_t(count);
  uint64_t traced = 0, first = 0;  // base rays traced so far; index of the next base ray
  while (out.size() < count && traced < budget) {
    const size_t need = count - out.size();
    const double rate = traced > 0 ? double(out.size()) / double(traced) : 1.0;
    const uint64_t want = rate > 0 ? uint64_t(double(need) / rate * 1.25) + 64 : budget;
    const size_t m = size_t(std::min<uint64_t>({want, budget - traced, std::max<uint64_t>(count, 1u << 20)}));
    base.resize(m);
    hits.resize(m);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        Rng rng(opt.seed, kTagBase, first + i);
        base[i] = random_camera_ray(cams, rng);
      }
    });
    opt.closest(base.data(), hits.data(), m);
    for (size_t i = 0; i < m && out.size() < count; ++i) {
      SurfacePoint sp;
      if (!surface_point(scene, f, base[i], hits[i], sp)) continue;
      Rng rng(opt.seed, tag(kind), first + i);
      if (kind == RayKind::kBounce) {
        Vec3d t, b;
        basis(sp.normal, t, b);
        const double r1 = rng.uniform(), r2 = rng.uniform();
        const double rad = std::sqrt(r1), phi = 2 * kPi * r2;
        const Vec3d d = t * (rad * std::cos(phi)) + b * (rad * std::sin(phi)) + sp.normal * std::sqrt(std::max(0.0, 1 - r1));
        out.push_back(make_ray(sp.p, normalize(d)));
      } else {
        // Segment to just short of the light (the light is outside the bounds).
        out.push_back(make_ray(sp.p, light - sp.p, 0, 1 - 1e-4));
      }
    }
    traced += m;
    first += m;
  }
  if (out.size() < count) {
    info.fallback = count - out.size();
    info.note = "too few primary hits: random rays fill the rest";
    for (size_t i = out.size(); i < count; ++i) {
      Rng rng(opt.seed, kTagFallback + tag(kind), i);
      out.push_back(random_ray(f, rng));
    }
  }
  return out;
}

std::vector<fmt::Ray> short_rays(const Scene& scene, const Frame& f, size_t count, const RayGenOptions& opt) {
  const std::vector<Camera> cams = ray_cameras(scene);
  std::vector<fmt::Ray> rays(count);
  for (size_t i = 0; i < count; ++i) {
    Rng rng(opt.seed, kTagBase + 50, i);
    rays[i] = (i & 1) ? random_ray(f, rng) : random_camera_ray(cams, rng);
  }
  std::vector<fmt::Hit> hits(count);
  opt.closest(rays.data(), hits.data(), count);
  for (size_t i = 0; i < count; ++i) {
    Rng rng(opt.seed, tag(RayKind::kShort), i);
    fmt::Ray& r = rays[i];
    const double u = rng.uniform(), sel = rng.uniform();
    if (hits[i].t < kInf) {
      const double th = hits[i].t;
      // An origin on a surface (th = 0) has no interval that ends before or just past its first hit: each
      // would be [0, 0] or [0, 0·k], which still holds the hit (TESTING.md item 5) while Embree reports a
      // miss for such an empty-length interval. Such a ray stays as it was: it hits at 0 on both sides.
      if (th == 0) {
      } else if (sel < 0.5) {
        r.tfar = float(th * (0.05 + 0.9 * u));  // ends before the first hit: must miss
      } else if (sel < 0.75) {
        r.tfar = float(th * (1.002 + 0.5 * u));  // ends just past the first hit: must hit it
      } else {
        r.tnear = float(th * 1.002 + 1e-3 * u * th);  // starts just past the first hit
      }
    } else {
      double t0, t1;
      if (ray_box(r, f.box, t0, t1))
        r.tfar = float(t0 + (t1 - t0) * u);
      else
        r.tfar = float(u * 2 * f.radius / std::max(1e-30, length({r.dir[0], r.dir[1], r.dir[2]})));
    }
    if (!(r.tnear <= r.tfar)) r.tfar = r.tnear;
  }
  return rays;
}

std::vector<fmt::Ray> primary_rays(const Scene& scene, size_t count, uint64_t seed) {
  const std::vector<Camera> cams = ray_cameras(scene);
  std::vector<fmt::Ray> rays(count);
  const size_t nc = cams.size();
  for (size_t k = 0; k < nc; ++k) {
    const size_t begin = count * k / nc, end = count * (k + 1) / nc, m = end - begin;
    if (m == 0) continue;
    // A w x h image (multiples of 4) in 4x4 tiles, tiles in scanline order: 16 consecutive rays form a
    // compact packet. The last tile row may be cut short at m rays.
    const double aspect = camera_aspect(cams[k]);
    const size_t w = 4 * std::max<size_t>(1, size_t(std::lround(std::sqrt(double(m) * aspect) / 4)));
    const size_t h = 4 * ((m + 4 * w - 1) / (4 * w));
    const size_t tiles_x = w / 4;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t j = r.begin(); j < r.end(); ++j) {
        Rng rng(seed, tag(RayKind::kPrimary), begin + j);
        const size_t tile = j / 16, within = j % 16;
        const size_t x = (tile % tiles_x) * 4 + within % 4, y = (tile / tiles_x) * 4 + within / 4;
        const double sx = (double(x) + rng.uniform()) / double(w);
        const double sy = (double(y) + rng.uniform()) / double(h);
        rays[begin + j] = camera_ray(cams[k], sx, sy);
      }
    });
  }
  return rays;
}

}  // namespace

const char* ray_kind_name(RayKind kind) {
  switch (kind) {
    case RayKind::kPrimary: return "primary";
    case RayKind::kRandom: return "random";
    case RayKind::kBounce: return "bounce";
    case RayKind::kShadow: return "shadow";
    case RayKind::kInside: return "inside";
    case RayKind::kShort: return "short";
  }
  return "?";
}

std::optional<RayKind> parse_ray_kind(std::string_view name) {
  for (RayKind k : kAllRayKinds)
    if (name == ray_kind_name(k)) return k;
  return std::nullopt;
}

std::vector<Camera> ray_cameras(const Scene& scene) {
  if (!scene.cameras.empty()) return scene.cameras;
  const Frame f = frame_of(scene);
  Camera c;
  c.name = "auto";
  c.type = Camera::Type::kPerspective;
  c.yfov = kPi / 4;
  c.aspect_ratio = 1.5;
  const Vec3d back = normalize({1, 0.6, 1.4});  // camera +z points away from the target
  const Vec3d right = normalize(cross({0, 1, 0}, back));
  const Vec3d up = cross(back, right);
  // The smallest distance from the centre at which all 8 corners of the bounds are in view, + 5%.
  const double th = std::tan(0.5 * c.yfov);
  double dist = 0;
  for (int k = 0; k < 8; ++k) {
    const Vec3d corner = {(k & 1) ? f.box.hi.x : f.box.lo.x, (k & 2) ? f.box.hi.y : f.box.lo.y,
                          (k & 4) ? f.box.hi.z : f.box.lo.z};
    const Vec3d q = corner - f.center;
    const double z = dot(q, back);
    dist = std::max({dist, z + std::abs(dot(q, right)) / (th * c.aspect_ratio), z + std::abs(dot(q, up)) / th});
  }
  dist = std::max(dist * 1.05, 1e-3 * f.radius);
  const Vec3d eye = f.center + back * dist;
  for (int r = 0; r < 3; ++r) {
    c.world(r, 0) = float(right[r]);
    c.world(r, 1) = float(up[r]);
    c.world(r, 2) = float(back[r]);
    c.world(r, 3) = float(eye[r]);
  }
  return {c};
}

Vec3d shadow_light(const Scene& scene) {
  const Frame f = frame_of(scene);
  return f.center + Vec3d{0.3, 1.2, 0.2} * f.radius;
}

std::vector<fmt::Ray> generate_rays(const Scene& scene, RayKind kind, size_t count, const RayGenOptions& options,
                                    RayGenInfo* info_out) {
  RayGenInfo info;
  info.rays = count;
  const Frame f = frame_of(scene);
  std::vector<fmt::Ray> rays;
  const bool needs_hits = kind == RayKind::kBounce || kind == RayKind::kShadow || kind == RayKind::kShort;
  if (needs_hits && !options.closest)
    throw std::invalid_argument(std::string("generate_rays: kind '") + ray_kind_name(kind) + "' needs a closest-hit callback");
  switch (kind) {
    case RayKind::kPrimary: rays = primary_rays(scene, count, options.seed); break;
    case RayKind::kRandom:
      rays.resize(count);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
          Rng rng(options.seed, tag(kind), i);
          rays[i] = random_ray(f, rng);
        }
      });
      break;
    case RayKind::kBounce:
    case RayKind::kShadow: rays = from_primary_hits(scene, f, kind, count, options, info); break;
    case RayKind::kInside: rays = inside_rays(scene, f, count, options.seed, info); break;
    case RayKind::kShort: rays = short_rays(scene, f, count, options); break;
  }
  if (info_out) *info_out = info;
  return rays;
}

}  // namespace rtp
