// Exact world bounds of instanced meshes without transforming every vertex of every instance:
// the extreme of a linear function over a point set, found by branch and bound on a point tree.
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <limits>
#include <memory>
#include <numeric>

#include "scene/scene.h"

namespace rtp {

Aabb Mesh::local_bounds() const {
  Aabb b;
  for (uint32_t i : indices) b.grow(to_d(positions[i]));
  return b;
}

uint64_t Scene::unique_triangles() const {
  uint64_t n = 0;
  for (const Mesh& m : meshes) n += m.triangle_count();
  return n;
}

uint64_t Scene::instanced_triangles() const {
  uint64_t n = 0;
  for (const Instance& i : instances) n += meshes[i.mesh].triangle_count();
  return n;
}

namespace {

// A median-split tree over the vertices a mesh's triangles use; leaves of <= 16 points. `split` false
// keeps them in one leaf: a mesh with few instances is searched at most 6 times per instance, fewer
// passes over its points than the median splits take (the trees of FlightHelmet's six meshes, one
// instance each, were 4 % of its convert). The search's answer is the same either way.
struct PointTree {
  struct Node { Aabb box; uint32_t begin, end, left, right; };  // left = 0: leaf
  std::vector<Node> nodes;
  std::vector<Vec3d> pts;

  explicit PointTree(const Mesh& m, bool split = true) {
    std::vector<uint8_t> used(m.positions.size(), 0);
    for (uint32_t i : m.indices) used[i] = 1;
    for (size_t i = 0; i < used.size(); ++i)
      if (used[i]) pts.push_back(to_d(m.positions[i]));
    if (!pts.empty()) build(0, uint32_t(pts.size()), split ? 16 : uint32_t(pts.size()));
  }
  uint32_t build(uint32_t b, uint32_t e, uint32_t leaf) {
    const uint32_t id = uint32_t(nodes.size());
    nodes.push_back({Aabb{}, b, e, 0, 0});
    Aabb box;
    for (uint32_t i = b; i < e; ++i) box.grow(pts[i]);
    nodes[id].box = box;
    if (e - b > leaf) {
      const Vec3d ext = box.extent();
      const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
      const uint32_t mid = b + (e - b) / 2;
      std::nth_element(pts.begin() + b, pts.begin() + mid, pts.begin() + e,
                       [axis](const Vec3d& p, const Vec3d& q) { return p[axis] < q[axis]; });
      const uint32_t l = build(b, mid, leaf), r = build(mid, e, leaf);
      nodes[id].left = l;
      nodes[id].right = r;
    }
    return id;
  }
  // max over the box of dot(r, p), evaluated in dot()'s order: rounding is monotone, so it never
  // undercuts a point of the box.
  static double box_bound(const Vec3d& r, const Aabb& b) {
    return std::max(r.x * b.lo.x, r.x * b.hi.x) + std::max(r.y * b.lo.y, r.y * b.hi.y) + std::max(r.z * b.lo.z, r.z * b.hi.z);
  }
  // max over points of dot(r, p), pruned by box_bound: the result is exact.
  double support(const Vec3d& r) const {
    double best = -std::numeric_limits<double>::infinity();
    uint32_t stack[128];
    int sp = 0;
    stack[sp++] = 0;
    while (sp) {
      const Node& n = nodes[stack[--sp]];
      if (box_bound(r, n.box) <= best) continue;
      if (!n.left) {
        for (uint32_t i = n.begin; i < n.end; ++i) best = std::max(best, dot(r, pts[i]));
      } else {
        stack[sp++] = n.right;
        stack[sp++] = n.left;
      }
    }
    return best;
  }
};

// World bounds of one instance of the mesh whose point tree is `t`.
Aabb instance_bounds(const PointTree& t, const Instance& inst) {
  Aabb acc;
  if (t.pts.empty()) return acc;
  for (int row = 0; row < 3; ++row) {
    const Vec3d w{inst.transform(row, 0), inst.transform(row, 1), inst.transform(row, 2)};
    const double tr = inst.transform(row, 3);
    acc.hi[row] = t.support(w) + tr;
    acc.lo[row] = -t.support(w * -1.0) + tr;
  }
  return acc;
}

// One face of an instance's world box, as a maximum: side 0..2 = hi[row], 3..5 = -lo[row]. `exact`
// runs the branch and bound; otherwise the root box's bound, which is never below the exact value
// (same evaluation order, monotone rounding).
double side_value(const PointTree& t, const Instance& inst, int side, bool exact) {
  const int row = side % 3;
  const double sign = side < 3 ? 1.0 : -1.0;
  const Vec3d w = Vec3d{inst.transform(row, 0), inst.transform(row, 1), inst.transform(row, 2)} * sign;
  const double tr = inst.transform(row, 3);
  const double s = exact ? t.support(w) : PointTree::box_bound(w, t.nodes[0].box);
  // hi = support(w) + tr; lo = -support(-w) + tr, so -lo = support(-w) - tr (negation is exact).
  return side < 3 ? s + tr : s - tr;
}

}  // namespace

Aabb compute_instance_world_bounds(const Scene& scene, size_t instance) {
  const Instance& inst = scene.instances[instance];
  return instance_bounds(PointTree(scene.meshes[inst.mesh], false), inst);  // one instance: flat
}

Aabb compute_world_bounds(const Scene& scene, const std::function<void(uint64_t, uint64_t)>& progress) {
  // One point tree per mesh, built in parallel (each is independent).
  // Split only for meshes with more than kFlatInstances instances.
  constexpr uint32_t kFlatInstances = 4;
  std::vector<uint32_t> uses(scene.meshes.size(), 0);
  for (const Instance& in : scene.instances) uses[in.mesh] += uses[in.mesh] <= kFlatInstances;
  std::vector<std::unique_ptr<PointTree>> trees(scene.meshes.size());
  tbb::parallel_for(size_t(0), scene.meshes.size(),
                    [&](size_t m) { trees[m] = std::make_unique<PointTree>(scene.meshes[m], uses[m] > kFlatInstances); });
  const size_t n = scene.instances.size();
  auto usable = [&](size_t i) { return !trees[scene.instances[i].mesh]->pts.empty(); };
  constexpr double kNone = -std::numeric_limits<double>::infinity();
  // Branch and bound over the instances too, one face of the scene box at a time: the scene's face is
  // the maximum of the instances' exact faces, and an instance whose root-box bound does not exceed an
  // exact face already found cannot raise it. So only the instances near the scene's boundary run the
  // point-tree search; the result is the same maximum as evaluating every instance, for any thread count.
  std::array<double, 6> face;
  for (int side = 0; side < 6; ++side) {
    // Seed: the exact face of the instance with the largest bound (ties: lowest index).
    struct Best { double v; size_t i; };
    const Best seed = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, 4096), Best{kNone, n},
        [&](const tbb::blocked_range<size_t>& r, Best b) {
          for (size_t i = r.begin(); i != r.end(); ++i) {
            if (!usable(i)) continue;
            const double v = side_value(*trees[scene.instances[i].mesh], scene.instances[i], side, false);
            if (v > b.v || (v == b.v && i < b.i)) b = {v, i};
          }
          return b;
        },
        [](Best a, Best b) { return b.v > a.v || (b.v == a.v && b.i < a.i) ? b : a; });
    if (seed.i == n) return Aabb{};  // no instance has a vertex
    const double start = side_value(*trees[scene.instances[seed.i].mesh], scene.instances[seed.i], side, true);
    face[side] = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, 1024), start,
        [&](const tbb::blocked_range<size_t>& r, double best) {
          for (size_t i = r.begin(); i != r.end(); ++i) {
            if (!usable(i)) continue;
            const PointTree& t = *trees[scene.instances[i].mesh];
            if (side_value(t, scene.instances[i], side, false) <= best) continue;
            best = std::max(best, side_value(t, scene.instances[i], side, true));
          }
          return best;
        },
        [](double a, double b) { return std::max(a, b); });
    if (progress) progress(n * uint64_t(side + 1) / 6, n);
  }
  Aabb all;
  for (int row = 0; row < 3; ++row) {
    all.hi[row] = face[row];
    all.lo[row] = -face[row + 3];
  }
  return all;
}

}  // namespace rtp
