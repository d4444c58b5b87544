// split_mesh: every triangle lands in exactly one piece of at most K triangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <tuple>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/shapes.h"

namespace rtp {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

// A triangle by value: its three corner positions and its source entry.
using TriKey = std::tuple<std::array<float, 9>, uint32_t, uint32_t>;

std::vector<TriKey> triangles_of(const Mesh& m) {
  std::vector<TriKey> out;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    std::array<float, 9> v;
    for (int k = 0; k < 3; ++k) {
      const Vec3f& p = m.positions[m.indices[3 * t + k]];
      v[3 * k] = p.x;
      v[3 * k + 1] = p.y;
      v[3 * k + 2] = p.z;
    }
    out.emplace_back(v, m.source[t].primitive, m.source[t].triangle);
  }
  return out;
}

void check_split(const Mesh& mesh, uint32_t k) {
  const std::vector<Mesh> pieces = split_mesh(mesh, k);
  std::vector<TriKey> expected = triangles_of(mesh), got;
  uint64_t total = 0;
  for (size_t i = 0; i < pieces.size(); ++i) {
    const Mesh& p = pieces[i];
    EXPECT_EQ(p.name, mesh.name + "#" + std::to_string(i));
    EXPECT_GE(p.triangle_count(), 1u);
    EXPECT_LE(p.triangle_count(), k);
    EXPECT_EQ(p.source.size(), p.triangle_count());
    EXPECT_EQ(p.primitives.size(), mesh.primitives.size());
    // Self-contained and compact: every vertex is referenced, every index is in range.
    std::vector<char> used(p.positions.size(), 0);
    for (uint32_t v : p.indices) {
      ASSERT_LT(v, p.positions.size());
      used[v] = 1;
    }
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);
    // Triangles keep their original relative order inside a piece.
    for (size_t t = 1; t < p.source.size(); ++t) EXPECT_LT(p.source[t - 1].triangle, p.source[t].triangle);
    std::vector<TriKey> tris = triangles_of(p);
    got.insert(got.end(), tris.begin(), tris.end());
    total += p.triangle_count();
  }
  EXPECT_EQ(total, mesh.triangle_count());
  std::sort(expected.begin(), expected.end());
  std::sort(got.begin(), got.end());
  EXPECT_TRUE(expected == got) << "the pieces' triangles differ from the mesh's";
}

TEST(MeshSplit, EveryTriangleInExactlyOnePiece) {
  const Mesh sphere = make_icosphere(3);  // 1280 triangles
  for (uint32_t k : {1000u, 100u, 17u, 3u}) check_split(sphere, k);
  check_split(make_grid(30, 7), 25);
}

TEST(MeshSplit, PiecesAreSpatiallyCoherent) {
  // A 64 x 1 strip split into pieces of <= 16 triangles: SAH cuts along x, so no piece is wider
  // than the strip's share plus one cell.
  const Mesh strip = make_grid(64, 1);
  const std::vector<Mesh> pieces = split_mesh(strip, 16);
  ASSERT_GE(pieces.size(), 8u);
  double previous_lo = -1;
  for (const Mesh& p : pieces) {
    Aabb b;
    for (const Vec3f& v : p.positions) b.grow(to_d(v));
    EXPECT_LE(b.hi.x - b.lo.x, 9.0);
    EXPECT_GT(b.lo.x, previous_lo);  // left to right
    previous_lo = b.lo.x;
  }
}

TEST(MeshSplit, TenThousandIdenticalTriangles) {
  Mesh m;
  m.name = "same";
  m.primitives = {SourcePrimitive{}};
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  for (uint32_t t = 0; t < 10000; ++t) {
    m.indices.insert(m.indices.end(), {0, 1, 2});
    m.source.push_back({0, t});
  }
  check_split(m, 64);
  const std::vector<Mesh> pieces = split_mesh(m, 100);
  EXPECT_EQ(pieces.size(), 128u);  // median halving: 10000 -> 128 leaves of 78 or 79
  EXPECT_EQ(pieces[0].source[0].triangle, 0u);
  EXPECT_EQ(pieces.back().source.back().triangle, 9999u);
  check_split(m, 1);
}

