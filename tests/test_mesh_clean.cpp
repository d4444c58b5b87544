// clean_mesh: exact counts on small hand-built meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/shapes.h"

namespace rtp {
namespace {

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
  m.positions.push_back({0, 0, 5});   // 8
  m.positions.push_back({1, 1, 6});   // 9
  m.positions.push_back({2, 2, 7});   // 10: collinear with 8, 9
  add_tri(m, 0, 0, 1);                // repeated index
  add_tri(m, 8, 9, 10);               // zero area
  add_tri(m, 3, 3, 3);                // all the same
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
  m.positions.push_back({0.5f, 2, 0});  // 4
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

}  // namespace
}  // namespace rtp
