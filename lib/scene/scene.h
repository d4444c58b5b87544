#pragma once
// The in-memory Scene every later stage consumes: meshes in local space, instances with affine
// transforms, cameras, and a source map back to the glTF file.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "core/math.h"

namespace rtp {

inline constexpr uint32_t kNoIndex = 0xffffffffu;

// One glTF primitive that contributed triangles to a Mesh.
struct SourcePrimitive {
  uint32_t gltf_mesh = kNoIndex;       // index into /meshes
  uint32_t gltf_primitive = kNoIndex;  // index into /meshes/M/primitives
};

// Where a triangle came from: Mesh::primitives[primitive], triangle number `triangle` of that
// primitive (after strip/fan expansion, counting every triangle the primitive defines).
struct TriangleSource {
  uint32_t primitive = 0;
  uint32_t triangle = 0;
};

// A triangle mesh in its own local space. One glTF mesh (all its triangle primitives) = one Mesh,
// shared by every node that uses it.
struct Mesh {
  std::string name;
  std::vector<Vec3f> positions;
  std::vector<uint32_t> indices;            // 3 per triangle, all < positions.size()
  std::vector<SourcePrimitive> primitives;  // the glTF primitives this mesh was built from
  std::vector<TriangleSource> source;       // one per triangle
  // Optional per-vertex attributes, loaded only when asked for (ImportOptions::attributes,
  // rtpack-convert --attributes): each is empty or has exactly one entry per position.
  // normals: glTF NORMAL (unit length; (0,0,0) = "none given" for vertices of a primitive without
  // NORMAL in a mesh where another primitive has it). uvs: glTF TEXCOORD_0 ((0,0) likewise).
  std::vector<Vec3f> normals;
  std::vector<Vec2f> uvs;

  uint64_t triangle_count() const { return indices.size() / 3; }
  Aabb local_bounds() const;
};

// A placement of a mesh in the world.
struct Instance {
  uint32_t mesh = 0;
  Affine3x4 transform;               // local -> world (node hierarchy composed in double, then stored)
  bool mirrored = false;             // det(transform) < 0: triangle winding flips
  uint32_t node = kNoIndex;          // glTF node index
  uint32_t gpu_instance = kNoIndex;  // index within the node's EXT_mesh_gpu_instancing, or kNoIndex
};

struct Camera {
  enum class Type { kPerspective, kOrthographic };
  std::string name;
  uint32_t node = kNoIndex;
  uint32_t gltf_camera = kNoIndex;
  Type type = Type::kPerspective;
  double yfov = 0, aspect_ratio = 0, znear = 0, zfar = 0;  // perspective (aspect/zfar 0 = unset)
  double xmag = 0, ymag = 0;                               // orthographic (znear/zfar shared)
  Affine3x4 world;                                         // camera -> world, rotation + translation only (scale stripped)
};

// What the importer read to build the scene (rtpack-convert's input bytes): the glTF or .glb file and
// its external buffers. Images are never read (a tracer needs no textures); they are counted apart.
struct InputFiles {
  uint64_t gltf_bytes = 0;    // the .gltf or .glb file
  uint64_t buffer_bytes = 0;  // external .bin buffers read (data URIs and the .glb BIN chunk are in gltf_bytes)
  uint32_t buffer_files = 0;
  std::vector<std::string> buffer_paths;  // the external buffer files read (an output must not replace one)
  uint32_t images = 0;                    // glTF images (none is read)
  uint64_t image_file_bytes = 0;          // sizes of the external image files that exist (stat only)
  uint64_t read_bytes() const { return gltf_bytes + buffer_bytes; }
};

struct Scene {
  std::string source_path;
  InputFiles input;
  int gltf_scene = -1;
  std::vector<Mesh> meshes;
  std::vector<Instance> instances;
  std::vector<Camera> cameras;
  std::vector<std::string> warnings;
  Aabb bounds;  // world bounds of every instanced triangle (with instance transforms)

  uint64_t unique_triangles() const;     // Σ over meshes
  uint64_t instanced_triangles() const;  // Σ over instances of their mesh's triangles
};

// Exact world bounds of all instances: for every instance, the extreme vertices along each world axis
// of the stored transform (branch and bound over a per-mesh point tree, not a transformed box; only
// instances whose root-box bound can still raise a face of the scene box are searched).
// `progress(done, total)` (optional) is called from the calling thread after each of its two passes
// over the instances (all six faces at once), `done` in instances' worth of the work (total = the
// instance count).
Aabb compute_world_bounds(const Scene& scene, const std::function<void(uint64_t, uint64_t)>& progress = {});
// The same for one instance (builds that mesh's point tree: for diagnostics, not for loops).
Aabb compute_instance_world_bounds(const Scene& scene, size_t instance);

}  // namespace rtp
