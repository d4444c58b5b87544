// lib/voxel unit tests (TESTING.md item 8, "culling never drops a real hit", at the unit level):
// conservative voxelization against an exact separating-axis reference, and the thin foil.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "voxel/voxel.h"
#include "voxel_rng.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using voxel::DagHit;
using voxel::DagPool;
using voxel::DagView;
using voxel::Grid;
using voxel::LocalDag;

// ---------------------------------------------------------------------------------------------
// Exact triangle/box overlap: the 13-axis separating-axis test on integers (every input is a
// multiple of 2^-kScale, so scaled coordinates are exact __int128 values; products stay below 2^126).
constexpr int kScale = 32;
using I = __int128;
struct IV {
  I v[3];
};

I to_fixed(double d) {
  const double s = std::ldexp(d, kScale);
  EXPECT_EQ(s, std::floor(s)) << d << " is not a multiple of 2^-" << kScale;
  EXPECT_LT(std::fabs(s), 0x1.0p40) << d << " is too large for the exact reference";
  return I(int64_t(s));
}
IV to_fixed(const Vec3d& p) { return {{to_fixed(p.x), to_fixed(p.y), to_fixed(p.z)}}; }
IV sub(const IV& a, const IV& b) { return {{a.v[0] - b.v[0], a.v[1] - b.v[1], a.v[2] - b.v[2]}}; }
IV cross(const IV& a, const IV& b) {
  return {{a.v[1] * b.v[2] - a.v[2] * b.v[1], a.v[2] * b.v[0] - a.v[0] * b.v[2], a.v[0] * b.v[1] - a.v[1] * b.v[0]}};
}
I dot(const IV& a, const IV& b) { return a.v[0] * b.v[0] + a.v[1] * b.v[1] + a.v[2] * b.v[2]; }

// Closed triangle (a, b, c) and closed box [lo, hi] intersect. Zero axes (degenerate triangles)
// separate nothing; the remaining axes are still a complete set for segments and points.
bool sat_overlap(const IV& a, const IV& b, const IV& c, const IV& lo, const IV& hi) {
  auto separated = [&](const IV& ax) {
    if (ax.v[0] == 0 && ax.v[1] == 0 && ax.v[2] == 0) return false;
    const I pa = dot(ax, a), pb = dot(ax, b), pc = dot(ax, c);
    const I tmin = std::min({pa, pb, pc}), tmax = std::max({pa, pb, pc});
    I bmin = 0, bmax = 0;
    for (int k = 0; k < 3; ++k) {
      bmin += ax.v[k] * (ax.v[k] > 0 ? lo.v[k] : hi.v[k]);
      bmax += ax.v[k] * (ax.v[k] > 0 ? hi.v[k] : lo.v[k]);
    }
    return tmax < bmin || tmin > bmax;
  };
  const IV e[3] = {sub(b, a), sub(c, b), sub(a, c)};
  for (int k = 0; k < 3; ++k) {
    IV u{{0, 0, 0}};
    u.v[k] = 1;
    if (separated(u)) return false;
    for (const IV& ei : e)
      if (separated(cross(ei, u))) return false;
  }
  return !separated(cross(e[0], e[1]));
}

// Reference voxelization: every cell whose box grown by `grow` (a multiple of 2^-kScale) the
// triangle touches.
Grid reference_voxels(const Grid& shape, const Vec3d& a, const Vec3d& b, const Vec3d& c, double grow) {
  Grid g(shape.origin, shape.cell, shape.resolution);
  const IV fa = to_fixed(a), fb = to_fixed(b), fc = to_fixed(c);
  const I cell = to_fixed(shape.cell), gr = to_fixed(grow);
  const IV org = to_fixed(shape.origin);
  for (uint32_t z = 0; z < g.resolution; ++z)
    for (uint32_t y = 0; y < g.resolution; ++y)
      for (uint32_t x = 0; x < g.resolution; ++x) {
        const uint32_t i[3] = {x, y, z};
        IV lo, hi;
        for (int k = 0; k < 3; ++k) {
          lo.v[k] = org.v[k] + I(i[k]) * cell - gr;
          hi.v[k] = org.v[k] + I(i[k] + 1) * cell + gr;
        }
        if (sat_overlap(fa, fb, fc, lo, hi)) g.set(x, y, z);
      }
  return g;
}

// Cells set in `a` but not in `b`.
uint64_t missing(const Grid& a, const Grid& b) {
  uint64_t n = 0;
  const std::vector<uint64_t> da = a.dense(), db = b.dense();
  for (size_t i = 0; i < da.size(); ++i) n += uint64_t(std::popcount(da[i] & ~db[i]));
  return n;
}

