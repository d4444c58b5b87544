// clean_mesh: exact counts on small hand-built meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/shapes.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

void expect_same_mesh(const Mesh& a, const Mesh& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.indices, b.indices);
  ASSERT_EQ(a.source.size(), b.source.size());
  for (size_t i = 0; i < a.source.size(); ++i) {
    EXPECT_EQ(a.source[i].primitive, b.source[i].primitive);
    EXPECT_EQ(a.source[i].triangle, b.source[i].triangle);
  }
}

// Appends a triangle with a distinct source entry (primitive 0, triangle = its position).
void add_tri(Mesh& m, uint32_t a, uint32_t b, uint32_t c) {
  m.indices.insert(m.indices.end(), {a, b, c});
  m.source.push_back({0, uint32_t(m.source.size())});
}

std::vector<uint32_t> source_triangles(const Mesh& m) {
  std::vector<uint32_t> out;
  for (const TriangleSource& s : m.source) out.push_back(s.triangle);
  return out;
}

TEST(MeshClean, ClosedCubeIsUntouched) {
  Mesh m = make_cube();
  const Mesh orig = m;
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.degenerate_removed, 0u);
  EXPECT_EQ(r.nonfinite_removed, 0u);
  EXPECT_EQ(r.welded_vertices, 0u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.nonmanifold_faces, 0u);
  EXPECT_EQ(r.nonmanifold_vertices, 0u);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_EQ(r.unused_vertices_removed, 0u);
  expect_same_mesh(m, orig);
}

TEST(MeshClean, TetrahedronAndIcosphereAreClosedManifolds) {
  for (Mesh m : {make_tetrahedron(), make_icosphere(2)}) {
    const Mesh orig = m;
    CleanReport r = clean_mesh(m, {.weld_eps = 0});
    EXPECT_EQ(r.boundary_edges, 0u) << m.name;
    EXPECT_EQ(r.nonmanifold_edges, 0u) << m.name;
    EXPECT_EQ(r.nonmanifold_faces, 0u) << m.name;
    EXPECT_EQ(r.welded_vertices, 0u) << m.name;
    expect_same_mesh(m, orig);
  }
}

TEST(MeshClean, OpenGridCountsBoundaryEdges) {
  Mesh m = make_grid(5, 3);
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.boundary_edges, 2u * (5 + 3));
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.nonmanifold_faces, 0u);
  EXPECT_EQ(m.triangle_count(), 30u);
}

TEST(MeshClean, DropsRepeatedIndexAndZeroAreaTriangles) {
  Mesh m = make_cube();
  m.positions.push_back({0, 0, 5});  // 8
  m.positions.push_back({1, 1, 6});  // 9
  m.positions.push_back({2, 2, 7});  // 10: collinear with 8, 9
  add_tri(m, 0, 0, 1);               // repeated index
  add_tri(m, 8, 9, 10);              // zero area
  add_tri(m, 3, 3, 3);               // all the same
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.degenerate_removed, 3u);
  EXPECT_EQ(r.nonfinite_removed, 0u);
  EXPECT_EQ(r.unused_vertices_removed, 3u);  // 8, 9, 10 only used by the dropped triangle
  EXPECT_EQ(m.triangle_count(), 12u);
  EXPECT_EQ(m.positions.size(), 8u);
  EXPECT_EQ(source_triangles(m), (std::vector<uint32_t>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11}));
  EXPECT_EQ(r.boundary_edges, 0u);
}

TEST(MeshClean, KeepsNeedleTriangle) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1000, 0, 0}, {500, 1e-3f, 0}};
  add_tri(m, 0, 1, 2);
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.degenerate_removed, 0u);
  EXPECT_EQ(m.triangle_count(), 1u);
  EXPECT_EQ(r.boundary_edges, 3u);
}

