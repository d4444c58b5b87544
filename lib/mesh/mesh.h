#pragma once
// Mesh processing on rtp::Mesh / rtp::Scene: clean-up (OpenMesh topology analysis), Loop subdivision
// (OpenSubdiv), and splitting into bounded pieces along a binned-SAH BVH.
//
// Every function keeps the per-triangle source map (Mesh::source) in step with Mesh::indices and
// leaves Mesh::primitives as it is. Invalid input (an index >= positions.size(), indices.size() not a
// multiple of 3, a source map that is neither empty nor one entry per triangle, a normals or uvs
// array that is neither empty nor one entry per position) throws rtp::Error with
// ExitCode::kInputInvalid; bad arguments throw rtp::Error with ExitCode::kUsage. The optional vertex
// attributes (Mesh::normals, Mesh::uvs) follow their vertices through every operation; an empty
// array stays empty.
#include <cstdint>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace rtp {

// ---- clean.cpp ----------------------------------------------------------------------------------

struct CleanOptions {
  // < 0: no welding. >= 0: vertices whose coordinates all differ by <= weld_eps (L-infinity) are
  // merged into the lowest-index vertex already kept within reach (0 merges exact duplicates only).
  // Only vertices with the same attributes merge: when Mesh::normals / Mesh::uvs are non-empty, the
  // normal / uv must be bitwise equal too, so hard edges and UV seams survive welding.
  double weld_eps = -1;
  // OpenMesh's half-edge analysis (CleanReport::nonmanifold_faces / nonmanifold_vertices): building the
  // half-edge structure of every mesh was 13 % of a FlightHelmet convert for two figures that change
  // nothing in the package, so rtpack-convert asks for it only with --topology.
  bool topology = true;
};

struct CleanReport {
  uint64_t degenerate_removed = 0;       // repeated index or exactly zero area (double), after welding
  uint64_t nonfinite_removed = 0;        // a vertex coordinate is NaN or infinite
  uint64_t welded_vertices = 0;          // vertices merged into another one
  uint64_t nonmanifold_edges = 0;        // undirected edges shared by > 2 kept triangles (reported only)
  bool topology_analysed = false;        // CleanOptions::topology: the next two were counted
  uint64_t nonmanifold_faces = 0;        // kept triangles OpenMesh's add_face refuses (complex edge/vertex)
  uint64_t nonmanifold_vertices = 0;     // vertices OpenMesh reports as non-manifold (e.g. bow-ties)
  uint64_t boundary_edges = 0;           // undirected edges used by exactly one kept triangle
  uint64_t unused_vertices_removed = 0;  // not referenced by any kept triangle (welded ones not counted)
};

// Drops non-finite and degenerate triangles, optionally welds vertices, drops unreferenced vertices
// (order-preserving compaction) and reports the topology. Surviving triangles keep their original
// order, winding and source entry. Invariant: old vertex count = new vertex count + welded_vertices +
// unused_vertices_removed.
CleanReport clean_mesh(Mesh& mesh, const CleanOptions& opt = {});

// ---- subdivide.cpp ------------------------------------------------------------------------------

struct UniformSubdivideResult {
  int levels = 0;              // levels applied (= the requested levels)
  bool used_fallback = false;  // OpenSubdiv refused the topology: midpoint (linear) 1-to-4 split used
  std::string fallback_reason;
};

// Uniform Loop subdivision (OpenSubdiv, VTX_BOUNDARY_EDGE_ONLY): exactly 4^levels triangles per input
// triangle, child triangles grouped by parent in parent order, each mapped to its parent's source
// entry. Vertices keep their indices' order as OpenSubdiv numbers them (unreferenced input vertices
// are carried along). Normals and uvs, when present, are interpolated as vertex primvars with the
// same stencils as positions; normals are then renormalized (a zero or non-finite result is stored
// as (0,0,0)). levels == 0 is a no-op; levels < 0 throws.
UniformSubdivideResult subdivide_uniform(Mesh& mesh, int levels);

// Midpoint (linear) 1-to-4 split, `levels` times: the fallback of subdivide_uniform, also usable on
// its own. Same triangle order and source map rules as subdivide_uniform; positions are unchanged.
// New vertices take the edge midpoint of position, normal (renormalized as above) and uv.
void subdivide_midpoint(Mesh& mesh, int levels);

// Longest edge (double) over all triangles; non-finite edge lengths are ignored. 0 for no triangles.
double longest_edge(const Mesh& mesh);

struct MeshSubdivideReport {
  uint32_t mesh = 0;
  bool instanced = false;      // false: no instance references the mesh, left alone
  double max_scale = 0;        // largest Affine3x4::max_scale() over its instances
  int levels = 0;              // uniform Loop levels applied
  bool hit_cap = false;        // still >= the target after max_levels
  bool used_fallback = false;  // some level used the midpoint fallback
  uint64_t triangles_before = 0, triangles_after = 0;
  double longest_world_edge_before = 0, longest_world_edge_after = 0;
};

struct SubdivideReport {
  std::vector<MeshSubdivideReport> meshes;  // one per Scene::meshes entry, same order
  uint64_t meshes_subdivided = 0;
  uint64_t meshes_at_cap = 0;
  uint64_t triangles_before = 0, triangles_after = 0;  // unique (per-mesh) triangles
};

// Adaptive uniform subdivision: every instanced mesh gets the smallest number of Loop levels L
// (<= max_levels) after which its longest edge times the largest scale of any of its instances is
// < max_edge_length. Each mesh is subdivided once, whatever its instance count; meshes already under
// the target and uninstanced meshes are left byte-identical. Meshes are processed in parallel
// (TBB); the result is deterministic. Scene::bounds is NOT recomputed (Loop only shrinks geometry,
// so the old bounds remain conservative; call compute_world_bounds for exact ones).
SubdivideReport subdivide_to_length(Scene& scene, double max_edge_length, int max_levels = 6);

// ---- split.cpp ----------------------------------------------------------------------------------

// Splits a mesh into pieces of at most max_triangles triangles: the leaves of a top-down binned SAH
// BVH over triangle centroids (3 axes x 16 bins; median split by centroid when no bin split exists),
// in left-to-right tree order. Each piece holds only its vertices (compacted, original order, with
// their normals/uvs when present), its triangles in original order with their source entries, the
// full primitives table, and the name "<name>#<piece>". A mesh with no triangles gives no pieces. max_triangles == 0 throws.
std::vector<Mesh> split_mesh(const Mesh& mesh, uint32_t max_triangles);

}  // namespace rtp