bool zero_area(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const IV n = cross(sub(to_fixed(b), to_fixed(a)), sub(to_fixed(c), to_fixed(b)));
  return n.v[0] == 0 && n.v[1] == 0 && n.v[2] == 0;
}

enum class Family { kDyadic, kAxisAligned, kOnGridPlanes, kTiny, kNeedle, kDegenerate, kFloat };
const char* family_name(Family f) {
  switch (f) {
    case Family::kDyadic: return "dyadic";
    case Family::kAxisAligned: return "axis-aligned";
    case Family::kOnGridPlanes: return "on grid planes";
    case Family::kTiny: return "tiny (inside one cell)";
    case Family::kNeedle: return "needle";
    case Family::kDegenerate: return "degenerate (zero area)";
    case Family::kFloat: return "float vertices";
  }
  return "?";
}

// One random triangle of a family in the grid's neighbourhood (grid units, then placed).
void make_triangle(Rng& rng, Family f, const Grid& g, Vec3d v[3]) {
  const double R = g.resolution;
  auto place = [&](double gx, double gy, double gz) { return g.origin + Vec3d{gx, gy, gz} * g.cell; };
  auto dy = [&](int bits) {
    return place(rng.dyadic(-1, R + 1, bits), rng.dyadic(-1, R + 1, bits), rng.dyadic(-1, R + 1, bits));
  };
  switch (f) {
    case Family::kDyadic:
      for (int i = 0; i < 3; ++i) v[i] = dy(6);  // few bits: the double arithmetic under test is exact
      break;
    case Family::kAxisAligned: {
      const int w = int(rng.below(3));
      const double plane = rng.below(2) ? double(rng.below(g.resolution + 1)) : rng.dyadic(0, R, 6);
      for (int i = 0; i < 3; ++i) {
        Vec3d p{rng.dyadic(-1, R + 1, 6), rng.dyadic(-1, R + 1, 6), rng.dyadic(-1, R + 1, 6)};
        p[w] = plane;
        v[i] = place(p.x, p.y, p.z);
      }
      break;
    }
    case Family::kOnGridPlanes:
      for (int i = 0; i < 3; ++i) {
        Vec3d p{rng.dyadic(-1, R + 1, 4), rng.dyadic(-1, R + 1, 4), rng.dyadic(-1, R + 1, 4)};
        for (int k = 0; k < 3; ++k)
          if (rng.below(3) != 0) p[k] = double(int(rng.below(g.resolution + 1)));  // exactly on a cell plane
        v[i] = place(p.x, p.y, p.z);
      }
      break;
    case Family::kTiny: {
      // Within one cell (sometimes touching its faces, edges or corners).
      Vec3d base{double(rng.below(g.resolution)), double(rng.below(g.resolution)), double(rng.below(g.resolution))};
      for (int i = 0; i < 3; ++i) {
        Vec3d p = base;
        for (int k = 0; k < 3; ++k) p[k] += rng.below(4) == 0 ? double(rng.below(2)) : rng.dyadic(0, 1, 20);
        v[i] = place(p.x, p.y, p.z);
      }
      break;
    }
    case Family::kNeedle: {
      const Vec3d a = dy(6), b = dy(6);
      const double s = rng.dyadic(0, 1, 8);
      Vec3d m = a + (b - a) * s;
      for (int k = 0; k < 3; ++k) m[k] = std::ldexp(std::round(std::ldexp(m[k], 20)), -20) + rng.dyadic(-1, 1, 3) * 0x1.0p-16;
      v[0] = a, v[1] = b, v[2] = m;
      break;
    }
    case Family::kDegenerate: {
      const Vec3d a = dy(6), b = dy(6);
      switch (rng.below(3)) {
        case 0: v[0] = v[1] = v[2] = a; break;                                   // a point
        case 1: v[0] = a, v[1] = a, v[2] = b; break;                             // two equal vertices
        default: v[0] = a, v[1] = b, v[2] = a + (b - a) * rng.dyadic(-1, 2, 3);  // collinear
      }
      break;
    }
    case Family::kFloat:
      // Vertices as a mesh stores them: floats (exact multiples of 2^-28 here, |x| >= 1/16 or 0).
      for (int i = 0; i < 3; ++i) {
        Vec3d p;
        for (int k = 0; k < 3; ++k) {
          float x = float(g.origin[k] + rng.range(-1, R + 1) * g.cell);
          if (std::fabs(x) < 0.0625f) x = 0;
          p[k] = x;
        }
        v[i] = p;
      }
      break;
  }
}

