// subdivide_uniform / subdivide_midpoint / subdivide_to_length.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/prepare.h"
#include "mesh/shapes.h"

#if __has_include("scene/import.h") && !defined(RTP_MESH_TESTS_NO_IMPORT)
#include "scene/import.h"
#endif

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

uint64_t pow4(int n) { return uint64_t(1) << (2 * n); }

void expect_finite_within(const Mesh& m, const Aabb& box) {
  const double tol = 1e-5;
  for (const Vec3f& p : m.positions) {
    ASSERT_TRUE(is_finite(p));
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(p[a], box.lo[a] - tol);
      EXPECT_LE(p[a], box.hi[a] + tol);
    }
  }
  for (uint32_t i : m.indices) ASSERT_LT(i, m.positions.size());
}

Aabb bounds_of(const Mesh& m) {
  Aabb b;
  for (const Vec3f& p : m.positions) b.grow(to_d(p));
  return b;
}

// Children of parent i are the 4^n consecutive triangles [i * 4^n, (i + 1) * 4^n) and carry its entry.
void expect_source_follows_parents(const Mesh& child, const Mesh& parent, int n) {
  ASSERT_EQ(child.source.size(), parent.source.size() * pow4(n));
  for (size_t t = 0; t < child.source.size(); ++t) {
    const TriangleSource& p = parent.source[t / pow4(n)];
    EXPECT_EQ(child.source[t].primitive, p.primitive);
    ASSERT_EQ(child.source[t].triangle, p.triangle) << "child " << t;
  }
}

TEST(MeshSubdivide, LoopIcosphereGivesFourToTheN) {
  const Mesh base = make_icosphere(1);
  for (int n = 1; n <= 3; ++n) {
    Mesh m = base;
    UniformSubdivideResult r = subdivide_uniform(m, n);
    EXPECT_FALSE(r.used_fallback);
    EXPECT_EQ(m.triangle_count(), pow4(n) * base.triangle_count());
    // Closed genus-0 triangle mesh: V = F / 2 + 2.
    EXPECT_EQ(m.positions.size(), m.triangle_count() / 2 + 2);
    expect_finite_within(m, bounds_of(base));
    expect_source_follows_parents(m, base, n);
    // Loop shrinks towards the limit surface, but not by much on a fine sphere.
    for (const Vec3f& p : m.positions) EXPECT_GT(length(to_d(p)), 0.9);
  }
}

TEST(MeshSubdivide, LoopMeshWithBoundaryGivesFourToTheN) {
  const Mesh base = make_grid(4, 3);
  for (int n = 1; n <= 3; ++n) {
    Mesh m = base;
    subdivide_uniform(m, n);
    EXPECT_EQ(m.triangle_count(), pow4(n) * base.triangle_count());
    expect_finite_within(m, bounds_of(base));
    expect_source_follows_parents(m, base, n);
    for (const Vec3f& p : m.positions) EXPECT_EQ(p.z, 0.0f);
  }
}

TEST(MeshSubdivide, ChildTrianglesLieInTheirParent) {
  // A regular planar grid: Loop reproduces the linear parametrisation away from the grid's corners,
  // so each child lies inside its parent and keeps its orientation (+z normals).
  const Mesh base = make_grid(6, 6);
  Mesh m = base;
  subdivide_uniform(m, 1);
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const size_t parent = t / 4;
    Vec3d c{0, 0, 0}, pv[3], cv[3];
    bool touches_corner = false;
    for (int k = 0; k < 3; ++k) {
      pv[k] = to_d(base.positions[base.indices[3 * parent + k]]);
      cv[k] = to_d(m.positions[m.indices[3 * t + k]]);
      c = c + cv[k] * (1.0 / 3.0);
      touches_corner |= (pv[k].x == 0 || pv[k].x == 6) && (pv[k].y == 0 || pv[k].y == 6);
    }
    EXPECT_GT(cross(cv[1] - cv[0], cv[2] - cv[0]).z, 0) << "child " << t;
    if (touches_corner) continue;
    const double area = cross(pv[1] - pv[0], pv[2] - pv[0]).z;
    for (int k = 0; k < 3; ++k) {
      const Vec3d& a = pv[(k + 1) % 3];
      const Vec3d& b = pv[(k + 2) % 3];
      EXPECT_GT(cross(b - a, c - a).z / area, 0.01) << "child " << t << " outside parent " << parent;
    }
  }
}

