#pragma once
// Internal helpers shared by lib/mesh/*.cpp (not part of the public API).
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "scene/scene.h"

namespace rtp::mesh_detail {

// Throws kInputInvalid unless indices are triangles within range and the source map is empty or
// one entry per triangle.
inline void validate_mesh(const Mesh& mesh, const char* what) {
  if (mesh.indices.size() % 3 != 0)
    fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' has " +
                 std::to_string(mesh.indices.size()) + " indices, not a multiple of 3");
  const uint64_t n = mesh.positions.size();
  for (size_t i = 0; i < mesh.indices.size(); ++i)
    if (mesh.indices[i] >= n)
      fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' index " + std::to_string(i) + " = " +
                   std::to_string(mesh.indices[i]) + " >= vertex count " + std::to_string(n));
  if (!mesh.source.empty() && mesh.source.size() != mesh.indices.size() / 3)
    fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' has " + std::to_string(mesh.source.size()) +
                 " source entries for " + std::to_string(mesh.indices.size() / 3) + " triangles");
}

// Keeps only the triangles listed in `tris` (ascending original triangle numbers) of `src`, with
// their source entries, and only the vertices they reference (ascending original vertex order).
// `remap` (optional, size = src vertex count) maps each index before use (e.g. welding).
inline void extract_triangles(const Mesh& src, const std::vector<uint32_t>& tris, Mesh& out,
                              const std::vector<uint32_t>* remap = nullptr) {
  std::vector<uint32_t> new_index(src.positions.size(), kNoIndex);
  for (uint32_t t : tris)
    for (int k = 0; k < 3; ++k) {
      uint32_t v = src.indices[3 * size_t(t) + k];
      if (remap) v = (*remap)[v];
      new_index[v] = 0;  // mark used
    }
  std::vector<Vec3f> positions;
  uint32_t next = 0;
  for (size_t v = 0; v < new_index.size(); ++v)
    if (new_index[v] != kNoIndex) {
      new_index[v] = next++;
      positions.push_back(src.positions[v]);
    }
  std::vector<uint32_t> indices;
  indices.reserve(tris.size() * 3);
  std::vector<TriangleSource> source;
  if (!src.source.empty()) source.reserve(tris.size());
  for (uint32_t t : tris) {
    for (int k = 0; k < 3; ++k) {
      uint32_t v = src.indices[3 * size_t(t) + k];
      if (remap) v = (*remap)[v];
      indices.push_back(new_index[v]);
    }
    if (!src.source.empty()) source.push_back(src.source[t]);
  }
  out.positions = std::move(positions);
  out.indices = std::move(indices);
  out.source = std::move(source);
}

}  // namespace rtp::mesh_detail