TEST(MeshClean, DropsNonFiniteTriangles) {
  Mesh m = make_tetrahedron();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  m.positions.push_back({nan, 0, 0});  // 4
  m.positions.push_back({0, inf, 0});  // 5
  add_tri(m, 0, 1, 4);
  add_tri(m, 5, 2, 3);
  add_tri(m, 4, 4, 5);  // non-finite and degenerate: counted once, as non-finite
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.nonfinite_removed, 3u);
  EXPECT_EQ(r.degenerate_removed, 0u);
  EXPECT_EQ(r.unused_vertices_removed, 2u);
  EXPECT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(source_triangles(m), (std::vector<uint32_t>{0, 1, 2, 3}));
  for (const Vec3f& p : m.positions) EXPECT_TRUE(is_finite(p));
}

TEST(MeshClean, DuplicatedFaceIsCountedAndKept) {
  // A closed tetrahedron plus a copy of its last face: each of that face's 3 edges is now shared by
  // 3 triangles, and OpenMesh refuses the copy (its half-edges are taken).
  Mesh m = make_tetrahedron();
  add_tri(m, 1, 3, 2);
  const Mesh orig = m;
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.nonmanifold_edges, 3u);
  EXPECT_EQ(r.nonmanifold_faces, 1u);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_EQ(r.degenerate_removed, 0u);
  expect_same_mesh(m, orig);  // reported, not dropped
}

TEST(MeshClean, FinSharingOneEdgeThrice) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0.5f, 1, 0}, {0.5f, -1, 0}, {0.5f, 0, 1}};
  add_tri(m, 0, 1, 2);
  add_tri(m, 1, 0, 3);
  add_tri(m, 0, 1, 4);  // same direction as the first: OpenMesh refuses it (complex edge)
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.nonmanifold_edges, 1u);
  EXPECT_EQ(r.nonmanifold_faces, 1u);
  EXPECT_EQ(r.boundary_edges, 6u);
  EXPECT_EQ(m.triangle_count(), 3u);
  EXPECT_EQ(source_triangles(m), (std::vector<uint32_t>{0, 1, 2}));
}

// CleanOptions::topology = false skips OpenMesh's analysis only: the clean-up and the edge counts stay.
TEST(MeshClean, TopologyOffSkipsOnlyTheHalfEdgeAnalysis) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}, {2, 2, 2}};  // the last one unused
  add_tri(m, 0, 1, 2);
  add_tri(m, 0, 3, 4);
  add_tri(m, 1, 1, 2);  // degenerate
  Mesh with = m;
  CleanOptions off;
  off.topology = false;
  const CleanReport r = clean_mesh(m, off), full = clean_mesh(with);
  EXPECT_FALSE(r.topology_analysed);
  EXPECT_TRUE(full.topology_analysed);
  EXPECT_EQ(r.nonmanifold_vertices, 0u);
  EXPECT_EQ(full.nonmanifold_vertices, 1u);
  for (const CleanReport* c : {&r, &full}) {
    EXPECT_EQ(c->degenerate_removed, 1u);
    EXPECT_EQ(c->unused_vertices_removed, 1u);
    EXPECT_EQ(c->boundary_edges, 6u);
  }
  EXPECT_EQ(m.indices, with.indices);
  EXPECT_EQ(m.positions.size(), with.positions.size());
}

TEST(MeshClean, BowTieVertexIsReported) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
  add_tri(m, 0, 1, 2);
  add_tri(m, 0, 3, 4);
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.nonmanifold_vertices, 1u);
  EXPECT_EQ(r.nonmanifold_faces, 0u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.boundary_edges, 6u);
}

TEST(MeshClean, RemovesUnusedVerticesPreservingOrder) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  for (int i = 0; i < 7; ++i) m.positions.push_back({float(i), float(i * i), float(i % 2)});
  add_tri(m, 5, 1, 3);
  add_tri(m, 3, 1, 6);
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.unused_vertices_removed, 3u);  // 0, 2, 4
  ASSERT_EQ(m.positions.size(), 4u);         // 1, 3, 5, 6 in that order
  EXPECT_EQ(m.positions[0], (Vec3f{1, 1, 1}));
  EXPECT_EQ(m.positions[1], (Vec3f{3, 9, 1}));
  EXPECT_EQ(m.positions[2], (Vec3f{5, 25, 1}));
  EXPECT_EQ(m.positions[3], (Vec3f{6, 36, 0}));
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{2, 0, 1, 1, 0, 3}));
}