TEST(MeshSubdivide, LevelZeroIsNoOpAndNegativeThrows) {
  Mesh m = make_cube();
  const Mesh orig = m;
  subdivide_uniform(m, 0);
  EXPECT_EQ(m.positions, orig.positions);
  EXPECT_EQ(m.indices, orig.indices);
  EXPECT_THROW(subdivide_uniform(m, -1), Error);
}

TEST(MeshSubdivide, NonManifoldInputDoesNotCrash) {
  Mesh fin;
  fin.primitives = {SourcePrimitive{}};
  fin.positions = {{0, 0, 0}, {1, 0, 0}, {0.5f, 1, 0}, {0.5f, -1, 0}, {0.5f, 0, 1}};
  fin.indices = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  fin.source = {{0, 0}, {0, 1}, {0, 2}};
  Mesh dup = make_tetrahedron();
  dup.indices.insert(dup.indices.end(), {1, 3, 2});
  dup.source.push_back({0, 4});
  for (const Mesh& base : {fin, dup}) {
    for (int n = 1; n <= 2; ++n) {
      Mesh m = base;
      subdivide_uniform(m, n);
      EXPECT_EQ(m.triangle_count(), pow4(n) * base.triangle_count());
      expect_finite_within(m, bounds_of(base));
      expect_source_follows_parents(m, base, n);
    }
  }
}

TEST(MeshSubdivide, MidpointSplitKeepsPositionsAndSharesEdges) {
  const Mesh base = make_cube();
  Mesh m = base;
  subdivide_midpoint(m, 2);
  EXPECT_EQ(m.triangle_count(), 16 * base.triangle_count());
  // Closed genus 0 stays closed: V = F / 2 + 2, and the original corners are untouched.
  EXPECT_EQ(m.positions.size(), m.triangle_count() / 2 + 2);
  for (size_t v = 0; v < base.positions.size(); ++v) EXPECT_EQ(m.positions[v], base.positions[v]);
  expect_source_follows_parents(m, base, 2);
}

Scene two_instance_scene(float scale_b) {
  Scene s;
  s.meshes.push_back(make_icosphere(0));  // edge ~1.05
  Instance a, b;
  a.mesh = b.mesh = 0;
  for (int i = 0; i < 3; ++i) b.transform(i, i) = scale_b;
  b.transform(0, 3) = 10;
  s.instances = {a, b};
  return s;
}

TEST(MeshSubdivide, AdaptiveLargestInstanceScaleDrivesTheLevel) {
  const double target = 0.5;
  Scene s = two_instance_scene(3);
  const Mesh base = s.meshes[0];
  SubdivideReport r = subdivide_to_length(s, target);
  ASSERT_EQ(r.meshes.size(), 1u);
  const MeshSubdivideReport& mr = r.meshes[0];
  EXPECT_NEAR(mr.max_scale, 3.0, 1e-12);
  EXPECT_FALSE(mr.hit_cap);
  ASSERT_GE(mr.levels, 1);
  EXPECT_NEAR(mr.longest_world_edge_before, 3 * longest_edge(base), 1e-9);
  EXPECT_LT(mr.longest_world_edge_after, target);
  EXPECT_LT(longest_edge(s.meshes[0]) * 3, target);
  // Applied once: 4^L x base, not per instance.
  EXPECT_EQ(s.meshes[0].triangle_count(), pow4(mr.levels) * base.triangle_count());
  EXPECT_EQ(mr.triangles_after, s.meshes[0].triangle_count());
  EXPECT_EQ(r.triangles_after, s.meshes[0].triangle_count());
  EXPECT_EQ(s.instances.size(), 2u);
  // Smallest such level: one level fewer is not enough.
  Mesh fewer = base;
  subdivide_uniform(fewer, mr.levels - 1);
  EXPECT_GE(longest_edge(fewer) * 3, target);
  // Same triangles, in the same order, as uniform subdivision in one go, up to float rounding between
  // levels (vertex numbering may differ: OpenSubdiv numbers edges differently per base mesh).
  Mesh once = base;
  subdivide_uniform(once, mr.levels);
  ASSERT_EQ(once.positions.size(), s.meshes[0].positions.size());
  ASSERT_EQ(once.indices.size(), s.meshes[0].indices.size());
  for (size_t i = 0; i < once.indices.size(); ++i)
    ASSERT_NEAR(length(to_d(once.positions[once.indices[i]]) - to_d(s.meshes[0].positions[s.meshes[0].indices[i]])), 0, 1e-6)
        << "corner " << i;

  // Only the scale-1 instance: fewer levels.
  Scene small = two_instance_scene(1);
  SubdivideReport r1 = subdivide_to_length(small, target);
  EXPECT_LT(r1.meshes[0].levels, mr.levels);
  EXPECT_LT(longest_edge(small.meshes[0]), target);
}

