// Voxelizing one batching point (Molenaar 2019 §4.2): pieces triangle by triangle, instances through
// their meshes' coarse local occupancy, each through the exact inverse of the world->local map the
// tracer uses (float L^-1, double T), with the margin of point_voxels.h.
#include "voxel/point_voxels.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <bit>
#include <cmath>
#include <limits>

#include "bvh/bvh.h"

namespace rtp::voxel {
namespace {

constexpr double kU = 1.0 / 16777216.0;  // 2^-24: float unit roundoff
constexpr double kSafety = 16;
constexpr uint32_t kLocalRes = 32;
constexpr uint64_t kInstanceDetail = 256;
constexpr size_t kSpanTriangles = 8192;  // a parallel unit of a point's triangle voxelization

float round_up(double v) {
  float f = float(v);
  if (double(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}
float round_down(double v) {
  float f = float(v);
  if (double(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

double row_norm(const double m[12]) {  // infinity norm of the 3x3 part
  double n = 0;
  for (int r = 0; r < 3; ++r) n = std::max(n, std::fabs(m[4 * r]) + std::fabs(m[4 * r + 1]) + std::fabs(m[4 * r + 2]));
  return n;
}

// The transform the tracer effectively applies to an instance's local geometry: the exact inverse of
// its stored world->local map (SPEC §2.4), and the error terms of point_voxels.h.
struct Effective {
  bool usable = false;
  double minv[12];
  double margin = 0, kappa = 0;
  Vec3d apply(const Vec3d& p) const {
    Vec3d o;
    for (int r = 0; r < 3; ++r) o[r] = minv[4 * r] * p.x + minv[4 * r + 1] * p.y + minv[4 * r + 2] * p.z + minv[4 * r + 3];
    return o;
  }
};

Effective effective(const fmt::InstanceRecord& rec, const Aabb& local_bounds) {
  Effective e;
  if (!record_invertible(rec)) return e;  // singular: the tracer never hits it
  // The tracer's world->local map (SPEC §2.4): M = [L^-1 | -L^-1·T] with the float L^-1 and double T.
  // Its exact inverse is [(L^-1)^-1 | T]: the translation is T itself, the linear part inverted here.
  Affine3x4 m;
  double md[12];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m(r, c) = md[4 * r + c] = rec.inverse_linear[3 * r + c];
    m(r, 3) = 0;
    md[4 * r + 3] = -(md[4 * r] * rec.translation[0] + md[4 * r + 1] * rec.translation[1] + md[4 * r + 2] * rec.translation[2]);
  }
  if (!invert_affine(m, e.minv)) return e;
  for (int r = 0; r < 3; ++r) e.minv[4 * r + 3] = rec.translation[r];
  const double ni = row_norm(e.minv), nm = row_norm(md);
  double vmax = 0, tmax = 0;
  for (int k = 0; k < 3; ++k) {
    vmax = std::max({vmax, std::fabs(local_bounds.lo[k]), std::fabs(local_bounds.hi[k])});
    tmax = std::max(tmax, std::fabs(md[4 * k + 3]));
  }
  e.margin = kSafety * kU * ni * (tmax + 2 * vmax);
  e.kappa = ni * nm;
  e.usable = std::isfinite(e.margin) && std::isfinite(e.kappa);
  return e;
}

// World box of a local box through the effective transform, grown by `grow`: the exact bounds of an
// affinely mapped box are Minv(centre) ± |Minv|·half-extent (two products instead of eight corners).
void world_box(const Effective& e, const Vec3d& lo, const Vec3d& hi, double grow, Vec3d& wlo, Vec3d& whi) {
  const Vec3d c = e.apply((lo + hi) * 0.5), h = (hi - lo) * 0.5;
  for (int r = 0; r < 3; ++r) {
    const double ext = std::fabs(e.minv[4 * r]) * h.x + std::fabs(e.minv[4 * r + 1]) * h.y + std::fabs(e.minv[4 * r + 2]) * h.z;
    // The two roundings of the centre and extent (relative 2^-52 of their magnitude) go into the growth.
    const double slack = 4 * std::numeric_limits<double>::epsilon() * (std::fabs(c[r]) + ext);
    wlo[r] = c[r] - ext - grow - slack;
    whi[r] = c[r] + ext + grow + slack;
  }
}

// Molenaar 2019 §4.2 (instances through their meshes' coarse occupancy), in grid units: the occupied
// local cells of one level are a lattice, and q(v) = (Minv·v − origin) / cell maps it affinely, so a
// cell's box in grid units is its centre q0 + x·dx + y·dy + z·dz ± a half extent E that is the same
// for every cell of the level (|A|·lc/2, the margin, and the rounding pad below). Each box marks the
// cells it overlaps (cell i spans [i, i + 1]): the boxes the world-space path built and marked, up to
// the rounding of either, which the pad covers — relative 10^-9 of every magnitude that enters the
// sums (double rounding is 2^-52 per operation; a few dozen operations).
void mark_instance_cells(Grid& g, const Effective& e, const MeshProxies::Proxy& p, const MeshProxies::Level& lv) {
  const uint32_t ratio = kLocalRes / lv.r;  // exact: a level's resolution divides kLocalRes
  const double inv = 1 / g.cell, lc = p.cell * ratio, r = double(g.resolution);
  double q0[3], step[3][3], E[3];
  for (int row = 0; row < 3; ++row) {
    const double b = (e.minv[4 * row + 3] - g.origin[row]) * inv;
    double c0 = b, ext = 0, mag = 1 + std::fabs(b);
    for (int c = 0; c < 3; ++c) {
      const double a = e.minv[4 * row + c] * inv;
      c0 += a * (p.origin[c] + 0.5 * lc);
      ext += std::fabs(a) * (0.5 * lc);
      step[c][row] = a * lc;
      mag += std::fabs(a) * (std::fabs(p.origin[c]) + p.cell * kLocalRes + lc);
    }
    q0[row] = c0;
    E[row] = ext + e.margin * inv + 1e-9 * (mag + std::fabs(c0) + ext);
  }
  int f[3], l[3];
  for (const uint32_t c : lv.cells) {  // the occupied cells in scan order (z, y, x ascending), not all r^3
    const double x = double(c & 255), y = double(c >> 8 & 255), z = double(c >> 16);
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const double q = q0[k] + x * step[0][k] + y * step[1][k] + z * step[2][k];
      const double lo = q - E[k], hi = q + E[k];
      inside &= hi >= 0 && lo < r;  // false for NaN too
      // Truncation is floor on the values clamped at 0 (below 0 the first cell is 0 whatever the floor).
      f[k] = inside ? int(std::max(lo, 0.0)) : 0;
      l[k] = inside ? std::min(int(std::min(hi, r)), int(g.resolution) - 1) : 0;
    }
    if (inside) g.mark_cells(f, l);
  }
}

}  // namespace

uint32_t choose_resolution(uint64_t triangles) {
  const double target = std::sqrt(double(std::max<uint64_t>(triangles, 1))) / 2;
  uint32_t r = 32;
  while (r < 512 && double(r) * std::sqrt(2.0) < target) r *= 2;  // nearest power of two (log scale)
  return r;
}

MeshProxies::MeshProxies(const Scene& scene, const Plan& plan) : proxies_(scene.meshes.size()) {
  std::vector<uint32_t> todo;
  for (uint32_t m = 0; m < scene.meshes.size(); ++m)
    if (m < plan.mesh_instanced.size() && plan.mesh_instanced[m]) todo.push_back(m);
  tbb::parallel_for(size_t(0), todo.size(), [&](size_t i) {
    const Mesh& mesh = scene.meshes[todo[i]];
    Proxy& p = proxies_[todo[i]];
    const Aabb b = plan.mesh_bounds[todo[i]];
    p.bounds = b;
    if (b.empty()) return;
    double ext = 0, mag = 0;
    for (int k = 0; k < 3; ++k)
      ext = std::max(ext, b.hi[k] - b.lo[k]), mag = std::max({mag, std::fabs(b.lo[k]), std::fabs(b.hi[k])});
    // Double rounding of the edge tests only: local vertices are exact floats.
    const double margin = 64 * std::numeric_limits<double>::epsilon() * (mag + ext);
    p.cell = std::max((ext + 4 * margin) / kLocalRes * (1 + 1e-9), std::numeric_limits<double>::min() * 1e6);
    p.origin = b.lo - Vec3d{margin, margin, margin};
    Grid g(p.origin, p.cell, kLocalRes);
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
      voxelize_triangle(g, to_d(mesh.positions[mesh.indices[t]]), to_d(mesh.positions[mesh.indices[t + 1]]),
                        to_d(mesh.positions[mesh.indices[t + 2]]), margin);
    for (uint32_t r = kLocalRes;; r /= 2) {
      Level lv{r, {}};
      std::vector<uint8_t> occupied(size_t(r) * r * r, 0);  // r^3, x fastest
      const uint32_t step = kLocalRes / r;
      for (uint32_t z = 0; z < kLocalRes; ++z)
        for (uint32_t y = 0; y < kLocalRes; ++y)
          for (uint32_t x = 0; x < kLocalRes; ++x)
            if (g.get(x, y, z)) occupied[x / step + r * (y / step + size_t(r) * (z / step))] = 1;
      for (uint32_t z = 0; z < r; ++z)
        for (uint32_t y = 0; y < r; ++y)
          for (uint32_t x = 0; x < r; ++x)
            if (occupied[x + r * (y + size_t(r) * z)]) lv.cells.push_back(x | y << 8 | z << 16);
      p.levels.insert(p.levels.begin(), std::move(lv));
      if (r == 1) break;
    }
  });
}

PointProxy voxelize_point(const Scene& scene, const Plan& plan, const MeshProxies& meshes, const fmt::InstanceRecord* records,
                          const BatchingPoint& bp, const VoxelOptions& o) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  Clock::duration in_parallel{0};  // wall time of the span loop, replaced by its threads' summed time
  std::atomic<int64_t> span_ns{0};
  PointProxy out;
  // Error terms first: they size the grid.
  std::vector<Effective> piece_eff(bp.pieces.size()), inst_eff(bp.instances.size());
  double margin = 0, kappa = 1;
  for (size_t i = 0; i < bp.pieces.size(); ++i) {
    const UniquePiece& pc = plan.pieces[bp.pieces[i]];
    piece_eff[i] = effective(records[pc.instance], pc.bounds);
  }
  for (size_t i = 0; i < bp.instances.size(); ++i) {
    inst_eff[i] = effective(records[bp.instances[i]], meshes[scene.instances[bp.instances[i]].mesh].bounds);
  }
  for (const auto* v : {&piece_eff, &inst_eff})
    for (const Effective& e : *v)
      if (e.usable) margin = std::max(margin, e.margin), kappa = std::max(kappa, e.kappa);
  if (o.thin) margin = 0;
  // An instance adds at most kInstanceDetail triangles' worth of detail: it is voxelized through its
  // mesh's coarse local occupancy, so more grid cells would only repeat the same boxes (and a point of
  // 300 trees of 12k triangles each would get 512^3 cells for what 128^3 shows).
  uint64_t detail = bp.unique_triangles;
  for (uint32_t i : bp.instances)
    detail += std::min<uint64_t>(scene.meshes[scene.instances[i].mesh].triangle_count(), kInstanceDetail);
  uint32_t res = o.resolution ? o.resolution : choose_resolution(detail);
  // Grid: the point's bounds grown by twice the margin (the effective geometry may lie up to `margin`
  // outside the bounds computed from the double transforms), cubic cells, origin and cell as floats.
  Vec3d lo = bp.bounds.lo, hi = bp.bounds.hi;
  if (bp.bounds.empty()) lo = hi = Vec3d{0, 0, 0};
  double ext = 0, mag = 0;
  for (int k = 0; k < 3; ++k) mag = std::max({mag, std::fabs(lo[k]), std::fabs(hi[k])});
  const double grow = 2 * margin + 4 * kU * mag + std::numeric_limits<float>::min();
  for (int k = 0; k < 3; ++k) {
    out.grid.origin[k] = round_down(lo[k] - grow);
    ext = std::max(ext, (hi[k] + grow) - double(out.grid.origin[k]));
  }
  // Cells no smaller than twice the margin: finer ones would all be set (every triangle grown by the
  // margin covers margin/cell cells per axis) at a cost that grows with the cube of it — far from the
  // origin (3e6: margin ~6 units) a requested 1024^3 grid of a 10-unit point would test 10^8 cells
  // per triangle. The convert summary's resolution histogram shows the resolution used.
  while (res > fmt::kDagMinResolution && ext / res < 2 * margin) res /= 2;
  float cell = round_up(ext / res);
  if (!(cell > 0)) cell = std::numeric_limits<float>::min();
  for (int k = 0; k < 3; ++k)  // the float cell must still cover the grown bounds
    while (double(out.grid.origin[k]) + double(cell) * res < hi[k] + grow) cell = std::nextafter(cell, 2 * cell);
  out.grid.cell = cell;
  out.grid.resolution = res;
  out.grid.margin = round_up(margin);
  out.grid.ray_rel = o.thin ? 0.0f : round_up(kSafety * kU * kappa);
  Grid g({out.grid.origin[0], out.grid.origin[1], out.grid.origin[2]}, cell, res);

  // The pieces' triangles in spans of at most kSpanTriangles, voxelized in parallel into one grid per
  // thread, then merged: the union of the same cells whatever the split (a large point's voxels were
  // one thread's 16 ms at the end of FlightHelmet's 2-thread convert while the other thread idled).
  std::vector<std::vector<Vec3d>> world(bp.pieces.size());  // each vertex moved once, not once per triangle
  struct Span {
    uint32_t piece;
    size_t first, end;  // triangles
  };
  std::vector<Span> spans;
  for (size_t i = 0; i < bp.pieces.size(); ++i) {
    const Effective& e = piece_eff[i];
    if (!e.usable) continue;
    const Mesh& mesh = plan.pieces[bp.pieces[i]].mesh;
    world[i].resize(mesh.positions.size());
    for (size_t k = 0; k < world[i].size(); ++k) world[i][k] = e.apply(to_d(mesh.positions[k]));
    const size_t tris = mesh.indices.size() / 3;
    for (size_t t = 0; t < tris; t += kSpanTriangles) spans.push_back({uint32_t(i), t, std::min(tris, t + kSpanTriangles)});
  }
  auto voxelize_span = [&](Grid& into, const Span& sp) {
    const Mesh& mesh = plan.pieces[bp.pieces[sp.piece]].mesh;
    const std::vector<Vec3d>& w = world[sp.piece];
    const double m = piece_eff[sp.piece].margin;
    for (size_t t = 3 * sp.first; t < 3 * sp.end; t += 3) {
      const Vec3d& a = w[mesh.indices[t]];
      const Vec3d& b = w[mesh.indices[t + 1]];
      const Vec3d& c = w[mesh.indices[t + 2]];
      if (o.thin)
        voxelize_triangle_thin(into, a, b, c);
      else
        voxelize_triangle(into, a, b, c, m);
    }
  };
  if (bp.unique_triangles <= kSpanTriangles) {  // one unit of work (however many pieces): no grid per thread
    for (const Span& sp : spans) voxelize_span(g, sp);
  } else {
    tbb::enumerable_thread_specific<Grid> part([&] { return Grid(g.origin, g.cell, g.resolution); });
    const Clock::time_point t0 = Clock::now();
    tbb::parallel_for(size_t(0), spans.size(), [&](size_t k) {
      const Clock::time_point s0 = Clock::now();
      voxelize_span(part.local(), spans[k]);
      span_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - s0).count();
    });
    in_parallel = Clock::now() - t0;
    for (const Grid& p : part) g.merge(p);
  }
  for (size_t i = 0; i < bp.instances.size(); ++i) {
    const Effective& e = inst_eff[i];
    if (!e.usable) continue;
    const MeshProxies::Proxy& p = meshes[scene.instances[bp.instances[i]].mesh];
    if (p.levels.empty()) continue;  // no triangles
    const Vec3d plo = p.origin, phi = p.origin + Vec3d{1, 1, 1} * (p.cell * kLocalRes);
    Vec3d wlo, whi;
    world_box(e, plo, phi, e.margin, wlo, whi);
    double cells = 0;
    for (int k = 0; k < 3; ++k) cells = std::max(cells, (whi[k] - wlo[k]) / cell);
    size_t lv = 0;  // the level whose cells span about two grid cells (8x fewer boxes than one)
    while (lv + 1 < p.levels.size() && double(p.levels[lv].r) < cells / 2) ++lv;
    mark_instance_cells(g, e, p, p.levels[lv]);
  }
  out.set_cells = g.count();
  out.dag = build_dag(g);
  out.grid.root = out.dag.root;
  out.work_seconds = std::chrono::duration<double>(Clock::now() - start - in_parallel).count() + double(span_ns.load()) * 1e-9;
  return out;
}

}  // namespace rtp::voxel
