#pragma once
// Shading attributes of a hit, read from a package's attribute chunks (formats/SPEC.md §4.4): the
// interpolated world-space normal and TEXCOORD_0 of (instance, prim, u, v). In core: every
// attribute chunk is loaded once; lookups are allocation-free and thread-safe.
//
// Also the checks of an attribute chunk (SPEC §4.4), shared with rtpack-inspect --verify
// (lib/inspect/inspect_attributes.cpp): decode_attributes (the chunk on its own) and
// check_attribute_geometry (against its geometry chunk and the mesh table). Both throw
// Error(kInputInvalid) naming the chunk, the entry and the field, in O(bytes of the chunk).
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "formats/chunk.h"
#include "formats/ray_file.h"
#include "layout/chunk_io.h"
#include "reader/reader.h"

namespace rtp {

class AttributeLookup {
 public:
  // Loads the instance table, the mesh table and every attribute chunk, each checked against its
  // geometry chunk (throws rtp::Error(kInputInvalid) naming a bad chunk and field).
  explicit AttributeLookup(const PackageReader& reader);
  ~AttributeLookup();
  bool has_normals() const;
  bool has_uvs() const;
  // Misses and meshes without attributes give zeros (formats/ray_file.h, fmt::Shading).
  fmt::Shading shade(const fmt::Hit& hit) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Order-independent hash of a set of triangle ids: a piece's leaf prims, an entry's triangle ids.
class PrimSetHash {
 public:
  void add(uint32_t prim);
  uint64_t value() const;

 private:
  uint64_t sum_ = 0, count_ = 0;
};

// What an attribute entry must agree with: the MeshEntry at its index in the geometry chunk.
struct AttributeGeometry {
  uint32_t id = 0;         // the MeshEntry's id
  uint32_t mesh = 0;       // its scene mesh (segment: = id; piece: its instance's mesh), or 0xFFFFFFFF
  uint64_t triangles = 0;  // the MeshEntry's triangles
  uint64_t prim_hash = 0;  // pieces: PrimSetHash of its leaves' prims (whole meshes: 0)
};

// Per entry: what the cross-checks need of its triangle ids (an entry without any: count 0).
struct AttributeTriIds {
  uint64_t hash = 0;   // PrimSetHash of the ids
  uint64_t count = 0;  // how many (= triangle_count when present)
  uint32_t last = 0;   // the largest (they ascend)
};

// The sections of one attribute chunk (kind 18 or 19), every rule of the chunk on its own checked.
struct AttributeSections {
  const fmt::AttributeEntry* entries = nullptr;
  const std::array<uint32_t, 3>* tris = nullptr;
  const std::array<float, 3>* normals = nullptr;
  const std::array<float, 2>* uvs = nullptr;
  const uint32_t* tri_ids = nullptr;
  uint64_t n_entries = 0, n_tris = 0, n_normals = 0, n_uvs = 0, n_tri_ids = 0;
  std::vector<AttributeTriIds> id_sets;  // per entry
};

// Kind 18 / 19 on its own: per entry reserved 0, its ranges inside the sections (attribute_entry_ranges),
// an entry that stores nothing as SPEC §4.4 says and one that stores triangles with normals or uvs, triangle
// ids in pieces only (kind 19) and there for every non-empty entry, the entries' triangle and triangle-id
// ranges not overlapping (Σ counts ≤ the sections), every vertex index < vertex_count, triangle ids
// strictly ascending; every normal unit length or (0,0,0), every uv finite.
AttributeSections decode_attributes(const ChunkView& v, uint32_t kind);

// Kind 18 / 19 against the geometry chunk's entries (same order) and the mesh table: one entry per
// MeshEntry, its id the MeshEntry's, its mesh < the meshes and the MeshEntry's mesh, stored where the mesh
// table says (kind 18: in segment `chunk_id`; kind 19: as pieces), triangle_count 0 or the MeshEntry's; a
// piece's triangle ids < its mesh's triangles and the set of the piece's leaf prims (by hash).
void check_attribute_geometry(const fmt::AttributeEntry* entries, const AttributeTriIds* id_sets, uint64_t count,
                              const std::vector<AttributeGeometry>& geometry, const fmt::MeshInfo* meshes, uint64_t n_meshes,
                              uint32_t kind, uint64_t chunk_id, const std::string& label);

}  // namespace rtp
