#pragma once
// rtpack-make-scene's source meshes: the default sample meshes found on disk, imported, refined by
// midpoint splits and normalized to size 1 (tools/rtpack-make-scene.cpp builds scenes from them).
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.h"

namespace rtp::tools {

struct SourceMesh {
  std::string name;
  std::vector<rtp::Vec3f> positions;
  std::vector<uint32_t> indices;
  rtp::Vec3f lo, hi;  // exact float bounds of the positions
  double norm = 1;    // uniform scale bringing the largest extent to 1
  uint64_t triangles() const { return indices.size() / 3; }
};

// The default sample `rel` (e.g. samples/khronos/Suzanne/glTF/Suzanne.gltf) under the first data root that
// holds it; throws Error(kInputIo) naming every place looked in.
std::string resolve_default(const std::string& rel);
// Every mesh with triangles of every file (external buffers also from allow_paths); throws naming the file.
// Refuses (exit 1, Error kUsage) when `output` is one of the files read: a source glTF's external buffer.
std::vector<SourceMesh> load_sources(const std::vector<std::string>& files, const std::vector<std::string>& allow_paths,
                                     const std::string& output);
// One 1-to-4 midpoint split of every triangle (shared edges share the midpoint vertex).
void refine_once(SourceMesh& m);
// lo, hi and norm from the positions.
void compute_bounds(SourceMesh& m);

}  // namespace rtp::tools