// prepare_scene refuses a uniform subdivision beyond its memory size before any work and runs one
// within it (PrepareOptions::memory_bytes; 0 = the machine's, which must be known here).
TEST(MeshSubdivide, UniformSubdivisionBeyondMemoryIsRefused) {
  const Scene s = two_instance_scene(1);  // one icosahedron: 20 triangles
  PrepareOptions o;
  o.subdivide_levels = 3;  // 1280 triangles: 113920 bytes at 89 each
  o.memory_bytes = 113000;
  Scene refused = s;
  try {
    prepare_scene(refused, o);
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ExitCode::kUsage);
    EXPECT_NE(std::string(e.what()).find("--subdivide 3: would make 1280 triangles from 20, about 0.0 GiB while refining "
                                         "(89 bytes per triangle)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(refused.meshes[0].triangle_count(), 20u);  // nothing refined
  o.memory_bytes = 114000;
  Scene ok = s;
  prepare_scene(ok, o);
  EXPECT_EQ(ok.meshes[0].triangle_count(), 1280u);
  EXPECT_GT(machine_memory_bytes(), uint64_t(1) << 28);
}

TEST(MeshSubdivide, AdaptiveLeavesShortAndUninstancedMeshesUntouched) {
  Scene s = two_instance_scene(3);
  Mesh tiny = make_icosphere(1);
  for (Vec3f& p : tiny.positions) p = {p.x * 0.01f, p.y * 0.01f, p.z * 0.01f};
  s.meshes.push_back(tiny);               // 1: instanced, already fine
  s.meshes.push_back(make_icosphere(0));  // 2: no instance
  Instance i;
  i.mesh = 1;
  s.instances.push_back(i);
  const Scene orig = s;
  SubdivideReport r = subdivide_to_length(s, 0.5);
  ASSERT_EQ(r.meshes.size(), 3u);
  EXPECT_GT(r.meshes[0].levels, 0);
  for (uint32_t m : {1u, 2u}) {
    EXPECT_EQ(r.meshes[m].levels, 0) << m;
    EXPECT_EQ(s.meshes[m].positions, orig.meshes[m].positions) << m;
    EXPECT_EQ(s.meshes[m].indices, orig.meshes[m].indices) << m;
    ASSERT_EQ(s.meshes[m].source.size(), orig.meshes[m].source.size());
    for (size_t t = 0; t < s.meshes[m].source.size(); ++t)
      EXPECT_EQ(s.meshes[m].source[t].triangle, orig.meshes[m].source[t].triangle);
  }
  EXPECT_TRUE(r.meshes[1].instanced);
  EXPECT_FALSE(r.meshes[2].instanced);
  EXPECT_EQ(r.meshes_subdivided, 1u);
  EXPECT_EQ(r.triangles_before, 20u + 80u + 20u);
  EXPECT_EQ(r.triangles_after, s.meshes[0].triangle_count() + 80u + 20u);
}

TEST(MeshSubdivide, AdaptiveReportsTheLevelCap) {
  Scene s = two_instance_scene(3);
  SubdivideReport r = subdivide_to_length(s, 1e-3, 2);
  EXPECT_EQ(r.meshes[0].levels, 2);
  EXPECT_TRUE(r.meshes[0].hit_cap);
  EXPECT_EQ(r.meshes_at_cap, 1u);
  EXPECT_EQ(s.meshes[0].triangle_count(), 16u * 20u);
  EXPECT_THROW(subdivide_to_length(s, 0.0), Error);
}

TEST(MeshSubdivide, AdaptiveIsDeterministic) {
  auto build = [] {
    Scene s;
    for (int k = 0; k < 8; ++k) {
      s.meshes.push_back(k % 2 ? make_icosphere(k / 4) : make_grid(k + 1, 2));
      Instance i;
      i.mesh = uint32_t(k);
      for (int a = 0; a < 3; ++a) i.transform(a, a) = float(1 + k % 3);
      s.instances.push_back(i);
    }
    return s;
  };
  Scene a = build(), b = build();
  subdivide_to_length(a, 0.3);
  subdivide_to_length(b, 0.3);
  for (size_t m = 0; m < a.meshes.size(); ++m) {
    EXPECT_EQ(a.meshes[m].positions, b.meshes[m].positions);
    EXPECT_EQ(a.meshes[m].indices, b.meshes[m].indices);
  }
}

// ---- vertex attributes (normals, uvs) -------------------------------------------------------------

// Normals = the (unit) positions of a sphere mesh.
Mesh sphere_with_normals(int s) {
  Mesh m = make_icosphere(s);
  m.normals = m.positions;
  return m;
}

// Every normal is unit length and within max_degrees of the direction of its vertex's position.
void expect_radial_normals(const Mesh& m, double max_degrees) {
  ASSERT_EQ(m.normals.size(), m.positions.size());
  const double min_cos = std::cos(max_degrees * 3.14159265358979 / 180);
  for (size_t v = 0; v < m.positions.size(); ++v) {
    const Vec3d n = to_d(m.normals[v]), p = to_d(m.positions[v]);
    ASSERT_NEAR(length(n), 1.0, 1e-5) << "vertex " << v;
    ASSERT_GT(dot(n, p) / length(p), min_cos) << "vertex " << v;
  }
}

// A 6 x 5 grid in z = 0 with its inner vertices moved off the lattice (irregular, so Loop moves
// vertices away from edge midpoints), uv = (x, y).
Mesh jittered_grid_with_uvs() {
  Mesh m = make_grid(6, 5);
  for (size_t v = 0; v < m.positions.size(); ++v) {
    Vec3f& p = m.positions[v];
    if (p.x > 0 && p.x < 6 && p.y > 0 && p.y < 5) {
      p.x += 0.3f * float(std::sin(1.7 * double(v)));
      p.y += 0.3f * float(std::cos(2.3 * double(v)));
    }
  }
  for (const Vec3f& p : m.positions) m.uvs.push_back({p.x, p.y});
  return m;
}

void expect_uv_is_xy(const Mesh& m) {
  ASSERT_EQ(m.uvs.size(), m.positions.size());
  for (size_t v = 0; v < m.positions.size(); ++v) {
    ASSERT_NEAR(m.uvs[v].x, m.positions[v].x, 1e-6) << "vertex " << v;
    ASSERT_NEAR(m.uvs[v].y, m.positions[v].y, 1e-6) << "vertex " << v;
  }
}

TEST(MeshSubdivide, LoopInterpolatesNormalsAndRenormalizes) {
  for (int n = 1; n <= 3; ++n) {
    Mesh m = sphere_with_normals(1);
    UniformSubdivideResult r = subdivide_uniform(m, n);
    ASSERT_FALSE(r.used_fallback);
    EXPECT_TRUE(m.uvs.empty());
    // The normals follow the same stencils as the positions, so they stay radial.
    expect_radial_normals(m, 0.1);
  }
  // A zero normal ("none given") everywhere stays zero.
  Mesh zero = make_icosphere(0);
  zero.normals.assign(zero.positions.size(), Vec3f{0, 0, 0});
  subdivide_uniform(zero, 2);
  ASSERT_EQ(zero.normals.size(), zero.positions.size());
  for (const Vec3f& nv : zero.normals) EXPECT_EQ(nv, (Vec3f{0, 0, 0}));
}

TEST(MeshSubdivide, LoopKeepsAffineUvsAffine) {
  const Mesh base = jittered_grid_with_uvs();
  for (int n = 1; n <= 3; ++n) {
    Mesh m = base;
    subdivide_uniform(m, n);
    EXPECT_TRUE(m.normals.empty());
    expect_uv_is_xy(m);
    // Meaningful only if Loop moved vertices off the midpoints: compare with the midpoint split.
    Mesh mid = base;
    subdivide_midpoint(mid, n);
    EXPECT_NE(m.uvs, mid.uvs);
  }
}

TEST(MeshSubdivide, MidpointInterpolatesAttributes) {
  Mesh g = jittered_grid_with_uvs();
  g.normals.assign(g.positions.size(), Vec3f{0, 0, 1});
  g.normals[7] = {0, 0, 0};
  subdivide_midpoint(g, 2);
  expect_uv_is_xy(g);
  ASSERT_EQ(g.normals.size(), g.positions.size());
  for (const Vec3f& nv : g.normals) EXPECT_TRUE(nv == (Vec3f{0, 0, 1}) || nv == (Vec3f{0, 0, 0}));
  EXPECT_EQ(g.normals[7], (Vec3f{0, 0, 0}));  // base vertices keep theirs

  for (int n = 1; n <= 3; ++n) {
    Mesh m = sphere_with_normals(1);
    subdivide_midpoint(m, n);
    EXPECT_TRUE(m.uvs.empty());
    expect_radial_normals(m, 3);
  }
}

TEST(MeshSubdivide, MeshesWithoutAttributesStayWithout) {
  Mesh loop = make_icosphere(1), mid = make_cube();
  subdivide_uniform(loop, 2);
  subdivide_midpoint(mid, 2);
  for (const Mesh* m : {&loop, &mid}) {
    EXPECT_TRUE(m->normals.empty());
    EXPECT_TRUE(m->uvs.empty());
  }
  Mesh bad = make_cube();
  bad.uvs.resize(3);
  EXPECT_THROW(subdivide_uniform(bad, 1), Error);
  EXPECT_THROW(subdivide_midpoint(bad, 1), Error);
}

TEST(MeshSubdivide, AdaptiveCarriesAttributes) {
  Scene s = two_instance_scene(3);
  s.meshes[0].normals = s.meshes[0].positions;
  for (const Vec3f& p : s.meshes[0].positions) s.meshes[0].uvs.push_back({p.x, p.y});
  SubdivideReport r = subdivide_to_length(s, 0.5);
  ASSERT_GT(r.meshes[0].levels, 0);
  expect_radial_normals(s.meshes[0], 0.1);
  expect_uv_is_xy(s.meshes[0]);
}

#if __has_include("scene/import.h") && !defined(RTP_MESH_TESTS_NO_IMPORT)
TEST(MeshSubdivide, CleanAndSubdivideSuzanne) {
  const std::filesystem::path path = RTP_SOURCE_DIR "/samples/khronos/Suzanne/glTF/Suzanne.gltf";  // committed
  ASSERT_TRUE(std::filesystem::exists(path)) << "committed sample missing: " << path;
  Scene s = import_gltf(path.string());
  ASSERT_FALSE(s.meshes.empty());
  Mesh m = s.meshes[0];
  const uint64_t before = m.triangle_count();
  CleanReport cr = clean_mesh(m, {.weld_eps = 0});
  EXPECT_EQ(m.triangle_count() + cr.degenerate_removed + cr.nonfinite_removed, before);
  const Aabb box = bounds_of(m);
  const uint64_t cleaned = m.triangle_count();
  subdivide_uniform(m, 1);
  EXPECT_EQ(m.triangle_count(), 4 * cleaned);
  expect_finite_within(m, box);
}
#endif

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
