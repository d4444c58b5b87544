// Splitting a mesh into pieces of bounded triangle count along a top-down binned SAH BVH
// (I. Wald, "On fast Construction of SAH-based Bounding Volume Hierarchies", RT 2007): at each node
// the centroids are binned into 16 bins on each of the 3 axes, and the plane minimising
// SA(left) * N(left) + SA(right) * N(right) (triangle bounds) is taken. A node is always split while it
// holds more than K triangles (no leaf-cost test); when no binned plane separates the centroids (all
// equal, or not finite), the node is split at the median centroid, ties broken by triangle number, so
// the recursion always terminates.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/mesh_util.h"

namespace rtp {
namespace {

constexpr int kBins = 16;

struct Prim {
  Aabb box;
  Vec3d centroid;
};

struct Bin {
  Aabb box;
  uint32_t count = 0;
};

// The bin of centroid coordinate c in a range whose centroid box starts at lo, scale = kBins / extent
// (computed once per range and axis).
inline int bin_index(double c, double lo, double scale) {
  double t = (c - lo) * scale;
  if (!(t >= 0)) t = 0;  // NaN centroids go left
  return std::min(kBins - 1, int(std::min(t, double(kBins))));
}

// Best binned SAH plane over [begin, end): returns false when no plane puts centroids on both sides.
// On success, `axis` and `split_bin` (left = bins [0, split_bin)) describe it, with the binning of
// `cbox`. Ties keep the first (axis x before y before z, lower plane first): deterministic.
bool find_sah_split(const std::vector<Prim>& prims, const uint32_t* begin, const uint32_t* end, const Aabb& cbox, int& axis,
                    int& split_bin) {
  // The three axes binned in one pass over the range (each axis's bins get the same primitives in the
  // same order as a pass per axis, so the same boxes): a pass per axis read every primitive 3 times.
  double scale[3];
  bool usable[3];
  for (int a = 0; a < 3; ++a) {
    const double extent = cbox.hi[a] - cbox.lo[a];
    usable[a] = extent > 0 && std::isfinite(extent);
    scale[a] = usable[a] ? kBins / extent : 0;
  }
  if (!usable[0] && !usable[1] && !usable[2]) return false;
  std::array<std::array<Bin, kBins>, 3> bins;
  for (const uint32_t* p = begin; p != end; ++p) {
    const Prim& prim = prims[*p];
    for (int a = 0; a < 3; ++a) {
      if (!usable[a]) continue;
      Bin& bin = bins[a][bin_index(prim.centroid[a], cbox.lo[a], scale[a])];
      bin.box.grow(prim.box);
      ++bin.count;
    }
  }
  double best = std::numeric_limits<double>::infinity();
  bool found = false;
  for (int a = 0; a < 3; ++a) {
    if (!usable[a]) continue;
    // Sweep from the right for suffix areas/counts, then from the left.
    std::array<double, kBins> right_area{};
    std::array<uint32_t, kBins> right_count{};
    Aabb acc;
    uint32_t n = 0;
    for (int b = kBins - 1; b > 0; --b) {
      acc.grow(bins[a][b].box);
      n += bins[a][b].count;
      right_area[b] = acc.surface_area();
      right_count[b] = n;
    }
    acc = Aabb{};
    n = 0;
    for (int b = 1; b < kBins; ++b) {
      acc.grow(bins[a][b - 1].box);
      n += bins[a][b - 1].count;
      if (n == 0 || right_count[b] == 0) continue;
      const double cost = acc.surface_area() * n + right_area[b] * right_count[b];
      if (cost < best || (!found && !std::isnan(cost))) {
        best = cost;
        axis = a;
        split_bin = b;
        found = true;
      }
    }
  }
  return found;
}

// Median split on the axis of largest centroid extent (x when none is finite and positive); the key
// is the centroid (NaN ordered last), then the triangle number, so equal centroids split by order.
uint32_t* median_split(const std::vector<Prim>& prims, uint32_t* begin, uint32_t* end, const Aabb& cbox) {
  int axis = 0;
  double widest = -1;
  for (int a = 0; a < 3; ++a) {
    const double e = cbox.hi[a] - cbox.lo[a];
    if (std::isfinite(e) && e > widest) {
      widest = e;
      axis = a;
    }
  }
  auto key = [&](uint32_t t) {
    double c = prims[t].centroid[axis];
    return std::isnan(c) ? std::numeric_limits<double>::infinity() : c;
  };
  uint32_t* mid = begin + (end - begin) / 2;
  std::nth_element(begin, mid, end, [&](uint32_t a, uint32_t b) {
    const double ka = key(a), kb = key(b);
    return ka < kb || (ka == kb && a < b);
  });
  // Keep each side in triangle order (pieces list their triangles in original order).
  std::sort(begin, mid);
  std::sort(mid, end);
  return mid;
}

}  // namespace

std::vector<Mesh> split_mesh(const Mesh& mesh, uint32_t max_triangles) {
  if (max_triangles == 0) throw Error(ExitCode::kUsage, "split_mesh: max_triangles must be > 0");
  mesh_detail::validate_mesh(mesh, "split_mesh");
  const uint64_t count = mesh.triangle_count();
  std::vector<Mesh> pieces;
  if (count == 0) return pieces;

  std::vector<Prim> prims(count);
  std::vector<uint32_t> order(count);
  for (uint32_t t = 0; t < count; ++t) {
    Prim& p = prims[t];
    for (int k = 0; k < 3; ++k) p.box.grow(to_d(mesh.positions[mesh.indices[3 * size_t(t) + k]]));
    Vec3d sum{0, 0, 0};
    for (int k = 0; k < 3; ++k) sum = sum + to_d(mesh.positions[mesh.indices[3 * size_t(t) + k]]);
    p.centroid = sum * (1.0 / 3.0);
    order[t] = t;
  }

  // Depth-first with an explicit stack (SAH splits can be unbalanced): right pushed before left, so
  // leaves come out left to right.
  struct Range {
    uint32_t begin, end;
  };
  std::vector<Range> stack{{0, uint32_t(count)}};
  std::vector<std::vector<uint32_t>> leaves;
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    uint32_t* b = order.data() + r.begin;
    uint32_t* e = order.data() + r.end;
    if (r.end - r.begin <= max_triangles) {
      leaves.emplace_back(b, e);
      continue;
    }
    Aabb cbox;
    for (const uint32_t* p = b; p != e; ++p) cbox.grow(prims[*p].centroid);
    int axis = 0, split_bin = 0;
    uint32_t* mid;
    if (find_sah_split(prims, b, e, cbox, axis, split_bin)) {
      // Stable: both sides keep triangle order.
      const double lo = cbox.lo[axis], scale = kBins / (cbox.hi[axis] - cbox.lo[axis]);  // as find_sah_split's
      mid = std::stable_partition(b, e, [&](uint32_t t) { return bin_index(prims[t].centroid[axis], lo, scale) < split_bin; });
    } else {
      mid = median_split(prims, b, e, cbox);
    }
    if (mid == b || mid == e) throw Error(ExitCode::kInternal, "split_mesh: empty BVH child");
    const uint32_t m = uint32_t(mid - order.data());
    stack.push_back({m, r.end});
    stack.push_back({r.begin, m});
  }

  pieces.resize(leaves.size());
  for (size_t i = 0; i < leaves.size(); ++i) {
    Mesh& piece = pieces[i];
    piece.name = mesh.name + "#" + std::to_string(i);
    piece.primitives = mesh.primitives;
    mesh_detail::extract_triangles(mesh, leaves[i], piece);
  }
  return pieces;
}

}  // namespace rtp
