// Cross-chunk decode checks (formats/SPEC.md §4.6) and the instance records' transforms (§2.4): each is
// O(entries of the chunk) plus O(1) per reference into the resident tables.
#include "reader/check_references.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/math.h"

namespace rtp {
namespace {

std::string num(uint64_t v) { return std::to_string(v); }

constexpr uint32_t kNoSegment = 0xFFFFFFFFu;
constexpr uint32_t kUnset = 0xFFFFFFFFu;

// "" or what is wrong with one record's transform.
std::string record_problem(const fmt::InstanceRecord& r) {
  for (int a = 0; a < 3; ++a)
    if (!(std::abs(r.translation[a]) <= double(FLT_MAX)))
      return "translation " + std::to_string(r.translation[a]) + " on axis " + num(uint64_t(a)) + " is not a finite float";
  bool zero = true;
  for (int k = 0; k < 9; ++k) {
    if (!std::isfinite(r.inverse_linear[k])) return "inverse linear part element " + num(uint64_t(k)) + " is not finite";
    zero = zero && r.inverse_linear[k] == 0.0f;
  }
  const double det = det3_of(r.inverse_linear);
  if (!zero && !(std::abs(det) > 0)) return "inverse linear part is singular but not all zeros";
  const uint32_t mirrored = det < 0 ? 1u : 0u;
  if (r.flags != mirrored)
    return "flags " + num(r.flags) + " disagree with the determinant's sign (expected " + num(mirrored) + ")";
  if (r.reserved != 0) return "reserved field is " + num(r.reserved) + ", not 0";
  return {};
}

}  // namespace

void check_instance_records(const fmt::InstanceRecord* records, uint64_t count, const std::string& label) {
  for (uint64_t k = 0; k < count; ++k) {
    const std::string e = record_problem(records[k]);
    if (!e.empty()) fail_invalid(label + ": instance " + num(k) + ": " + e);
  }
}

void check_segment_meshes(const fmt::MeshEntry* entries, uint64_t count, uint64_t segment, const SceneTables& t,
                          const std::string& label) {
  if (!t.meshes) return;
  std::vector<uint32_t> ids(count);
  for (uint64_t k = 0; k < count; ++k) {
    const fmt::MeshEntry& e = entries[k];
    auto what = [&] { return label + ": mesh " + num(e.id) + " (entry " + num(k) + ")"; };
    if (e.id >= t.n_meshes) fail_invalid(what() + ": out of range (" + num(t.n_meshes) + " meshes)");
    const fmt::MeshInfo& m = t.meshes[e.id];
    if (m.segment != segment)
      fail_invalid(what() + ": the mesh table places the mesh in " +
                   (m.segment == kNoSegment ? std::string("no segment") : "segment " + num(m.segment)) + ", not in segment " +
                   num(segment));
    if (e.triangles != m.triangles)
      fail_invalid(what() + ": " + num(e.triangles) + " triangles, the mesh table says " + num(m.triangles));
    ids[k] = e.id;
  }
  std::sort(ids.begin(), ids.end());
  const auto twice = std::adjacent_find(ids.begin(), ids.end());
  if (twice != ids.end()) fail_invalid(label + ": mesh " + num(*twice) + " has two entries");
}

std::vector<uint64_t> piece_triangle_bounds(const PointRefs& p, const SceneTables& t, const std::string& label) {
  std::vector<uint64_t> bounds(p.n_entries, kUnknownCount);
  if (!t.meshes || !t.instances) return bounds;
  std::vector<uint32_t> piece_mesh(p.n_entries, kUnset);  // the scene mesh each piece entry is of
  for (uint64_t k = 0; k < p.n_records; ++k) {
    auto what = [&] { return label + ": instance " + num(k); };
    const fmt::InstanceRef& ref = t.instances[p.global_ids[k]];
    const uint32_t mesh = ref.mesh;  // < n_meshes: check_instance_table
    const uint32_t slot = p.slots[p.records[k].mesh];
    const uint32_t segment = t.meshes[mesh].segment;
    auto placed = [&] {
      return what() + ": global instance " + num(p.global_ids[k]) + ", which the instance table places in " +
             (ref.point == fmt::InstanceRef::kNoPoint ? std::string("no batching point")
                                                      : "batching point " + num(ref.point) + " (local " + num(ref.local) + ")");
    };
    if (!(slot & fmt::kPieceBit)) {
      if (ref.point != p.point || ref.local != k) fail_invalid(placed());
      if (slot != mesh)
        fail_invalid(what() + ": its mesh slot names mesh " + num(slot) + ", the instance table says mesh " + num(mesh));
      if (segment == kNoSegment)
        fail_invalid(what() + ": mesh " + num(mesh) + " is in no segment (the mesh table stores it as pieces)");
      continue;
    }
    const uint32_t entry = slot & ~fmt::kPieceBit;
    if (ref.point == fmt::InstanceRef::kNoPoint || std::pair<uint64_t, uint64_t>(ref.point, ref.local) > std::pair(p.point, k))
      fail_invalid(placed() + ", after this piece (it names the first)");
    if (segment != kNoSegment)
      fail_invalid(what() + ": a piece of mesh " + num(mesh) + ", which the mesh table places in segment " + num(segment));
    if (piece_mesh[entry] != kUnset && piece_mesh[entry] != mesh)
      fail_invalid(what() + ": piece entry " + num(entry) + " is of mesh " + num(piece_mesh[entry]) + " and of mesh " +
                   num(mesh));
    piece_mesh[entry] = mesh;
    bounds[entry] = t.meshes[mesh].triangles;
  }
  return bounds;
}

}  // namespace rtp
