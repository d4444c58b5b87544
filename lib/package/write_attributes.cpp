// Attribute chunks: per entry the mesh's triangle indices and per-vertex normals / uvs, each stored
// only when the mesh has them (SPEC §4.4).
#include "package/write_attributes.h"

#include <string>

#include "core/error.h"
#include "layout/chunk_io.h"

namespace rtp {

void AttributeChunkBuilder::add(uint32_t id, uint32_t scene_mesh, const Mesh& mesh, const std::vector<uint32_t>* tri_ids) {
  fmt::AttributeEntry e{};
  e.id = id;
  e.mesh = scene_mesh;
  e.normal_first = e.uv_first = e.tri_id_first = fmt::kNoAttribute;
  const bool n = !mesh.normals.empty(), t = !mesh.uvs.empty();
  if ((n && mesh.normals.size() != mesh.positions.size()) || (t && mesh.uvs.size() != mesh.positions.size()))
    throw Error(ExitCode::kInternal, "mesh '" + mesh.name + "': attribute arrays out of step with its positions");
  if (n || t) {
    e.triangle_count = uint32_t(mesh.triangle_count());
    e.triangle_first = triangles_.size() / 3;
    e.vertex_count = uint32_t(mesh.positions.size());
    triangles_.insert(triangles_.end(), mesh.indices.begin(), mesh.indices.end());
    if (n) {
      e.normal_first = uint32_t(normals_.size());
      normals_.insert(normals_.end(), mesh.normals.begin(), mesh.normals.end());
    }
    if (t) {
      e.uv_first = uint32_t(uvs_.size());
      uvs_.insert(uvs_.end(), mesh.uvs.begin(), mesh.uvs.end());
    }
    if (tri_ids) {
      if (tri_ids->size() != mesh.triangle_count())
        throw Error(ExitCode::kInternal, "piece of '" + mesh.name + "': triangle id map out of step");
      for (size_t k = 1; k < tri_ids->size(); ++k)  // readers binary-search it
        if ((*tri_ids)[k] <= (*tri_ids)[k - 1])
          throw Error(ExitCode::kInternal, "piece of '" + mesh.name + "': triangle ids not ascending");
      e.tri_id_first = uint32_t(tri_ids_.size());
      tri_ids_.insert(tri_ids_.end(), tri_ids->begin(), tri_ids->end());
    }
    if (normals_.size() >= fmt::kNoAttribute || uvs_.size() >= fmt::kNoAttribute || tri_ids_.size() >= fmt::kNoAttribute)
      fail_invalid("mesh '" + mesh.name + "': more than 2^32 attribute vertices in one chunk");
  }
  entries_.push_back(e);
}

AlignedBytes AttributeChunkBuilder::finish(fmt::ChunkKind kind) const {
  ChunkBuilder cb{uint32_t(kind)};
  cb.add(fmt::SectionType::kAttrEntries, entries_);
  cb.add_raw(fmt::SectionType::kAttrTriangles, triangles_.data(), triangles_.size() / 3, 12);
  if (!normals_.empty()) cb.add(fmt::SectionType::kAttrNormals, normals_);
  if (!uvs_.empty()) cb.add(fmt::SectionType::kAttrUvs, uvs_);
  if (!tri_ids_.empty()) cb.add(fmt::SectionType::kAttrTriIds, tri_ids_);
  return cb.finish();
}

}  // namespace rtp