TEST(MeshSplit, OneTrianglePerPiece) {
  const Mesh cube = make_cube();
  const std::vector<Mesh> pieces = split_mesh(cube, 1);
  ASSERT_EQ(pieces.size(), 12u);
  for (const Mesh& p : pieces) {
    EXPECT_EQ(p.triangle_count(), 1u);
    EXPECT_EQ(p.positions.size(), 3u);
  }
  check_split(cube, 1);
  check_split(make_icosphere(2), 1);
}

TEST(MeshSplit, SmallMeshIsOnePieceAndEmptyMeshNone) {
  const Mesh tet = make_tetrahedron();
  const std::vector<Mesh> pieces = split_mesh(tet, 4);
  ASSERT_EQ(pieces.size(), 1u);
  EXPECT_EQ(pieces[0].name, "tetrahedron#0");
  EXPECT_EQ(pieces[0].positions, tet.positions);
  EXPECT_EQ(pieces[0].indices, tet.indices);
  EXPECT_TRUE(split_mesh(Mesh{}, 4).empty());
  EXPECT_THROW(split_mesh(tet, 0), Error);
}

TEST(MeshSplit, Deterministic) {
  const Mesh sphere = make_icosphere(3);
  const std::vector<Mesh> a = split_mesh(sphere, 50), b = split_mesh(sphere, 50);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].positions, b[i].positions);
    EXPECT_EQ(a[i].indices, b[i].indices);
  }
}

// Every corner of every piece's triangle has the position, normal and uv of the same corner of the
// source triangle (make_* meshes: source.triangle = the triangle's number in `mesh`).
void check_split_attributes(const Mesh& mesh, uint32_t k) {
  const std::vector<Mesh> pieces = split_mesh(mesh, k);
  ASSERT_GT(pieces.size(), 1u);
  for (const Mesh& p : pieces) {
    ASSERT_EQ(p.normals.size(), mesh.normals.empty() ? 0 : p.positions.size());
    ASSERT_EQ(p.uvs.size(), mesh.uvs.empty() ? 0 : p.positions.size());
    for (size_t t = 0; t < p.triangle_count(); ++t)
      for (int c = 0; c < 3; ++c) {
        const uint32_t v = p.indices[3 * t + c];
        const uint32_t w = mesh.indices[3 * size_t(p.source[t].triangle) + c];
        ASSERT_EQ(p.positions[v], mesh.positions[w]) << p.name << " triangle " << t;
        if (!mesh.normals.empty()) {
          ASSERT_EQ(p.normals[v], mesh.normals[w]) << p.name << " triangle " << t;
        }
        if (!mesh.uvs.empty()) {
          ASSERT_EQ(p.uvs[v], mesh.uvs[w]) << p.name << " triangle " << t;
        }
      }
  }
}

TEST(MeshSplit, PiecesCarryAttributes) {
  Mesh sphere = make_icosphere(3);
  sphere.normals = sphere.positions;
  for (size_t v = 0; v < sphere.positions.size(); ++v)
    sphere.uvs.push_back({float(v) * 0.5f, sphere.positions[v].z});  // distinct per vertex
  for (uint32_t k : {100u, 17u, 1u}) check_split_attributes(sphere, k);
  Mesh normals_only = sphere;
  normals_only.uvs.clear();
  check_split_attributes(normals_only, 40);
  Mesh uvs_only = sphere;
  uvs_only.normals.clear();
  check_split_attributes(uvs_only, 40);
  check_split_attributes(make_icosphere(2), 40);  // none: pieces have none either

  Mesh bad = sphere;
  bad.normals.pop_back();
  EXPECT_THROW(split_mesh(bad, 40), Error);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp
