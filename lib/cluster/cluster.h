#pragma once
// Batching points (Molenaar 2019 §3.1): the scene's objects clustered by a SAH BVH over their
// bounds and cut where a subtree fits the chunk target; instanced meshes stored once, in segments.
#include <cstdint>
#include <string>
#include <vector>

#include "formats/top_level.h"
#include "scene/scene.h"

namespace rtp {

enum class ChunkBy { kInstanced, kUnique };

struct ClusterOptions {
  uint64_t chunk_target = 0;  // triangles per batching point; 0 = derived from the scene
  ChunkBy chunk_by = ChunkBy::kInstanced;
  double piece_fraction = 0.25;  // unique meshes larger than this fraction of the target are split
  uint64_t segment_target = 0;   // triangles per mesh segment; 0 = derived from the instanced meshes' (<= chunk target)
};

// A piece of a non-instanced mesh, in the mesh's local space; its instance's transform places it
// (unique geometry is not baked into world space: that would round it to float far from the origin).
struct UniquePiece {
  uint32_t instance = 0;       // the scene instance it came from
  Mesh mesh;                   // local space; Mesh::source still maps to the glTF triangle
  std::vector<uint32_t> prim;  // per triangle: its index in the original scene mesh
  Aabb bounds;                 // mesh.local_bounds(), once (the converter reads it three times)
};

struct BatchingPoint {
  std::vector<uint32_t> pieces;     // indices into Plan::pieces
  std::vector<uint32_t> instances;  // scene instances of instanced meshes
  Aabb bounds;
  uint64_t unique_triangles = 0;     // triangles of its pieces
  uint64_t instanced_triangles = 0;  // Σ triangles of its instances' meshes
};

struct MeshSegment {
  std::vector<uint32_t> meshes;  // scene meshes (instanced ones) stored in this segment
  uint64_t triangles = 0;
};

struct Plan {
  uint64_t chunk_target = 0;  // the target used (derived when the option was 0)
  ChunkBy chunk_by = ChunkBy::kInstanced;
  std::vector<uint8_t> mesh_instanced;  // per scene mesh: 1 if used by ≥ 2 instances
  std::vector<uint32_t> mesh_segment;   // per scene mesh: its segment, or kNoIndex
  std::vector<Aabb> mesh_bounds;        // per scene mesh: local_bounds() if instanced, else empty
  std::vector<UniquePiece> pieces;
  std::vector<BatchingPoint> points;
  std::vector<MeshSegment> segments;
  std::vector<fmt::TopNode> top;  // node 0 = root; empty when there are no batching points
};

// Deterministic (sequential, ordered); derives the target when options.chunk_target == 0.
Plan plan_batching_points(const Scene& scene, const ClusterOptions& options);

// The target derived for a scene: Σ triangles / 64, clamped to [2^16, 2^22] (Molenaar uses 1M–15M
// for scenes of 10^8–10^10 triangles; a small scene still gets several chunks).
uint64_t default_chunk_target(const Scene& scene, ChunkBy by);

}  // namespace rtp
