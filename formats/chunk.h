#pragma once
// The inside of every chunk (formats/SPEC.md §4): a small section table, then 64-byte aligned
// arrays of the formats/ structs. Offsets are relative to the start of the (decompressed) chunk.
#include <cstddef>
#include <cstdint>

namespace rtp::fmt {

inline constexpr uint32_t kChunkMagic = 0x48435452;  // "RTCH"

// Chunk header, 16 bytes, followed by section_count SectionEntry records:
//   0  uint32 magic "RTCH"
//   4  uint32 kind          = the TOC kind
//   8  uint32 section_count
//   12 uint32 reserved (0)
struct ChunkHeader {
  uint32_t magic;
  uint32_t kind;
  uint32_t section_count;
  uint32_t reserved;
};
static_assert(sizeof(ChunkHeader) == 16);

// Section entry, 24 bytes:
//   0  uint32 type          SectionType
//   4  uint32 elem_size     bytes per element (checked against the reader's struct size)
//   8  uint64 offset        multiple of 64, relative to the chunk start
//   16 uint64 count         number of elements
struct SectionEntry {
  uint32_t type;
  uint32_t elem_size;
  uint64_t offset;
  uint64_t count;
};
static_assert(sizeof(SectionEntry) == 24 && offsetof(SectionEntry, offset) == 8);

enum class SectionType : uint32_t {
  kNodes = 1,           // WideNode<W>[]  (mesh or instance BVH nodes, concatenated)
  kBlocks = 2,          // LeafBlock<B>[] (concatenated)
  kMeshEntries = 3,     // MeshEntry[]    (one BVH per entry: its slice of kNodes/kBlocks)
  kInstanceIds = 4,     // uint32[]       top-level leaf entries (local instance indices)
  kInstances = 5,       // InstanceRecord[] local instances (mesh = local mesh slot)
  kGlobalIds = 6,       // uint32[]       per local instance: the scene instance index
  kMeshSlots = 7,       // uint32[]       per local mesh slot: global mesh id, or kPieceBit | entry
  kTopNodes = 8,        // TopNode[]
  kPointDescs = 9,      // BatchingPointDesc[]
  kSegmentRefs = 10,    // uint32[]       mesh segments a batching point needs (ranges in descs)
  kMeshTable = 11,      // MeshInfo[]     resident global mesh table
  kSourcePrims = 12,    // SourcePrimitive pairs {gltf mesh, gltf primitive} (uint32[2])
  kSourceTris = 13,     // TriangleSource pairs {primitive slot, triangle} (uint32[2])
  kJson = 14,           // uint8[] UTF-8 JSON text
  kInstanceNodes = 15,  // WideNode<W>[] the batching point's instance BVH
  kInstanceBvh = 16,    // one MeshEntry: the instance BVH's root and sizes (items in kInstanceIds)
  // Attribute chunks (kinds 18/19, only with rtpack-convert --attributes), SPEC §4.4:
  kAttrEntries = 17,    // AttributeEntry[] one per MeshEntry of the geometry chunk, same order
  kAttrTriangles = 18,  // uint32[3][]      per triangle: vertex indices (relative to the entry)
  kAttrNormals = 19,    // float[3][]       per vertex: unit normal in the mesh's local space
  kAttrUvs = 20,        // float[2][]       per vertex: TEXCOORD_0
  kAttrTriIds = 21,     // uint32[]         per piece triangle: its index in the scene mesh, ascending
  // Occlusion culling (2.0), SPEC §4.5 and formats/dag.h:
  kPointGrids = 22,  // DagGrid[]        per batching point (descriptors chunk): grid and DAG root
  kDagNodes = 23,    // uint32[]         DAG pool node words (kind 7)
  kDagLeaves = 24,   // uint64[]         DAG pool leaf masks (kind 7)
  // 5.0: the instance table holds where each record is, not a copy of it, SPEC §2.5:
  kInstanceRefs = 25,  // InstanceRef[]    per scene instance (instance table, kind 4)
  // 7.0: instance boxes as the culling proxy of instance-heavy points, SPEC §4.5 and formats/dag.h:
  kCullNodes = 26,  // CullNode<W>[]    DAG pool chunk (kind 7): those points' instance BVHs, 8-bit boxes
};

inline constexpr uint32_t kMeshInstanced = 1, kMeshNormals = 2, kMeshUvs = 4;  // MeshInfo::flags
inline constexpr uint32_t kPieceBit = 0x80000000u;                             // kMeshSlots: a piece stored in this chunk

// One BVH inside a chunk, 32 bytes:
//   0  uint32 id           global mesh id (segments) or piece index (batching points)
//   4  uint32 root         ChildRef, node indices relative to node_first
//   8  uint32 node_first   first node in kNodes
//   12 uint32 node_count
//   16 uint32 block_first  first block in kBlocks (leaf refs are relative to it)
//   20 uint32 block_count
//   24 uint64 triangles
struct MeshEntry {
  uint32_t id;
  uint32_t root;
  uint32_t node_first;
  uint32_t node_count;
  uint32_t block_first;
  uint32_t block_count;
  uint64_t triangles;
};
static_assert(sizeof(MeshEntry) == 32 && offsetof(MeshEntry, triangles) == 24);

// Resident mesh table entry (kMeshTable), 32 bytes:
//   0  uint32 segment        mesh segment holding its BVH, or 0xFFFFFFFF for a unique mesh (stored
//                            as pieces in batching points, in its local space)
//   4  uint32 flags          bit 0: instanced (used by >= 2 instances); bit 1: its attribute entries
//                            hold normals; bit 2: they hold TEXCOORD_0 (1.1)
//   8  uint64 triangles
//   16 uint32 source_prim_first  first entry of this mesh in kSourcePrims
//   20 uint32 source_prim_count
//   24 uint64 source_tri_first   first entry of this mesh in kSourceTris (one per triangle)
struct MeshInfo {
  uint32_t segment;
  uint32_t flags;
  uint64_t triangles;
  uint32_t source_prim_first;
  uint32_t source_prim_count;
  uint64_t source_tri_first;
};
static_assert(sizeof(MeshInfo) == 32 && offsetof(MeshInfo, source_tri_first) == 24);

// Batching-point descriptor (kPointDescs), 64 bytes:
//   0  float lo[3], 12 float hi[3]   world bounds
//   24 uint64 unique_triangles       triangles of its pieces
//   32 uint64 instanced_triangles    Σ triangles of its instances' meshes
//   40 uint32 instance_count         instances of instanced meshes
//   44 uint32 piece_count
//   48 uint32 segment_first          range in kSegmentRefs: the segments it needs
//   52 uint32 segment_count
//   56 uint32 chunk_id               id of its kBatchingPoint chunk (= its index)
//   60 uint32 reserved
struct BatchingPointDesc {
  float lo[3];
  float hi[3];
  uint64_t unique_triangles;
  uint64_t instanced_triangles;
  uint32_t instance_count;
  uint32_t piece_count;
  uint32_t segment_first;
  uint32_t segment_count;
  uint32_t chunk_id;
  uint32_t reserved;
};
static_assert(sizeof(BatchingPointDesc) == 64 && offsetof(BatchingPointDesc, chunk_id) == 56);

inline constexpr uint32_t kNoAttribute = 0xFFFFFFFFu;

// Attribute entry (kAttrEntries), 40 bytes — the vertex attributes of one MeshEntry (same index):
//   0  uint32 id             = the MeshEntry's id (segment: scene mesh; batching point: piece index)
//   4  uint32 mesh           the scene mesh whose triangles these are
//   8  uint32 triangle_count = the MeshEntry's triangles (0 when the entry has no attribute)
//   12 uint32 vertex_count
//   16 uint64 triangle_first first triangle in kAttrTriangles
//   24 uint32 normal_first   first vertex in kAttrNormals, or kNoAttribute
//   28 uint32 uv_first       first vertex in kAttrUvs, or kNoAttribute
//   32 uint32 tri_id_first   first entry in kAttrTriIds (pieces), or kNoAttribute (a whole mesh: the
//                            leaf's prim is the attribute triangle index itself)
//   36 uint32 reserved (0)
struct AttributeEntry {
  uint32_t id;
  uint32_t mesh;
  uint32_t triangle_count;
  uint32_t vertex_count;
  uint64_t triangle_first;
  uint32_t normal_first;
  uint32_t uv_first;
  uint32_t tri_id_first;
  uint32_t reserved;
};
static_assert(sizeof(AttributeEntry) == 40 && offsetof(AttributeEntry, triangle_first) == 16 &&
              offsetof(AttributeEntry, tri_id_first) == 32);

}  // namespace rtp::fmt
