#pragma once
// The cross-chunk half of the decode checks (formats/SPEC.md §4.6): what a geometry chunk says about
// scene meshes and instances, against the resident instance and mesh tables. Used by check_chunks.cpp.
#include <cstdint>
#include <string>
#include <vector>

#include "reader/check_chunks.h"

namespace rtp {

// Kind 17 entries against the mesh table: mesh in range, the table's segment = `segment`, the table's
// triangle count, no mesh twice in the chunk.
void check_segment_meshes(const fmt::MeshEntry* entries, uint64_t count, uint64_t segment, const SceneTables& t,
                          const std::string& label);

// What of a batching point piece_triangle_bounds reads (sections 5, 6, 7 and the count of section 3).
struct PointRefs {
  const fmt::InstanceRecord* records;
  const uint32_t* global_ids;
  const uint32_t* slots;
  uint64_t n_records, n_entries;
  uint64_t point;  // this chunk's batching point
};

// Kind 16 records against both tables (see decode_point): where the instance table places each record
// (an instance: this point and local index; a piece: its first piece, so not after this one); per piece entry, the triangle count of the scene
// mesh its leaves index, or kUnknownCount (no record uses it, or a table is missing).
std::vector<uint64_t> piece_triangle_bounds(const PointRefs& p, const SceneTables& t, const std::string& label);

}  // namespace rtp