// TESTING.md item 8: the conservative voxelization sets every cell a triangle touches (an
// independent exact 13-axis SAT decides), and no cell farther than its margin; thin voxelization
// leaves touched cells unset.
TEST(VoxelVoxelize, ConservativeEqualsExactSeparatingAxisReference) {
  Rng rng(1);
  const Family families[] = {Family::kDyadic, Family::kAxisAligned, Family::kOnGridPlanes, Family::kTiny,
                             Family::kNeedle, Family::kDegenerate,  Family::kFloat};
  const double kTinyGrow = 0x1.0p-20;  // "farther than margin + tiny"
  uint64_t triangles = 0, thin_missed = 0, thin_touched = 0;
  for (Family f : families) {
    uint64_t fam_missing = 0, fam_extra = 0, fam_ref = 0, fam_set = 0, fam_tris = 0;
    for (int t = 0; t < 700; ++t) {
      const uint32_t R = 4u << rng.below(3);                                         // 4, 8, 16
      const double cell = std::ldexp(double(1 + rng.below(4)), -int(rng.below(3)));  // 1/4 .. 4, dyadic
      const Vec3d origin{rng.dyadic(-3, 3, 4), rng.dyadic(-3, 3, 4), rng.dyadic(-3, 3, 4)};
      const Grid shape(origin, cell, R);
      Vec3d v[3];
      make_triangle(rng, f, shape, v);
      // Margins: 0 where the double arithmetic of the test is exact (few-bit dyadic inputs), else a
      // small one covering its rounding (like MeshProxies's 64 eps), and sometimes a large one.
      const bool exact = f != Family::kFloat && f != Family::kTiny && f != Family::kNeedle;
      const double rounding = exact ? 0.0 : 0x1.0p-32;
      const double margin = rng.below(4) == 0 ? cell * std::ldexp(1.0, -int(2 + rng.below(4))) : 0.0;
      Grid got = shape;
      voxel::voxelize_triangle(got, v[0], v[1], v[2], margin + rounding);
      const Grid must = reference_voxels(shape, v[0], v[1], v[2], margin);
      fam_missing += missing(must, got);
      EXPECT_EQ(missing(must, got), 0u) << family_name(f) << " triangle " << t << " R=" << R << " cell=" << cell << " origin=("
                                        << origin.x << "," << origin.y << "," << origin.z << ") margin=" << margin << " ("
                                        << v[0].x << "," << v[0].y << "," << v[0].z << ") (" << v[1].x << "," << v[1].y << ","
                                        << v[1].z << ") (" << v[2].x << "," << v[2].y << "," << v[2].z << ")";
      if (!zero_area(v[0], v[1], v[2])) {
        const Grid may = reference_voxels(shape, v[0], v[1], v[2], margin + rounding + kTinyGrow);
        fam_extra += missing(got, may);
        EXPECT_EQ(missing(got, may), 0u) << family_name(f) << " triangle " << t << ": cells set farther than the margin";
      } else {
        // Zero area: the grown bounding box is the documented superset; nothing outside it.
        Grid box = shape;
        Vec3d lo, hi;
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min({v[0][k], v[1][k], v[2][k]}) - margin - rounding - kTinyGrow;
          hi[k] = std::max({v[0][k], v[1][k], v[2][k]}) + margin + rounding + kTinyGrow;
        }
        box.mark_box(lo, hi);
        EXPECT_EQ(missing(got, box), 0u) << family_name(f) << " triangle " << t << ": cells outside the grown bounds";
      }
      fam_ref += must.count();
      fam_set += got.count();
      ++fam_tris;
      if (margin == 0 && f != Family::kDegenerate) {
        Grid thin = shape;
        voxel::voxelize_triangle_thin(thin, v[0], v[1], v[2]);
        thin_missed += missing(must, thin);
        thin_touched += must.count();
      }
    }
    std::printf("[ voxelize ] %-24s %5llu triangles, %7llu touched cells, %7llu set, %llu missing, %llu beyond the margin\n",
                family_name(f), (unsigned long long)fam_tris, (unsigned long long)fam_ref, (unsigned long long)fam_set,
                (unsigned long long)fam_missing, (unsigned long long)fam_extra);
    triangles += fam_tris;
    EXPECT_GT(fam_ref, 0u) << family_name(f) << ": the triangles must touch the grids";
    // Not "set everything": beyond the exact set only what the rounding margin reaches (the zero-area
    // triangles' grown bounding boxes are checked triangle by triangle above).
    if (f != Family::kDegenerate) {
      EXPECT_LE(fam_set, fam_ref + fam_ref / 50) << family_name(f);
    }
  }
  std::printf("[ voxelize ] thin voxelization leaves %llu of %llu touched cells unset\n", (unsigned long long)thin_missed,
              (unsigned long long)thin_touched);
  EXPECT_GE(triangles, 4000u);
  // The foil has gaps.
  EXPECT_GT(thin_missed, 0u);
}

