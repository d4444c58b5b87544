#pragma once
// Test-only helpers for lib/trace: a tiny W-wide BVH builder (median splits, octant orders, padded SoA
// blocks) that gives SceneView<W, B> without lib/bvh, a brute-force double-precision reference with
// edge-tie classification, and deterministic random numbers.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"
#include "scene/scene.h"
#include "layout/scene_view.h"
#include "trace/trace.h"
#include "test_rng.h"

namespace rtp::trace_test {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

// The SIMD ISAs this CPU runs (AVX2, AVX-512): the ones with packets and the vector kernels.
inline std::vector<Isa> simd_isas() {
  std::vector<Isa> out;
  for (Isa isa : {Isa::kAvx2, Isa::kAvx512})
    if (static_cast<int>(isa) <= static_cast<int>(detect_isa())) out.push_back(isa);
  return out;
}

using Rng = test::SplitMix64<1, float>;

struct Tri {
  std::array<std::array<float, 3>, 3> v;  // v[corner][axis]
};

// Row-major 3x4 transforms.
using Affine = std::array<float, 12>;
inline Affine identity() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}; }
inline Affine translation(double x, double y, double z) { return {1, 0, 0, float(x), 0, 1, 0, float(y), 0, 0, 1, float(z)}; }
// Inverse of a 3x4 affine in double, rounded to float (SPEC §2.4 stores its 3x3 part).
inline Affine invert(const Affine& m) {
  const double a = m[0], b = m[1], c = m[2], d = m[4], e = m[5], f = m[6], g = m[8], h = m[9], i = m[10];
  const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  const double r[9] = {(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det,
                       (f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det,
                       (d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det};
  Affine out{};
  for (int row = 0; row < 3; ++row) {
    double t = 0;
    for (int k = 0; k < 3; ++k) {
      out[4 * row + k] = float(r[3 * row + k]);
      t -= r[3 * row + k] * double(m[4 * k + 3]);
    }
    out[4 * row + 3] = float(t);
  }
  return out;
}
inline std::array<double, 3> apply(const Affine& m, const std::array<double, 3>& p) {
  std::array<double, 3> o{};
  for (int r = 0; r < 3; ++r)
    o[r] = double(m[4 * r]) * p[0] + double(m[4 * r + 1]) * p[1] + double(m[4 * r + 2]) * p[2] + double(m[4 * r + 3]);
  return o;
}

struct TestInstance {
  uint32_t mesh;
  Affine local_to_world;
};

struct Box {
  float lo[3] = {kInf, kInf, kInf};
  float hi[3] = {-kInf, -kInf, -kInf};
  void grow(const Box& b) {
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], b.lo[a]), hi[a] = std::max(hi[a], b.hi[a]);
  }
  float centre(int a) const { return 0.5f * lo[a] + 0.5f * hi[a]; }
};

// Builds one W-wide level over items with boxes; make_leaf(first, count) (indices into `perm`) returns a
// leaf ChildRef. Median split along the widest centroid axis into up to W groups.
template <int W>
struct LevelBuilder {
  std::vector<fmt::WideNode<W>>* nodes;
  std::vector<Box> boxes;
  std::vector<uint32_t> perm;
  uint32_t leaf_max;

  template <class MakeLeaf>
  uint32_t build(uint32_t first, uint32_t count, MakeLeaf&& make_leaf) {
    if (count <= leaf_max) return make_leaf(first, count);
    Box cb;
    for (uint32_t k = first; k < first + count; ++k)
      for (int a = 0; a < 3; ++a) {
        const float c = boxes[perm[k]].centre(a);
        cb.lo[a] = std::min(cb.lo[a], c), cb.hi[a] = std::max(cb.hi[a], c);
      }
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (cb.hi[a] - cb.lo[a] > cb.hi[axis] - cb.lo[axis]) axis = a;
    std::sort(perm.begin() + first, perm.begin() + first + count, [&](uint32_t x, uint32_t y) {
      const float cx = boxes[x].centre(axis), cy = boxes[y].centre(axis);
      return cx < cy || (cx == cy && x < y);
    });
    const uint32_t groups = std::min<uint32_t>(W, std::max<uint32_t>(2, (count + leaf_max - 1) / leaf_max));
    const uint32_t index = uint32_t(nodes->size());
    nodes->emplace_back();
    uint32_t children[W];
    Box child_box[W];
    for (uint32_t g = 0; g < groups; ++g) {
      const uint32_t b = first + uint32_t(uint64_t(count) * g / groups);
      const uint32_t e = first + uint32_t(uint64_t(count) * (g + 1) / groups);
      for (uint32_t k = b; k < e; ++k) child_box[g].grow(boxes[perm[k]]);
      children[g] = build(b, e - b, make_leaf);
    }
    fmt::WideNode<W>& node = (*nodes)[index];
    for (int lane = 0; lane < W; ++lane) {
      const bool used = uint32_t(lane) < groups;
      for (int a = 0; a < 3; ++a) {
        node.lo[a][lane] = used ? child_box[lane].lo[a] : kInf;
        node.hi[a][lane] = used ? child_box[lane].hi[a] : -kInf;
      }
      node.child[lane] = used ? children[lane] : fmt::ChildRef::kEmpty;
    }
    for (int oct = 0; oct < 8; ++oct) {
      std::array<int, W> lanes;
      std::iota(lanes.begin(), lanes.end(), 0);
      auto key = [&](int lane) {
        if (uint32_t(lane) >= groups) return double(kInf);
        double k = 0;
        for (int a = 0; a < 3; ++a) k += ((oct >> a) & 1 ? -1.0 : 1.0) * child_box[lane].centre(a);
        return k;
      };
      std::stable_sort(lanes.begin(), lanes.end(), [&](int x, int y) { return key(x) < key(y); });
      for (int i = 0; i < W; ++i) node.order[oct][i] = uint8_t(lanes[i]);
    }
    return fmt::ChildRef::inner(index);
  }
};

template <int W, int B>
struct TestScene {
  struct MeshBvh {
    std::vector<fmt::WideNode<W>> nodes;
    std::vector<fmt::LeafBlock<B>> blocks;
    uint32_t root = fmt::ChildRef::kEmpty;
  };
  std::vector<std::vector<Tri>> meshes;
  std::vector<TestInstance> placements;
  std::vector<MeshBvh> bvhs;
  std::vector<MeshBvhView<W, B>> mesh_views;
  std::vector<fmt::WideNode<W>> top_nodes;
  std::vector<uint32_t> top_instances;
  std::vector<fmt::InstanceRecord> instances;
  uint32_t top_root = fmt::ChildRef::kEmpty;

  SceneView<W, B> view() const { return {top_nodes.data(), top_root, top_instances.data(), instances.data(), mesh_views.data()}; }
};

// leaf_blocks: blocks per mesh leaf (1..16); top_leaf: instances per top leaf (1..16).
template <int W, int B>
TestScene<W, B> build_scene(std::vector<std::vector<Tri>> meshes, std::vector<TestInstance> placements, uint32_t leaf_blocks = 2,
                            uint32_t top_leaf = 2) {
  TestScene<W, B> s;
  s.meshes = std::move(meshes);
  s.placements = std::move(placements);
  s.bvhs.resize(s.meshes.size());
  for (size_t m = 0; m < s.meshes.size(); ++m) {
    const std::vector<Tri>& tris = s.meshes[m];
    auto& bvh = s.bvhs[m];
    LevelBuilder<W> lb{&bvh.nodes, {}, {}, leaf_blocks * B};
    for (const Tri& t : tris) {
      Box b;
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a) b.lo[a] = std::min(b.lo[a], t.v[c][a]), b.hi[a] = std::max(b.hi[a], t.v[c][a]);
      lb.boxes.push_back(b);
    }
    lb.perm.resize(tris.size());
    std::iota(lb.perm.begin(), lb.perm.end(), 0u);
    if (tris.empty()) continue;
    bvh.root = lb.build(0, uint32_t(tris.size()), [&](uint32_t first, uint32_t count) {
      const uint32_t first_block = uint32_t(bvh.blocks.size());
      const uint32_t nb = (count + B - 1) / B;
      for (uint32_t blk = 0; blk < nb; ++blk) {
        fmt::LeafBlock<B> out;
        for (int lane = 0; lane < B; ++lane) {
          const uint32_t k = std::min(blk * B + lane, count - 1);  // pad by repeating the last triangle
          const uint32_t prim = lb.perm[first + k];
          const Tri& t = tris[prim];
          for (int a = 0; a < 3; ++a) {
            out.v0[a][lane] = t.v[0][a];
            out.v1[a][lane] = t.v[1][a];
            out.v2[a][lane] = t.v[2][a];
          }
          out.prim[lane] = prim;
        }
        bvh.blocks.push_back(out);
      }
      return fmt::ChildRef::leaf(first_block, nb);
    });
  }
  for (auto& bvh : s.bvhs) s.mesh_views.push_back({bvh.nodes.data(), bvh.blocks.data(), bvh.root});

  LevelBuilder<W> top{&s.top_nodes, {}, {}, top_leaf};
  for (uint32_t i = 0; i < s.placements.size(); ++i) {
    const TestInstance& p = s.placements[i];
    fmt::InstanceRecord rec{};
    const Affine inv = invert(p.local_to_world);  // SPEC §2.4: double T, float L^-1
    for (int r = 0; r < 3; ++r) {
      rec.translation[r] = p.local_to_world[size_t(4 * r + 3)];
      for (int c = 0; c < 3; ++c) rec.inverse_linear[3 * r + c] = inv[size_t(4 * r + c)];
    }
    rec.mesh = p.mesh;
    s.instances.push_back(rec);
    Box b;  // world bounds of the transformed vertices (double), rounded outward
    for (const Tri& t : s.meshes[p.mesh])
      for (int c = 0; c < 3; ++c) {
        const auto w = apply(p.local_to_world, {t.v[c][0], t.v[c][1], t.v[c][2]});
        for (int a = 0; a < 3; ++a) {
          b.lo[a] = std::min(b.lo[a], std::nextafter(float(w[a]), -kInf));
          b.hi[a] = std::max(b.hi[a], std::nextafter(float(w[a]), kInf));
        }
      }
    top.boxes.push_back(b);
    top.perm.push_back(i);
  }
  if (!s.placements.empty())
    s.top_root = top.build(0, uint32_t(s.placements.size()), [&](uint32_t first, uint32_t count) {
      const uint32_t at = uint32_t(s.top_instances.size());
      for (uint32_t k = 0; k < count; ++k) s.top_instances.push_back(top.perm[first + k]);
      return fmt::ChildRef::leaf(at, count);
    });
  return s;
}

