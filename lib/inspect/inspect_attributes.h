#pragma once
// rtpack-inspect --verify for attribute chunks (formats/SPEC.md §4.4): each one parsed and checked on
// its own (ranges, indices, unit normals, finite uvs, ascending triangle ids), then matched against
// the geometry chunk it belongs to and the mesh table's attribute flags.
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/aligned.h"
#include "formats/chunk.h"
#include "formats/package.h"

namespace rtp {
class Problems;
}

namespace rtp::inspect_detail {

// What an attribute entry must agree with: one MeshEntry of the geometry chunk.
struct GeometryEntry {
  uint32_t id = 0;    // MeshEntry id
  uint32_t mesh = 0;  // scene mesh (segment: = id; piece: its instance's mesh), or 0xFFFFFFFF
  uint64_t triangles = 0;
  uint64_t prim_hash = 0;  // pieces: hash of the set of leaf prims (0 for whole meshes)
};

uint64_t prim_set_hash(const std::vector<uint32_t>& prims);  // order-independent

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
    std::vector<fmt::AttributeEntry> entries;
    std::vector<uint64_t> tri_hash;  // per entry with tri ids
    bool ok = false;
  };
  std::map<std::pair<uint32_t, uint64_t>, std::vector<GeometryEntry>> geometry_;  // keyed by geometry kind
  std::map<std::pair<uint32_t, uint64_t>, Seen> attrs_;                           // keyed by geometry kind
};

}  // namespace rtp::inspect_detail
