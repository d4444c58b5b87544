// Exact world bounds of instanced meshes without transforming every vertex of every instance:
// the extreme of a linear function over a point set, found by branch and bound on a point tree.
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
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

// A median-split tree over the vertices a mesh's triangles use; leaves of <= 16 points.
struct PointTree {
  struct Node { Aabb box; uint32_t begin, end, left, right; };  // left = 0: leaf
  std::vector<Node> nodes;
  std::vector<Vec3d> pts;

  explicit PointTree(const Mesh& m) {
    std::vector<uint8_t> used(m.positions.size(), 0);
    for (uint32_t i : m.indices) used[i] = 1;
    for (size_t i = 0; i < used.size(); ++i)
      if (used[i]) pts.push_back(to_d(m.positions[i]));
    if (!pts.empty()) build(0, uint32_t(pts.size()));
  }
  uint32_t build(uint32_t b, uint32_t e) {
    const uint32_t id = uint32_t(nodes.size());
    nodes.push_back({Aabb{}, b, e, 0, 0});
    Aabb box;
    for (uint32_t i = b; i < e; ++i) box.grow(pts[i]);
    nodes[id].box = box;
    if (e - b > 16) {
      const Vec3d ext = box.extent();
      const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
      const uint32_t mid = b + (e - b) / 2;
      std::nth_element(pts.begin() + b, pts.begin() + mid, pts.begin() + e,
                       [axis](const Vec3d& p, const Vec3d& q) { return p[axis] < q[axis]; });
      const uint32_t l = build(b, mid), r = build(mid, e);
      nodes[id].left = l;
      nodes[id].right = r;
    }
    return id;
  }
  // max over points of dot(r, p). The box bound uses the same evaluation order as dot(), and
  // rounding is monotone, so the bound never undercuts a point: the result is exact.
  double support(const Vec3d& r) const {
    double best = -std::numeric_limits<double>::infinity();
    uint32_t stack[128];
    int sp = 0;
    stack[sp++] = 0;
    while (sp) {
      const Node& n = nodes[stack[--sp]];
      const double ub = std::max(r.x * n.box.lo.x, r.x * n.box.hi.x) + std::max(r.y * n.box.lo.y, r.y * n.box.hi.y) +
                        std::max(r.z * n.box.lo.z, r.z * n.box.hi.z);
      if (ub <= best) continue;
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

}  // namespace

Aabb compute_instance_world_bounds(const Scene& scene, size_t instance) {
  const Instance& inst = scene.instances[instance];
  return instance_bounds(PointTree(scene.meshes[inst.mesh]), inst);
}

Aabb compute_world_bounds(const Scene& scene, const std::function<void(uint64_t, uint64_t)>& progress) {
  // One point tree per mesh, built in parallel (each is independent).
  std::vector<std::unique_ptr<PointTree>> trees(scene.meshes.size());
  tbb::parallel_for(size_t(0), scene.meshes.size(), [&](size_t m) { trees[m] = std::make_unique<PointTree>(scene.meshes[m]); });
  // Instances in slices of about 1 %, each in parallel; progress is reported between slices from the
  // calling thread. min/max do not depend on the order: the bounds are the same for any thread count.
  const size_t n = scene.instances.size(), slice = std::max<size_t>(4096, n / 100);
  Aabb all;
  for (size_t first = 0; first < n; first += slice) {
    const size_t last = std::min(n, first + slice);
    all.grow(tbb::parallel_reduce(
        tbb::blocked_range<size_t>(first, last, 1024), Aabb{},
        [&](const tbb::blocked_range<size_t>& r, Aabb acc) {
          for (size_t i = r.begin(); i != r.end(); ++i) {
            const Instance& inst = scene.instances[i];
            const Aabb b = instance_bounds(*trees[inst.mesh], inst);
            if (b.empty()) continue;
            for (int row = 0; row < 3; ++row) {
              acc.hi[row] = std::max(acc.hi[row], b.hi[row]);
              acc.lo[row] = std::min(acc.lo[row], b.lo[row]);
            }
          }
          return acc;
        },
        [](Aabb a, const Aabb& b) {
          a.grow(b);
          return a;
        }));
    if (progress) progress(last, n);
  }
  return all;
}

}  // namespace rtp