// TESTING.md item 8: a triangle exactly on a grid plane sets the cells on both sides (a ray along
// the plane hits it from either); one inside a cell sets only that cell.
// The AVX2 rows of a small box (voxelize_rows_avx2.cpp) set exactly the cells the scalar loop sets:
// float vertices (rounding everywhere), boxes of one to five cells a side anywhere in grids of
// 16^3 and 32^3 with float origins and cells, margins from 0 to a quarter cell, and NaN-free
// slivers, grid by grid, cell by cell.
TEST(VoxelVoxelize, Avx2RowsSetTheScalarCells) {
  if (detect_isa() == Isa::kScalar) GTEST_SKIP() << "this CPU has no AVX2: only the scalar loop runs here";
  Rng rng(7);
  uint64_t triangles = 0, small_boxes = 0, small_across = 0, cells = 0;
  for (int t = 0; t < 20000; ++t) {
    const uint32_t R = 16u << rng.below(2);
    const float cell = float(rng.range(0.01, 3.0));
    const Vec3d origin{float(rng.range(-50, 50)), float(rng.range(-50, 50)), float(rng.range(-50, 50))};
    const Grid shape(origin, cell, R);
    // A region of 1..5 cells a side, vertices as floats inside it (sometimes on its faces).
    int size[3];
    Vec3d base;
    for (int k = 0; k < 3; ++k) {
      size[k] = 1 + int(rng.below(5));
      base[k] = origin[k] + double(rng.below(R - size[k] + 1)) * cell;
    }
    Vec3d v[3];
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) {
        const double u = rng.below(8) == 0 ? double(rng.below(2)) : rng.uniform();
        v[i][k] = float(base[k] + u * size[k] * cell);
      }
    if (rng.below(6) == 0) v[2] = v[0] + (v[1] - v[0]) * rng.uniform() + Vec3d{1e-6, -1e-6, 1e-6};  // sliver
    // A vertex on a grid corner with no margin: plane and edge values of exactly zero at cell corners,
    // where a comparison's direction or a sum's grouping decides the cell.
    const bool corner = rng.below(3) == 0;
    if (corner)
      for (int k = 0; k < 3; ++k) v[0][k] = base[k] + double(rng.below(uint32_t(size[k]) + 1)) * cell;
    const double margin = corner || rng.below(3) == 0 ? 0.0 : cell * rng.range(0, 0.25);
    Grid scalar = shape, avx2 = shape;
    voxel::voxelize_triangle(scalar, v[0], v[1], v[2], margin, Isa::kScalar);
    voxel::voxelize_triangle(avx2, v[0], v[1], v[2], margin, Isa::kAvx2);
    ASSERT_EQ(avx2.dense(), scalar.dense()) << "triangle " << t << " R=" << R << " cell=" << cell << " margin=" << margin << " ("
                                            << v[0].x << "," << v[0].y << "," << v[0].z << ") (" << v[1].x << "," << v[1].y << ","
                                            << v[1].z << ") (" << v[2].x << "," << v[2].y << "," << v[2].z << ")";
    ++triangles;
    cells += scalar.count();
    // Boxes the rows take (at most 8 cells along x, 64 in all) and the single-row path does not, and
    // of those the ones across a face of a 4^3 block (their cells gathered block by block).
    int spans = 0, volume = 1;
    bool across = false;
    for (int k = 0; k < 3; ++k) {
      const double lo = std::min({v[0][k], v[1][k], v[2][k]}) - margin, hi = std::max({v[0][k], v[1][k], v[2][k]}) + margin;
      const int first = int(std::floor((lo - origin[k]) / cell)), last = int(std::floor((hi - origin[k]) / cell));
      const int n = last - first + 1;
      spans += n > 1;
      volume *= n;
      across = across || (std::max(first, 0) >> 2) != (std::min(last, int(R) - 1) >> 2);
    }
    small_boxes += spans >= 2 && volume <= 64;
    small_across += spans >= 2 && volume <= 64 && across;
  }
  std::printf(
      "[ voxelize ] AVX2 rows vs scalar: %llu triangles (%llu small boxes of two or more rows, %llu of them "
      "across a block face), %llu cells, all equal\n",
      (unsigned long long)triangles, (unsigned long long)small_boxes, (unsigned long long)small_across,
      (unsigned long long)cells);
  EXPECT_GT(small_boxes, triangles / 3);
  EXPECT_GT(small_across, small_boxes / 4);
  EXPECT_GT(cells, 10 * triangles);
}