// A cube with every triangle on its own three vertices (36), slightly jittered.
Mesh split_cube(float jitter) {
  Mesh cube = make_cube();
  Mesh m;
  m.primitives = cube.primitives;
  m.source = cube.source;
  for (size_t i = 0; i < cube.indices.size(); ++i) {
    Vec3f p = cube.positions[cube.indices[i]];
    const float s = (i % 3 == 0) ? jitter : (i % 3 == 1 ? -jitter : 0.0f);
    m.positions.push_back({p.x + s, p.y - s, p.z + s});
    m.indices.push_back(uint32_t(i));
  }
  return m;
}

TEST(MeshClean, WeldMergesNearbyVertices) {
  Mesh m = split_cube(1e-4f);
  CleanReport r = clean_mesh(m, {.weld_eps = 1e-3});
  EXPECT_EQ(r.welded_vertices, 28u);
  EXPECT_EQ(r.unused_vertices_removed, 0u);
  EXPECT_EQ(m.positions.size(), 8u);
  EXPECT_EQ(m.triangle_count(), 12u);
  EXPECT_EQ(r.boundary_edges, 0u);
  EXPECT_EQ(r.nonmanifold_edges, 0u);
  EXPECT_EQ(r.nonmanifold_faces, 0u);
  // Deterministic: each corner keeps the lowest-index copy, so vertex 0 is the first copy's position.
  Mesh again = split_cube(1e-4f);
  EXPECT_EQ(m.positions[0], again.positions[0]);
  clean_mesh(again, {.weld_eps = 1e-3});
  EXPECT_EQ(m.positions, again.positions);
  EXPECT_EQ(m.indices, again.indices);
}

TEST(MeshClean, WeldOffOrTooSmallKeepsSeams) {
  Mesh off = split_cube(1e-4f);
  CleanReport r = clean_mesh(off);
  EXPECT_EQ(r.welded_vertices, 0u);
  EXPECT_EQ(off.positions.size(), 36u);
  EXPECT_EQ(r.boundary_edges, 36u);

  Mesh exact = split_cube(1e-4f);
  r = clean_mesh(exact, {.weld_eps = 0});
  EXPECT_EQ(exact.positions.size(), 36u - r.welded_vertices);
  EXPECT_LT(r.welded_vertices, 28u);

  Mesh clean_copies = split_cube(0);
  r = clean_mesh(clean_copies, {.weld_eps = 0});
  EXPECT_EQ(r.welded_vertices, 28u);
  EXPECT_EQ(r.boundary_edges, 0u);
}

TEST(MeshClean, WeldDistanceIsLInfinity) {
  // (0.9, 0.9, 0.9) * eps away: L2 distance ~1.56 eps, L-infinity 0.9 eps -> merged.
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {0.9f, 0.9f, 0.9f}, {10, 0, 0}, {0, 10, 0}};
  add_tri(m, 0, 2, 3);
  add_tri(m, 1, 3, 2);
  CleanReport r = clean_mesh(m, {.weld_eps = 1.0});
  EXPECT_EQ(r.welded_vertices, 1u);
  EXPECT_EQ(m.positions.size(), 3u);
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 1}));
  EXPECT_EQ(r.boundary_edges, 0u);  // two faces glued back to back

  Mesh far = m;
  far.positions = {{0, 0, 0}, {1.5f, 0, 0}, {10, 0, 0}, {0, 10, 0}};
  far.indices = {0, 2, 3, 1, 3, 2};
  r = clean_mesh(far, {.weld_eps = 1.0});
  EXPECT_EQ(r.welded_vertices, 0u);
}

