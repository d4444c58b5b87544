#pragma once
// The attribute stream of one geometry chunk (formats/SPEC.md §4.4): normals and TEXCOORD_0 of each
// of its meshes/pieces, indexed per triangle, in a chunk of its own so tracing never reads them.
#include <cstdint>
#include <vector>

#include "core/aligned.h"
#include "formats/chunk.h"
#include "formats/package.h"
#include "scene/scene.h"

namespace rtp {

class AttributeChunkBuilder {
 public:
  // One call per MeshEntry of the geometry chunk, in entry order: entry `id`, holding triangles of scene
  // mesh `scene_mesh`. `tri_ids` (pieces only): per triangle of `mesh`, its index in the scene mesh,
  // strictly ascending; nullptr for a whole mesh.
  void add(uint32_t id, uint32_t scene_mesh, const Mesh& mesh, const std::vector<uint32_t>* tri_ids);
  bool empty() const { return normals_.empty() && uvs_.empty(); }  // nothing to store
  bool has_normals() const { return !normals_.empty(); }
  bool has_uvs() const { return !uvs_.empty(); }
  AlignedBytes finish(fmt::ChunkKind kind) const;

 private:
  std::vector<fmt::AttributeEntry> entries_;
  std::vector<uint32_t> triangles_, tri_ids_;
  std::vector<Vec3f> normals_;
  std::vector<Vec2f> uvs_;
};

}  // namespace rtp
