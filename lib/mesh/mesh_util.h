#pragma once
// Internal helpers shared by lib/mesh/*.cpp (not part of the public API).
#include <cstdint>
#include <string>
#include <vector>

#include "core/error.h"
#include "scene/scene.h"

namespace rtp::mesh_detail {

// Throws kInputInvalid unless indices are triangles within range, the source map is empty or one
// entry per triangle, and each attribute array (normals, uvs) is empty or one entry per position.
inline void validate_mesh(const Mesh& mesh, const char* what) {
  if (mesh.indices.size() % 3 != 0)
    fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' has " + std::to_string(mesh.indices.size()) +
                 " indices, not a multiple of 3");
  const uint64_t n = mesh.positions.size();
  for (size_t i = 0; i < mesh.indices.size(); ++i)
    if (mesh.indices[i] >= n)
      fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' index " + std::to_string(i) + " = " +
                   std::to_string(mesh.indices[i]) + " >= vertex count " + std::to_string(n));
  if (!mesh.source.empty() && mesh.source.size() != mesh.indices.size() / 3)
    fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' has " + std::to_string(mesh.source.size()) +
                 " source entries for " + std::to_string(mesh.indices.size() / 3) + " triangles");
  auto check_attribute = [&](size_t size, const char* name) {
    if (size != 0 && size != n)
      fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' has " + std::to_string(size) + " " + name + " for " +
                   std::to_string(n) + " positions");
  };
  check_attribute(mesh.normals.size(), "normals");
  check_attribute(mesh.uvs.size(), "uvs");
}

// Keeps only the triangles listed in `tris` (ascending original triangle numbers) of `src`, with
// their source entries, and only the vertices they reference (ascending original vertex order) with
// their attributes (empty attribute arrays stay empty). `out` may be `src`. `remap` (optional,
// size = src vertex count) maps each index before use (e.g. welding).
inline void extract_triangles(const Mesh& src, const std::vector<uint32_t>& tris, Mesh& out,
                              const std::vector<uint32_t>* remap = nullptr) {
  std::vector<uint32_t> new_index(src.positions.size(), kNoIndex);
  for (uint32_t t : tris)
    for (int k = 0; k < 3; ++k) {
      uint32_t v = src.indices[3 * size_t(t) + k];
      if (remap) v = (*remap)[v];
      new_index[v] = 0;  // mark used
    }
  std::vector<Vec3f> positions, normals;
  std::vector<Vec2f> uvs;
  const bool has_normals = !src.normals.empty(), has_uvs = !src.uvs.empty();
  uint32_t next = 0;
  for (size_t v = 0; v < new_index.size(); ++v)
    if (new_index[v] != kNoIndex) {
      new_index[v] = next++;
      positions.push_back(src.positions[v]);
      if (has_normals) normals.push_back(src.normals[v]);
      if (has_uvs) uvs.push_back(src.uvs[v]);
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
  out.normals = std::move(normals);
  out.uvs = std::move(uvs);
  out.indices = std::move(indices);
  out.source = std::move(source);
}

}  // namespace rtp::mesh_detail