TEST(MeshClean, WeldingCanMakeTrianglesDegenerate) {
  // A sliver whose short edge is shorter than eps collapses and is removed after welding.
  Mesh m = make_grid(1, 1);
  m.positions.push_back({0.5f, 2, 0});     // 4
  m.positions.push_back({0.5001f, 2, 0});  // 5, 1e-4 from 4
  add_tri(m, 2, 4, 5);
  CleanReport r = clean_mesh(m, {.weld_eps = 1e-3});
  EXPECT_EQ(r.welded_vertices, 1u);
  EXPECT_EQ(r.degenerate_removed, 1u);
  EXPECT_EQ(r.unused_vertices_removed, 1u);  // 4 survived welding but only the sliver used it
  EXPECT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(m.positions.size(), 4u);
}

TEST(MeshClean, RejectsInvalidInput) {
  Mesh m = make_tetrahedron();
  m.indices[5] = 17;
  EXPECT_THROW(clean_mesh(m), Error);
  Mesh s = make_tetrahedron();
  s.source.pop_back();
  EXPECT_THROW(clean_mesh(s), Error);
}

// ---- vertex attributes (normals, uvs) -------------------------------------------------------------

// One triangle corner by value: position, normal, uv (absent arrays read as zero).
struct Corner {
  Vec3f p, n;
  Vec2f uv;
  bool operator==(const Corner&) const = default;
};

Corner corner(const Mesh& m, size_t t, int k) {
  const uint32_t v = m.indices[3 * t + k];
  return {m.positions[v], m.normals.empty() ? Vec3f{} : m.normals[v], m.uvs.empty() ? Vec2f{} : m.uvs[v]};
}

// Every triangle of `after` has, corner by corner, the position, normal and uv of the triangle of
// `before` its source entry names (source.triangle = the triangle's number in `before`).
void expect_corners_kept(const Mesh& before, const Mesh& after) {
  ASSERT_EQ(after.normals.size(), before.normals.empty() ? 0 : after.positions.size());
  ASSERT_EQ(after.uvs.size(), before.uvs.empty() ? 0 : after.positions.size());
  for (size_t t = 0; t < after.triangle_count(); ++t)
    for (int k = 0; k < 3; ++k)
      ASSERT_EQ(corner(after, t, k), corner(before, after.source[t].triangle, k)) << "triangle " << t << " corner " << k;
}

// A distinct normal and uv per vertex, derived from its number.
void add_vertex_attributes(Mesh& m) {
  m.normals.clear();
  m.uvs.clear();
  for (size_t v = 0; v < m.positions.size(); ++v) {
    const double a = 0.37 * double(v);
    m.normals.push_back({float(std::cos(a)), float(std::sin(a)), 0});
    m.uvs.push_back({float(v) * 0.125f, 1 - float(v) * 0.0625f});
  }
}

TEST(MeshClean, CompactionCarriesAttributes) {
  Mesh m;
  m.primitives = {SourcePrimitive{}};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < 9; ++i) m.positions.push_back({float(i), float(i * i), float(i % 2)});
  m.positions[7] = {nan, 0, 0};
  add_tri(m, 5, 1, 3);
  add_tri(m, 0, 0, 2);  // degenerate: 0 and 2 become unused
  add_tri(m, 3, 1, 8);
  add_tri(m, 7, 4, 6);  // non-finite: 4, 6, 7 become unused
  add_tri(m, 8, 1, 5);
  add_vertex_attributes(m);
  const Mesh before = m;
  CleanReport r = clean_mesh(m);
  EXPECT_EQ(r.unused_vertices_removed, 5u);
  ASSERT_EQ(m.positions.size(), 4u);  // 1, 3, 5, 8
  EXPECT_EQ(m.normals.size(), 4u);
  EXPECT_EQ(m.uvs.size(), 4u);
  EXPECT_EQ(source_triangles(m), (std::vector<uint32_t>{0, 2, 4}));
  expect_corners_kept(before, m);
  EXPECT_EQ(m.normals[2], before.normals[5]);
  EXPECT_EQ(m.uvs[3], before.uvs[8]);

  // Only one of the arrays present: the other stays empty.
  Mesh uv_before = before;
  uv_before.normals.clear();
  Mesh only_uv = uv_before;
  clean_mesh(only_uv, {.weld_eps = 0});
  EXPECT_TRUE(only_uv.normals.empty());
  EXPECT_EQ(only_uv.uvs.size(), only_uv.positions.size());
  expect_corners_kept(uv_before, only_uv);
  Mesh none = make_cube();
  clean_mesh(none, {.weld_eps = 0});
  EXPECT_TRUE(none.normals.empty());
  EXPECT_TRUE(none.uvs.empty());
}

