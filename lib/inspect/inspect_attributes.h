#pragma once
// rtpack-inspect --verify for attribute chunks (formats/SPEC.md §4.4): each one parsed and checked on
// its own (decode_attributes: ranges, indices, unit normals, finite uvs, ascending triangle ids), then
// matched against the geometry chunk it belongs to and the mesh table (check_attribute_geometry): the
// same checks, and the same messages, as the attribute lookup of rtpack-trace --shading
// (lib/reader/attribute_lookup.h). Here also the mesh table's and the header's attribute flags.
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/aligned.h"
#include "formats/chunk.h"
#include "formats/package.h"
#include "reader/attribute_lookup.h"

namespace rtp {
class Problems;
}

namespace rtp::inspect_detail {

// What an attribute entry must agree with: one MeshEntry of the geometry chunk (id, mesh, triangles,
// prim_hash: the PrimSetHash of a piece's leaf prims, 0 for whole meshes).
using GeometryEntry = AttributeGeometry;

uint64_t prim_set_hash(const std::vector<uint32_t>& prims);  // order-independent (PrimSetHash)

class AttributeChecker {
 public:
  // Geometry chunk (kind 17 or 16, id) and its entries in MeshEntry order.
  void geometry(uint32_t kind, uint64_t id, std::vector<GeometryEntry> entries);
  // An attribute chunk (kind 18 or 19): parses and checks it; problems name `label`.
  void chunk(uint32_t kind, uint64_t id, const std::string& label, const AlignedBytes& bytes, Problems& out);
  // Cross-checks: every attribute chunk has its geometry chunk and agrees with it; every geometry
  // chunk holding a mesh flagged with attributes has its attribute chunk; header flags.
  void finish(const std::vector<fmt::MeshInfo>& meshes, uint64_t header_flags, Problems& out) const;

 private:
  struct Seen {
    std::string label;
    uint32_t kind = 0;  // 18 or 19
    std::vector<fmt::AttributeEntry> entries;
    std::vector<AttributeTriIds> id_sets;  // per entry
    bool ok = false;                       // decode_attributes passed
  };
  // The mesh table's attribute flags against the entries; returns the header flags they imply.
  static uint64_t check_flags(const Seen& s, const std::vector<GeometryEntry>& geometry, const std::vector<fmt::MeshInfo>& meshes,
                              Problems& out);
  std::map<std::pair<uint32_t, uint64_t>, std::vector<GeometryEntry>> geometry_;  // keyed by geometry kind
  std::map<std::pair<uint32_t, uint64_t>, Seen> attrs_;                           // keyed by geometry kind
};

}  // namespace rtp::inspect_detail
