#pragma once
// glTF 2.0 import (.gltf with external/data-URI buffers, .glb), with Draco, meshopt, quantization,
// sparse accessors and EXT_mesh_gpu_instancing. Throws rtp::Error naming the JSON pointer on bad input.
#include <functional>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace rtp {

struct ImportOptions {
  int scene = -1;  // -1: the file's default scene (or scene 0 when none is set)
  // Optional vertex attributes (Mesh::normals / Mesh::uvs). Off by default: store no more than asked.
  bool normals = false;  // glTF NORMAL (float or normalized byte/short, KHR_mesh_quantization)
  bool uvs = false;      // glTF TEXCOORD_0 (float or normalized unsigned byte/short)
  // Directories besides the glTF's own from which external buffers may be read (--allow-path).
  std::vector<std::string> allowed_dirs;
  std::function<void(const std::string&)> on_warning;  // also collected in Scene::warnings
  // Progress of the longest step on instanced scenes, the exact world bounds: (instances done, total),
  // called from the importing thread.
  std::function<void(uint64_t, uint64_t)> on_progress;
};

Scene import_gltf(const std::string& path, const ImportOptions& options = {});

}  // namespace rtp