// The cube as 12 triangles on 36 vertices of their own (split_cube), each corner with its face's
// normal and a uv from its position in the face: 24 distinct (position, normal, uv) corners.
Mesh hard_edged_cube(float jitter) {
  Mesh m = split_cube(jitter);
  const Mesh cube = make_cube();
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    const Vec3d a = to_d(cube.positions[cube.indices[3 * t]]);
    const Vec3d n = cross(to_d(cube.positions[cube.indices[3 * t + 1]]) - a, to_d(cube.positions[cube.indices[3 * t + 2]]) - a);
    const Vec3d u = n * (1.0 / length(n));
    for (int k = 0; k < 3; ++k) {
      const Vec3f p = cube.positions[cube.indices[3 * t + k]];
      m.normals.push_back({float(u.x), float(u.y), float(u.z)});
      // The two coordinates across the face (the one along the normal is constant on it).
      const float s = std::abs(u.x) > 0.5 ? p.y : p.x, r = std::abs(u.z) > 0.5 ? p.y : p.z;
      m.uvs.push_back({s * 0.5f + 0.5f, r * 0.5f + 0.5f});
    }
  }
  return m;
}

TEST(MeshClean, WeldKeepsNormalAndUvSeams) {
  // Exact duplicates with equal attributes merge; coincident vertices whose normals differ do not.
  Mesh m = hard_edged_cube(0);
  const Mesh before = m;
  CleanReport r = clean_mesh(m, {.weld_eps = 0});
  EXPECT_EQ(r.welded_vertices, 12u);
  EXPECT_EQ(m.positions.size(), 24u);
  EXPECT_EQ(m.normals.size(), 24u);
  EXPECT_EQ(m.uvs.size(), 24u);
  EXPECT_EQ(m.triangle_count(), 12u);
  EXPECT_EQ(r.degenerate_removed, 0u);
  expect_corners_kept(before, m);
  // Welding again changes nothing: 3 normals at each of the 8 corner positions stay apart.
  r = clean_mesh(m, {.weld_eps = 0});
  EXPECT_EQ(r.welded_vertices, 0u);
  EXPECT_EQ(m.positions.size(), 24u);

  // Same with a tolerance: jittered copies within eps merge only with their own face's copies.
  Mesh jittered = hard_edged_cube(1e-4f);
  const Mesh jbefore = jittered;
  r = clean_mesh(jittered, {.weld_eps = 1e-3});
  EXPECT_EQ(r.welded_vertices, 12u);
  EXPECT_EQ(jittered.positions.size(), 24u);
  for (size_t t = 0; t < jittered.triangle_count(); ++t)
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = jittered.indices[3 * t + k];
      const uint32_t w = jbefore.indices[3 * size_t(jittered.source[t].triangle) + k];
      EXPECT_EQ(jittered.normals[v], jbefore.normals[w]);
      EXPECT_EQ(jittered.uvs[v], jbefore.uvs[w]);
    }

  // Only the normals present: the same 24.
  Mesh normals_only = hard_edged_cube(0);
  normals_only.uvs.clear();
  clean_mesh(normals_only, {.weld_eps = 0});
  EXPECT_EQ(normals_only.positions.size(), 24u);
  // Equal normals, differing uvs (a uv seam): still kept apart.
  Mesh uv_seam = hard_edged_cube(0);
  for (Vec3f& n : uv_seam.normals) n = {0, 0, 1};
  for (size_t v = 0; v < uv_seam.uvs.size(); ++v) {
    const size_t face = v / 6;  // 6 corners per face
    uv_seam.uvs[v].x += 10.0f * float(face);
  }
  clean_mesh(uv_seam, {.weld_eps = 0});
  EXPECT_EQ(uv_seam.positions.size(), 24u);
  // Without attributes the cube welds to 8 vertices.
  Mesh plain = hard_edged_cube(0);
  plain.normals.clear();
  plain.uvs.clear();
  r = clean_mesh(plain, {.weld_eps = 0});
  EXPECT_EQ(r.welded_vertices, 28u);
  EXPECT_EQ(plain.positions.size(), 8u);
}

