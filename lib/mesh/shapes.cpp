// Procedural test meshes: tetrahedron, cube, icosphere (icosahedron with midpoint subdivision
// projected to the unit sphere), planar grid.
#include "mesh/shapes.h"

#include <cmath>
#include <map>
#include <utility>

namespace rtp {
namespace {

Mesh finish(std::string name, std::vector<Vec3f> positions, std::vector<uint32_t> indices) {
  Mesh m;
  m.name = std::move(name);
  m.positions = std::move(positions);
  m.indices = std::move(indices);
  m.primitives = {SourcePrimitive{}};
  m.source.resize(m.indices.size() / 3);
  for (uint32_t t = 0; t < m.source.size(); ++t) m.source[t] = {0, t};
  return m;
}

}  // namespace

Mesh make_tetrahedron() {
  return finish("tetrahedron", {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}}, {0, 1, 2, 0, 2, 3, 0, 3, 1, 1, 3, 2});
}

Mesh make_cube(double h) {
  std::vector<Vec3f> p;
  p.reserve(8);
  for (int i = 0; i < 8; ++i) p.push_back({float(i & 1 ? h : -h), float(i & 2 ? h : -h), float(i & 4 ? h : -h)});
  // Faces as quads (CCW seen from outside), two triangles each.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  std::vector<uint32_t> idx;
  for (const auto& q : quads)
    for (uint32_t v : {q[0], q[1], q[2], q[0], q[2], q[3]}) idx.push_back(v);
  return finish("cube", std::move(p), std::move(idx));
}

Mesh make_icosphere(int subdivisions) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3d> p = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                          {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<uint32_t> idx = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                               4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                               6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
  for (Vec3d& v : p) v = v * (1.0 / length(v));
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto get = [&](uint32_t a, uint32_t b) {
      auto key = std::minmax(a, b);
      auto [it, inserted] = mid.try_emplace({key.first, key.second}, uint32_t(p.size()));
      if (inserted) {
        Vec3d m = p[a] + p[b];
        p.push_back(m * (1.0 / length(m)));
      }
      return it->second;
    };
    std::vector<uint32_t> next;
    for (size_t i = 0; i < idx.size(); i += 3) {
      uint32_t a = idx[i], b = idx[i + 1], c = idx[i + 2];
      uint32_t ab = get(a, b), bc = get(b, c), ca = get(c, a);
      for (uint32_t v : {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca}) next.push_back(v);
    }
    idx = std::move(next);
  }
  std::vector<Vec3f> pf;
  pf.reserve(p.size());
  for (const Vec3d& v : p) pf.push_back({float(v.x), float(v.y), float(v.z)});
  return finish("icosphere", std::move(pf), std::move(idx));
}

Mesh make_grid(uint32_t nx, uint32_t ny) {
  std::vector<Vec3f> p;
  for (uint32_t y = 0; y <= ny; ++y)
    for (uint32_t x = 0; x <= nx; ++x) p.push_back({float(x), float(y), 0});
  std::vector<uint32_t> idx;
  for (uint32_t y = 0; y < ny; ++y)
    for (uint32_t x = 0; x < nx; ++x) {
      uint32_t a = y * (nx + 1) + x, b = a + 1, c = a + nx + 1, d = c + 1;
      for (uint32_t v : {a, b, d, a, d, c}) idx.push_back(v);
    }
  return finish("grid", std::move(p), std::move(idx));
}

}  // namespace rtp
