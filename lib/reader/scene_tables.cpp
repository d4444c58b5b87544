#include "reader/scene_tables.h"

#include <string>

#include "core/error.h"

namespace rtp {
namespace {

// The chunk (kind, 0), read whole; its label through `label`.
const AlignedBytes& read_table(const PackageReader& r, fmt::ChunkKind kind, AlignedBytes& out, std::string& label) {
  const int64_t i = r.find(kind, 0);
  if (i < 0) fail_invalid(std::string("missing ") + chunk_kind_name(uint32_t(kind)) + " 0");
  label = chunk_label(r.toc()[size_t(i)], size_t(i));
  out = r.read(size_t(i));
  return out;
}

}  // namespace

ResidentTables read_resident_tables(const PackageReader& r) {
  ResidentTables t;
  for (const fmt::TocEntry& e : r.toc()) t.n_segments += e.kind == uint32_t(fmt::ChunkKind::kMeshSegment);
  const AlignedBytes& mb = read_table(r, fmt::ChunkKind::kMeshes, t.mesh_bytes, t.mesh_label);
  const ChunkView mv(mb.data(), mb.size(), uint32_t(fmt::ChunkKind::kMeshes), t.mesh_label);
  t.view.meshes = mv.get<fmt::MeshInfo>(fmt::SectionType::kMeshTable, t.view.n_meshes);
  const AlignedBytes& ib = read_table(r, fmt::ChunkKind::kInstances, t.instance_bytes, t.instance_label);
  const ChunkView iv(ib.data(), ib.size(), uint32_t(fmt::ChunkKind::kInstances), t.instance_label);
  t.view.instances = iv.get<fmt::InstanceRef>(fmt::SectionType::kInstanceRefs, t.view.n_instances);
  return t;
}

void check_resident_tables(const ResidentTables& t, uint64_t points) {
  check_mesh_table(t.view.meshes, t.view.n_meshes, kUnknownCount, kUnknownCount, t.n_segments, t.mesh_label);
  check_instance_table(t.view.instances, t.view.n_instances, t.view.n_meshes, points, t.instance_label);
}

}  // namespace rtp