// formats/ray_file.h validity, written out again independently of lib/trace.
inline bool ray_is_valid_for_test(const fmt::Ray& r) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(r.org[a]) || !std::isfinite(r.dir[a])) return false;
  return !std::isnan(r.tnear) && !std::isnan(r.tfar) && r.tnear <= r.tfar && r.tnear != kInf;
}

// ---- brute force in double -------------------------------------------------------------------------

struct RefHit {
  double t = std::numeric_limits<double>::infinity();
  uint32_t instance = fmt::Hit::kNone, prim = fmt::Hit::kNone;
  double edge = 0;  // smallest barycentric of the hit (distance to the nearest edge, relative)
};

// Moller-Trumbore in double: t and the three barycentrics (any sign); false for a parallel ray.
inline bool ray_triangle_double(const std::array<double, 3>& o, const std::array<double, 3>& d,
                                const std::array<std::array<double, 3>, 3>& v, double* t, double b[3]) {
  auto sub = [](const std::array<double, 3>& x, const std::array<double, 3>& y) {
    return std::array<double, 3>{x[0] - y[0], x[1] - y[1], x[2] - y[2]};
  };
  auto cross = [](const std::array<double, 3>& x, const std::array<double, 3>& y) {
    return std::array<double, 3>{x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
  };
  auto dot = [](const std::array<double, 3>& x, const std::array<double, 3>& y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
  };
  const auto e1 = sub(v[1], v[0]), e2 = sub(v[2], v[0]);
  const auto p = cross(d, e2);
  const double det = dot(e1, p);
  if (det == 0 || !std::isfinite(det)) return false;
  const auto s = sub(o, v[0]);
  const double u = dot(s, p) / det;
  const auto q = cross(s, e1);
  const double w = dot(d, q) / det;
  *t = dot(e2, q) / det;
  b[0] = 1 - u - w, b[1] = u, b[2] = w;
  return std::isfinite(*t);
}

template <int W, int B>
std::array<std::array<double, 3>, 3> world_triangle(const TestScene<W, B>& s, uint32_t inst, uint32_t prim) {
  const TestInstance& p = s.placements[inst];
  const Tri& t = s.meshes[p.mesh][prim];
  std::array<std::array<double, 3>, 3> v;
  for (int c = 0; c < 3; ++c) v[c] = apply(p.local_to_world, {t.v[c][0], t.v[c][1], t.v[c][2]});
  return v;
}

// Closest hit over every instanced triangle, ties by (t, instance, prim); valid rays only.
// Möller-Trumbore is not watertight: barycentrics down to -1e-12 count as inside.
template <int W, int B>
RefHit brute_force(const TestScene<W, B>& s, const fmt::Ray& r) {
  RefHit best;
  const std::array<double, 3> o{r.org[0], r.org[1], r.org[2]}, d{r.dir[0], r.dir[1], r.dir[2]};
  for (uint32_t i = 0; i < s.placements.size(); ++i)
    for (uint32_t p = 0; p < s.meshes[s.placements[i].mesh].size(); ++p) {
      double t, b[3];
      if (!ray_triangle_double(o, d, world_triangle(s, i, p), &t, b)) continue;
      // A hair of slack so that double rounding cannot open a gap on a shared edge (rays aimed at
      // edges and vertices): the reference must not leak where the tracer must not.
      if (b[0] < -1e-12 || b[1] < -1e-12 || b[2] < -1e-12 || t < r.tnear || t > r.tfar) continue;
      if (t < best.t) best = {t, i, p, std::min({b[0], b[1], b[2]})};
    }
  return best;
}

// Compares one hit with the reference (TESTING.md): 0 agree, 1 classified edge tie, 2 failure.
template <int W, int B>
int classify(const TestScene<W, B>& s, const fmt::Ray& r, const fmt::Hit& h, const RefHit& ref, double edge_eps = 1e-5) {
  const bool hit = h.instance != fmt::Hit::kNone, ref_hit = ref.instance != fmt::Hit::kNone;
  if (!hit && !ref_hit) return 0;
  auto ours_near_edge = [&]() {  // our triangle, in double: inside up to edge_eps and t close
    if (!hit || h.instance >= s.placements.size()) return false;
    double t, b[3];
    const std::array<double, 3> o{r.org[0], r.org[1], r.org[2]}, d{r.dir[0], r.dir[1], r.dir[2]};
    if (!ray_triangle_double(o, d, world_triangle(s, h.instance, h.prim), &t, b)) return false;
    return std::min({b[0], b[1], b[2]}) > -edge_eps && std::fabs(t - h.t) <= 1e-4 * std::max(1.0, std::fabs(t));
  };
  if (hit && ref_hit) {
    const bool t_ok = std::fabs(double(h.t) - ref.t) <= 1e-4 * std::max(1.0, std::fabs(ref.t));
    if (t_ok && h.instance == ref.instance && h.prim == ref.prim) return 0;
    if (ref.edge < edge_eps || (t_ok && ours_near_edge())) return 1;
    return 2;
  }
  if (ref_hit) return ref.edge < edge_eps ? 1 : 2;
  return ours_near_edge() ? 1 : 2;
}

// ---- meshes ----------------------------------------------------------------------------------------

// A lib/mesh mesh scaled and moved (in double, rounded once) into a triangle soup whose shared
// vertices stay bit-identical; optionally its vertex positions and unique edges (vertex index pairs).
inline std::vector<Tri> soup(const Mesh& m, double scale, std::array<double, 3> centre,
                             std::vector<std::array<float, 3>>* vertices = nullptr,
                             std::vector<std::array<uint32_t, 2>>* edges = nullptr) {
  std::vector<std::array<float, 3>> pos;
  for (const Vec3f& p : m.positions)
    pos.push_back({float(p.x * scale + centre[0]), float(p.y * scale + centre[1]), float(p.z * scale + centre[2])});
  std::vector<Tri> out;
  std::vector<std::array<uint32_t, 2>> e;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    Tri tri;
    for (int c = 0; c < 3; ++c) {
      tri.v[c] = pos[m.indices[3 * t + c]];
      const uint32_t a = m.indices[3 * t + c], b = m.indices[3 * t + (c + 1) % 3];
      e.push_back({std::min(a, b), std::max(a, b)});
    }
    out.push_back(tri);
  }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  if (vertices) *vertices = pos;
  if (edges) *edges = e;
  return out;
}

}  // namespace rtp::trace_test