TEST(VoxelVoxelize, PlanesAndSingleCells) {
  Grid g({0, 0, 0}, 1, 8);
  voxel::voxelize_triangle(g, {1, 2, 3}, {2, 2, 3}, {1, 3, 3}, 0);  // z = 3, covering cell column (1, 2)
  EXPECT_TRUE(g.get(1, 2, 2));
  EXPECT_TRUE(g.get(1, 2, 3));
  EXPECT_FALSE(g.get(1, 2, 4));
  EXPECT_FALSE(g.get(3, 3, 3));
  Grid one({0, 0, 0}, 1, 8);
  voxel::voxelize_triangle(one, {4.25, 4.25, 4.25}, {4.5, 4.25, 4.25}, {4.25, 4.5, 4.75}, 0);
  EXPECT_EQ(one.count(), 1u);
  EXPECT_TRUE(one.get(4, 4, 4));
  // Exactly on the grid's upper face: the boundary cells touch it (closed boxes), as on the lower face.
  Grid top({0, 0, 0}, 1, 8);
  voxel::voxelize_triangle(top, {8, 2, 3}, {8, 3, 3}, {8, 2, 4}, 0);
  EXPECT_TRUE(top.get(7, 2, 3));
  EXPECT_EQ(top.count(), 8u);  // the cells of the x = 7 layer whose closed boxes touch it (vertices included)
  Grid low({0, 0, 0}, 1, 8);
  voxel::voxelize_triangle(low, {0, 2.5, 3.5}, {0, 2.75, 3.5}, {0, 2.5, 3.75}, 0);
  EXPECT_EQ(low.count(), 1u);
  EXPECT_TRUE(low.get(0, 2, 3));
  Grid boxed({0, 0, 0}, 1, 8);
  boxed.mark_box({8, 1.5, 1.5}, {9, 1.5, 1.5});
  EXPECT_EQ(boxed.count(), 1u);
  EXPECT_TRUE(boxed.get(7, 1, 1));
  Grid thin({0, 0, 0}, 1, 8);
  voxel::voxelize_triangle_thin(thin, {1, 2, 3}, {2, 2, 3}, {1, 3, 3});
  EXPECT_EQ(thin.count(), 1u);  // one cell of the two
}

// mark_box fills whole 4x4x4 blocks with per-axis masks: it must set exactly the cells whose closed
// boxes meet the closed query box, for boxes inside, across and beyond the grid, on planes or not.
TEST(VoxelVoxelize, MarkBoxSetsExactlyTheOverlappedCells) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-3, 19);
  std::uniform_int_distribution<int> on_plane(0, 2);
  const Vec3d origin{-1, -1, -1};
  const double cell = 0.5;
  const uint32_t R = 32;
  for (int trial = 0; trial < 400; ++trial) {
    Vec3d lo, hi;
    for (int k = 0; k < 3; ++k) {
      double a = u(rng), b = a + std::abs(u(rng)) * (trial % 4 == 0 ? 1.0 : 0.1);
      if (on_plane(rng) == 0) a = std::floor(a * 2) / 2, b = std::ceil(b * 2) / 2;  // on cell planes
      lo[k] = a;
      hi[k] = b;
    }
    Grid g(origin, cell, R);
    g.mark_box(lo, hi);
    uint64_t expected = 0;
    for (uint32_t z = 0; z < R; ++z)
      for (uint32_t y = 0; y < R; ++y)
        for (uint32_t x = 0; x < R; ++x) {
          const uint32_t c[3] = {x, y, z};
          bool in = true;
          for (int k = 0; k < 3; ++k) in = in && origin[k] + c[k] * cell <= hi[k] && origin[k] + (c[k] + 1) * cell >= lo[k];
          expected += in;
          ASSERT_EQ(g.get(x, y, z), in) << "trial " << trial << " cell (" << x << "," << y << "," << z << ")";
        }
    EXPECT_EQ(g.count(), expected) << "trial " << trial;
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