TEST(MeshClean, WeldComparesAttributeBits) {
  // -0 and +0 in a normal are different bits: not merged (the comparison is bitwise).
  Mesh m;
  m.name = "bits";
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}};
  m.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {-0.0f, 0, 1}};
  add_tri(m, 0, 1, 2);
  add_tri(m, 3, 2, 1);
  CleanReport r = clean_mesh(m, {.weld_eps = 0.5});
  EXPECT_EQ(r.welded_vertices, 0u);
  m.normals[3] = {0, 0, 1};
  r = clean_mesh(m, {.weld_eps = 0.5});
  EXPECT_EQ(r.welded_vertices, 1u);
  EXPECT_EQ(m.positions.size(), 3u);
}

TEST(MeshClean, RejectsAttributeSizeMismatch) {
  for (int which = 0; which < 4; ++which) {
    Mesh m = make_tetrahedron();
    m.name = "lopsided";
    if (which == 0) m.normals.resize(3);
    if (which == 1) m.normals.resize(5);
    if (which == 2) m.uvs.resize(1);
    if (which == 3) m.uvs.resize(8);
    try {
      clean_mesh(m);
      ADD_FAILURE() << "no throw for case " << which;
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kInputInvalid);
      EXPECT_NE(std::string(e.what()).find("lopsided"), std::string::npos) << e.what();
    }
  }
  Mesh ok = make_tetrahedron();
  ok.normals.resize(4);
  ok.uvs.resize(4);
  EXPECT_NO_THROW(clean_mesh(ok));
}

// The edge counts against their definition (every undirected edge key counted in a map) on soups of
// random triangles over few vertices, where edges repeat 1 to many times.
TEST(MeshClean, EdgeCountsMatchTheirDefinitionOnRandomSoups) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const uint32_t nv = 4 + trial * 3;
    Mesh m;
    for (uint32_t v = 0; v < nv; ++v) m.positions.push_back({float(v), float(v * v % 7), float(v % 3) + 0.5f * float(v)});
    std::uniform_int_distribution<uint32_t> pick(0, nv - 1);
    for (int t = 0; t < 10 + 15 * trial; ++t) {
      uint32_t a = pick(rng), b = pick(rng), c = pick(rng);
      if (a == b || b == c || a == c) continue;
      add_tri(m, a, b, c);
    }
    CleanReport r = clean_mesh(m, {.weld_eps = -1, .topology = false});
    std::map<std::pair<uint32_t, uint32_t>, int> uses;
    for (size_t t = 0; t < m.indices.size(); t += 3)
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = m.indices[t + k], b = m.indices[t + (k + 1) % 3];
        ++uses[{std::min(a, b), std::max(a, b)}];
      }
    uint64_t boundary = 0, nonmanifold = 0;
    for (const auto& [edge, n] : uses) boundary += n == 1, nonmanifold += n > 2;
    EXPECT_EQ(r.boundary_edges, boundary) << "trial " << trial;
    EXPECT_EQ(r.nonmanifold_edges, nonmanifold) << "trial " << trial;
    EXPECT_GT(nonmanifold + boundary, 0u) << "trial " << trial;
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
