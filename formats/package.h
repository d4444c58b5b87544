#pragma once
// The .rtp package container: header, table of contents, chunks (formats/SPEC.md §1, §3).
// Plain old data, little-endian, no pointers.
#include <cstddef>
#include <cstdint>

namespace rtp::fmt {

inline constexpr char kMagic[8] = {'R', 'T', 'P', 'A', 'C', 'K', '\r', '\n'};
inline constexpr uint32_t kVersionMajor = 7;  // a reader refuses another major version
inline constexpr uint32_t kVersionMinor = 0;  // a reader accepts any minor version of its major
// History: 1.0 container; 1.1 attribute chunks (kinds 18, 19) and header flags; 2.0 occlusion-culling
// DAGs (kind 7, per-point grids) and the header flag kFlagDag; 3.0 DAG leaves used once stored inline
// in their level-1 node (formats/dag.h inline mask); 4.0 instance records with a double translation;
// 5.0 the instance table holds InstanceRef (where each record is) instead of a second copy of the records;
// 6.0 72-byte instance records (no forward L, no glTF source fields: what moves a ray only).
inline constexpr uint64_t kAlignment = 4096;  // every chunk and the TOC start at a multiple of this

// File header at offset 0, 128 bytes (the first 4 KiB block is reserved for it), SPEC §1:
//   0   char[8]  magic "RTPACK\r\n"
//   8   uint32   version_major
//   12  uint32   version_minor
//   16  uint64   flags              HeaderFlags: which attribute streams the package holds
//   24  uint64   file_size          bytes of the whole file
//   32  uint64   toc_offset         multiple of 4096
//   40  uint64   toc_count          number of TocEntry records
//   48  uint32   toc_entry_size     sizeof(TocEntry) = 48 (lets a reader skip newer, longer entries)
//   52  uint32   toc_crc32c         CRC-32C of the toc_count * toc_entry_size TOC bytes
//   56  uint64   unique_triangles
//   64  uint64   instanced_triangles
//   72  float[3] bounds_lo          world bounds
//   84  float[3] bounds_hi
//   96  uint32   bvh_width          W of every wide node in the package
//   100 uint32   leaf_width         B of every leaf block
//   104 uint8[20] reserved (0)
//   124 uint32   header_crc32c      CRC-32C of bytes 0..123
struct Header {
  char magic[8];
  uint32_t version_major;
  uint32_t version_minor;
  uint64_t flags;
  uint64_t file_size;
  uint64_t toc_offset;
  uint64_t toc_count;
  uint32_t toc_entry_size;
  uint32_t toc_crc32c;
  uint64_t unique_triangles;
  uint64_t instanced_triangles;
  float bounds_lo[3];
  float bounds_hi[3];
  uint32_t bvh_width;
  uint32_t leaf_width;
  uint8_t reserved[20];
  uint32_t header_crc32c;
};
static_assert(sizeof(Header) == 128);
static_assert(offsetof(Header, toc_offset) == 32 && offsetof(Header, toc_crc32c) == 52 && offsetof(Header, bounds_lo) == 72 &&
              offsetof(Header, bvh_width) == 96 && offsetof(Header, header_crc32c) == 124);

// Header flags (SPEC §1.1). Unknown bits are ignored by readers.
inline constexpr uint64_t kFlagNormals = 1;  // some attribute chunk holds normals
inline constexpr uint64_t kFlagUvs = 2;      // some attribute chunk holds TEXCOORD_0
inline constexpr uint64_t kFlagDag = 4;      // the package holds culling DAGs (kind 7, section 22)

// Chunk kinds (SPEC §3). Readers skip kinds they do not know.
enum class ChunkKind : uint32_t {
  kMetadata = 1,            // resident: JSON (source, options, tool version, cameras, source map summary)
  kTopLevelBvh = 2,         // resident: 4-wide top-level BVH over batching points, with parent pointers
  kBatchingPoints = 3,      // resident: batching-point descriptors
  kInstances = 4,           // resident: InstanceRecord table
  kMeshes = 5,              // resident: mesh table (mesh -> segment, BVH root, triangle count)
  kSourceMap = 6,           // resident: per mesh triangle -> glTF (mesh, primitive, triangle)
  kDagPool = 7,             // resident: the sparse voxel DAG pool shared by every batching point (2.0)
  kBatchingPoint = 16,      // on demand: one batching point's unique geometry and instance list
  kMeshSegment = 17,        // on demand: several instanced meshes with their local-space BVHs
  kSegmentAttributes = 18,  // on demand: normals/uvs of mesh segment `id` (only with --attributes)
  kPointAttributes = 19,    // on demand: normals/uvs of batching point `id`'s pieces
};

// Compression of a chunk's stored bytes.
enum class Compression : uint32_t { kNone = 0, kZstd = 1 };

// Table-of-contents entry, 48 bytes, SPEC §3:
//   0   uint32 kind         ChunkKind
//   4   uint32 compression  Compression
//   8   uint64 id           unique per kind
//   16  uint64 offset       multiple of 4096
//   24  uint64 stored_size  bytes in the file (compressed)
//   32  uint64 raw_size     bytes after decompression
//   40  uint32 crc32c       CRC-32C of the stored bytes
//   44  uint32 reserved (0)
struct TocEntry {
  uint32_t kind;
  uint32_t compression;
  uint64_t id;
  uint64_t offset;
  uint64_t stored_size;
  uint64_t raw_size;
  uint32_t crc32c;
  uint32_t reserved;
};
static_assert(sizeof(TocEntry) == 48 && offsetof(TocEntry, offset) == 16 && offsetof(TocEntry, crc32c) == 40);

}  // namespace rtp::fmt
