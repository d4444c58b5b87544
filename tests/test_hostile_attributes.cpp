// Attribute chunks that break SPEC §4.4 (kinds 18 and 19), every checksum re-sealed so only the checks
// of lib/reader/attribute_lookup.h can tell: triangle ids not ascending, past the mesh or not the piece's,
// a mesh id that is huge or not the entry's, an id not the MeshEntry's, a vertex index past vertex_count,
// NaN normals and uvs, reserved fields, a whole mesh with triangle ids. `rtpack-trace --shading` used to
// answer exit 0 with wrong shading: now the attribute lookup, rtpack-trace --shading and rtpack-inspect
// --verify all refuse the package (exit 3, chunk, entry and field named) and no output file is left.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>

#include "formats/chunk.h"
#include "hostile_package.h"
#include "reader/attribute_lookup.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

using fmt::SectionType;

// Lantern with a second instance of its mesh 0: that mesh is instanced, so it is stored in a mesh
// segment and has a kind-18 chunk (bases().lantern stores all three meshes as pieces: kind 19 only).
struct SegmentBase {
  fs::path dir = temp_dir("hostile_attribute_bases");
  std::string path;
  SegmentBase() {
    ImportOptions io;
    io.normals = io.uvs = true;
    Scene s = import_gltf((source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf").string(), io);
    Instance twin = s.instances.at(0);
    twin.transform(0, 3) += 40.0;
    s.instances.push_back(twin);
    prepare_scene(s, {});
    s.bounds = compute_world_bounds(s);
    ClusterOptions co;
    co.chunk_target = 1000;
    ConvertOptions cv;
    cv.width = kW;
    cv.leaf_width = kB;
    cv.zstd_level = 0;
    path = (dir / "lantern-instanced.rtp").string();
    write_package(s, plan_batching_points(s, co), path, cv);
  }
  ~SegmentBase() { fs::remove_all(dir); }
};
const std::string& segment_base() {
  static SegmentBase b;
  return b.path;
}

// One attribute chunk of a package as stored: where it is and what it holds.
struct AttrChunk {
  size_t index = 0;
  std::string label;
  std::vector<fmt::AttributeEntry> entries;
  std::vector<uint32_t> tri_ids;
  uint64_t n_normals = 0, n_uvs = 0;
};
AttrChunk attr_chunk(const std::string& path, fmt::ChunkKind kind, uint64_t id) {
  AttrChunk c;
  std::tie(c.index, c.label) = chunk_of(path, kind, id);
  const PackageReader r(path);
  const AlignedBytes b = r.read(c.index);
  ChunkView v(b.data(), b.size(), uint32_t(kind), c.label);
  c.entries = v.copy<fmt::AttributeEntry>(SectionType::kAttrEntries);
  c.tri_ids = v.copy<uint32_t>(SectionType::kAttrTriIds, false);
  c.n_normals = v.copy<std::array<float, 3>>(SectionType::kAttrNormals, false).size();
  c.n_uvs = v.copy<std::array<float, 2>>(SectionType::kAttrUvs, false).size();
  return c;
}

std::vector<fmt::MeshInfo> mesh_table(const std::string& path) {
  const PackageReader r(path);
  const int64_t i = r.find(fmt::ChunkKind::kMeshes, 0);
  const AlignedBytes b = r.read(size_t(i));
  return ChunkView(b.data(), b.size(), uint32_t(fmt::ChunkKind::kMeshes), "mesh table")
      .copy<fmt::MeshInfo>(SectionType::kMeshTable);
}

std::vector<fmt::InstanceRef> instance_table(const std::string& path) {
  const PackageReader r(path);
  const int64_t i = r.find(fmt::ChunkKind::kInstances, 0);
  const AlignedBytes b = r.read(size_t(i));
  return ChunkView(b.data(), b.size(), uint32_t(fmt::ChunkKind::kInstances), "instance table")
      .copy<fmt::InstanceRef>(SectionType::kInstanceRefs);
}

// The index of the first entry of `c` that stores triangles (and, with `pred`, satisfies it).
size_t stored_entry(const AttrChunk& c, const std::function<bool(const fmt::AttributeEntry&)>& pred = {}) {
  for (size_t k = 0; k < c.entries.size(); ++k)
    if (c.entries[k].triangle_count > 1 && (!pred || pred(c.entries[k]))) return k;
  throw std::runtime_error("no such attribute entry");
}

std::string entry_name(const AttrChunk& c, size_t k) {
  return "entry " + std::to_string(k) + " (id " + std::to_string(c.entries[k].id) + ")";
}

// Edits the attribute chunk's bytes, every CRC re-sealed.
void patch(const std::string& path, const AttrChunk& c, const std::function<void(uint8_t*)>& edit) {
  patch_chunk(path, c.index, [&](uint8_t* chunk, size_t) { edit(chunk); });
}
fmt::AttributeEntry& entry_at(uint8_t* chunk, size_t k) {
  return section<fmt::AttributeEntry>(chunk, SectionType::kAttrEntries)[k];
}

class HostileAttributes : public Hostile {
 protected:
  // The attribute lookup (in process), rtpack-trace --shading and rtpack-inspect --verify (subprocesses)
  // refuse the package: exit 3, every needle in the message; rtpack-trace leaves no ray, hit or shading file.
  void expect_refused(const std::string& path, const std::vector<std::string>& needles) {
    try {
      const PackageReader r(path);
      const AttributeLookup lookup(r);
      ADD_FAILURE() << "the attribute lookup loaded the package";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kInputInvalid) << e.what();
      EXPECT_TRUE(contains_all(e.what(), needles)) << e.what();
    }
    const fs::path rays = dir / "cam.rays", hits = dir / "cam.hits", shading = dir / "cam.shading";
    const ToolResult t = run_tool(
        "rtpack-trace",
        {path, "--make-camera-rays", "32x24", "--rays", rays.string(), "--hits", hits.string(), "--shading", shading.string()},
        dir, {}, 20);
    EXPECT_EQ(t.code, 3) << (t.timed_out ? "hung " : "") << "signal " << t.signal << ": " << t.err;
    EXPECT_TRUE(contains_all(t.err, needles)) << "rtpack-trace --shading: " << t.err;
    for (const fs::path& p : {rays, hits, shading}) EXPECT_FALSE(fs::exists(p)) << p << " left by a refused run";
    const ToolResult v = run_tool("rtpack-inspect", {"--verify", path}, dir, {}, 20);
    EXPECT_EQ(v.code, 3) << v.out << v.err;
    EXPECT_TRUE(contains_all(v.out, needles)) << "rtpack-inspect --verify: " << v.out << v.err;  // listed on stdout
  }
  // A fault in the chunk on its own (decode_attributes): plain rtpack-inspect, which decodes every chunk it
  // reads, refuses it too (SPEC §4.7 readers A I V). Faults against the geometry need --verify.
  void expect_refused_alone(const std::string& path, const std::vector<std::string>& needles) {
    expect_refused(path, needles);
    const ToolResult i = run_tool("rtpack-inspect", {path}, dir, {}, 20);
    EXPECT_EQ(i.code, 3) << i.out << i.err;
    EXPECT_TRUE(contains_all(i.out + i.err, needles)) << "rtpack-inspect: " << i.out << i.err;
  }
};

TEST_F(HostileAttributes, IntactPackagesShadeWithExitZero) {
  for (const std::string& base : {bases().lantern, segment_base()}) {
    SCOPED_TRACE(base);
    const PackageReader r(base);
    EXPECT_GE(r.find(base == bases().lantern ? fmt::ChunkKind::kPointAttributes : fmt::ChunkKind::kSegmentAttributes, 0), 0);
    const AttributeLookup lookup(r);
    EXPECT_TRUE(lookup.has_normals());
    EXPECT_TRUE(lookup.has_uvs());
    const fs::path rays = dir / "cam.rays", hits = dir / "cam.hits", shading = dir / "cam.shading";
    const ToolResult t = run_tool(
        "rtpack-trace",
        {base, "--make-camera-rays", "48x32", "--rays", rays.string(), "--hits", hits.string(), "--shading", shading.string()},
        dir, {}, 20);
    ASSERT_EQ(t.code, 0) << t.err;
    const std::string hb = slurp(hits), sb = slurp(shading);
    ASSERT_EQ(hb.size(), 48u * 32u * sizeof(fmt::Hit));
    ASSERT_EQ(sb.size(), 48u * 32u * sizeof(fmt::Shading));
    // Lit and textured hits, and among them hits on a mesh stored whole in a mesh segment (kind 18).
    const std::vector<fmt::MeshInfo> meshes = mesh_table(base);
    const std::vector<fmt::InstanceRef> instances = instance_table(base);
    uint64_t lit = 0, textured = 0, segment_lit = 0;
    for (size_t i = 0; i < 48 * 32; ++i) {
      fmt::Hit h;
      fmt::Shading got;
      std::memcpy(&h, hb.data() + i * sizeof h, sizeof h);
      std::memcpy(&got, sb.data() + i * sizeof got, sizeof got);
      const fmt::Shading want = lookup.shade(h);
      ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << "ray " << i;
      const bool n = got.normal[0] != 0 || got.normal[1] != 0 || got.normal[2] != 0;
      lit += n;
      textured += got.uv[0] != 0 || got.uv[1] != 0;
      if (n && h.instance < instances.size()) segment_lit += meshes.at(instances[h.instance].mesh).segment != fmt::kNoAttribute;
    }
    EXPECT_GT(lit, 20u);
    EXPECT_GT(textured, 20u);
    if (base == segment_base()) {
      EXPECT_GT(segment_lit, 5u);
    }
    const ToolResult v = run_tool("rtpack-inspect", {"--verify", base}, dir, {}, 20);
    EXPECT_EQ(v.code, 0) << v.out << v.err;
  }
}

TEST_F(HostileAttributes, TriangleIdsNotAscending) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  patch(p, c, [&](uint8_t* ch) {
    uint32_t* ids = section<uint32_t>(ch, SectionType::kAttrTriIds) + c.entries[k].tri_id_first;
    std::swap(ids[0], ids[1]);
  });
  expect_refused_alone(p, {c.label, entry_name(c, k), "triangle ids not strictly ascending at 1"});
}

TEST_F(HostileAttributes, TriangleIdPastTheMesh) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  const fmt::AttributeEntry& e = c.entries[k];
  const uint64_t tris = mesh_table(p).at(e.mesh).triangles;
  patch(p, c, [&](uint8_t* ch) {  // the last id: the ids still ascend
    section<uint32_t>(ch, SectionType::kAttrTriIds)[e.tri_id_first + e.triangle_count - 1] = uint32_t(tris);
  });
  expect_refused(p, {c.label, entry_name(c, k),
                     "triangle id " + std::to_string(tris) + " out of range (mesh " + std::to_string(e.mesh) + " has " +
                         std::to_string(tris) + " triangles)"});
}

TEST_F(HostileAttributes, TriangleIdNotThePieces) {
  // An id inside the mesh and still ascending, but not a prim of the piece's leaves: its largest id + 1.
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const std::vector<fmt::MeshInfo> meshes = mesh_table(p);
  const size_t k = stored_entry(c, [&](const fmt::AttributeEntry& e) {
    return c.tri_ids.at(e.tri_id_first + e.triangle_count - 1) + 1 < meshes.at(e.mesh).triangles;
  });
  const fmt::AttributeEntry& e = c.entries[k];
  patch(p, c, [&](uint8_t* ch) { ++section<uint32_t>(ch, SectionType::kAttrTriIds)[e.tri_id_first + e.triangle_count - 1]; });
  expect_refused(p, {c.label, entry_name(c, k), "its triangle ids are not the piece's triangles"});
}

TEST_F(HostileAttributes, MeshIdHuge) {
  for (const auto& [base, kind] : {std::pair{bases().lantern, fmt::ChunkKind::kPointAttributes},
                                   std::pair{segment_base(), fmt::ChunkKind::kSegmentAttributes}}) {
    SCOPED_TRACE(base);
    const std::string p = copy(base);
    const AttrChunk c = attr_chunk(p, kind, 0);
    const size_t k = stored_entry(c);
    patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).mesh = 0xFFFFFFF0u; });
    expect_refused(
        p, {c.label, entry_name(c, k), "mesh 4294967280 out of range (" + std::to_string(mesh_table(p).size()) + " meshes)"});
  }
}

TEST_F(HostileAttributes, MeshNotTheEntrysMesh) {
  for (const auto& [base, kind] : {std::pair{bases().lantern, fmt::ChunkKind::kPointAttributes},
                                   std::pair{segment_base(), fmt::ChunkKind::kSegmentAttributes}}) {
    SCOPED_TRACE(base);
    const std::string p = copy(base);
    const AttrChunk c = attr_chunk(p, kind, 0);
    const size_t k = stored_entry(c);
    const fmt::AttributeEntry& e = c.entries[k];
    const uint32_t other = (e.mesh + 1) % uint32_t(mesh_table(p).size());  // a real mesh, not this one
    patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).mesh = other; });
    expect_refused(p, {c.label, entry_name(c, k),
                       "mesh " + std::to_string(other) + ", the geometry entry's are " + std::to_string(e.id) + " and " +
                           std::to_string(e.mesh)});
  }
}

TEST_F(HostileAttributes, IdNotTheMeshEntrys) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  const uint32_t id = c.entries[k].id;
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).id = id + 1000; });
  expect_refused(p, {c.label, "entry " + std::to_string(k) + " (id " + std::to_string(id + 1000) + ")",
                     "the geometry entry's are " + std::to_string(id) + " and"});
}

TEST_F(HostileAttributes, VertexIndexPastVertexCount) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  const fmt::AttributeEntry& e = c.entries[k];
  patch(p, c, [&](uint8_t* ch) {
    section<std::array<uint32_t, 3>>(ch, SectionType::kAttrTriangles)[e.triangle_first][1] = e.vertex_count;
  });
  expect_refused_alone(
      p, {c.label, entry_name(c, k), "vertex indices out of range: triangle 0",
          "has vertex index " + std::to_string(e.vertex_count) + ", vertex_count " + std::to_string(e.vertex_count)});
}

TEST_F(HostileAttributes, NanNormal) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c, [](const fmt::AttributeEntry& e) { return e.normal_first != fmt::kNoAttribute; });
  const uint32_t at = c.entries[k].normal_first + 1;
  patch(p, c, [&](uint8_t* ch) { section<std::array<float, 3>>(ch, SectionType::kAttrNormals)[at][1] = std::nanf(""); });
  expect_refused_alone(p, {c.label, "normals neither unit length nor (0,0,0): normal " + std::to_string(at) + " = ("});
}

TEST_F(HostileAttributes, NanUv) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c, [](const fmt::AttributeEntry& e) { return e.uv_first != fmt::kNoAttribute; });
  const uint32_t at = c.entries[k].uv_first + 2;
  patch(p, c, [&](uint8_t* ch) { section<std::array<float, 2>>(ch, SectionType::kAttrUvs)[at][0] = std::nanf(""); });
  expect_refused_alone(p, {c.label, "non-finite texture coordinates: uv " + std::to_string(at) + " = (nan"});
}

TEST_F(HostileAttributes, ReservedNotZero) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).reserved = 7; });
  expect_refused_alone(p, {c.label, entry_name(c, k), "reserved 7, not 0"});
}

TEST_F(HostileAttributes, SegmentEntryWithTriangleIds) {
  const std::string p = copy(segment_base());
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kSegmentAttributes, 0);
  const size_t k = stored_entry(c);
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).tri_id_first = 0; });
  expect_refused_alone(p, {c.label, entry_name(c, k), "tri_id_first 0 in a mesh segment's chunk"});
}

TEST_F(HostileAttributes, PieceEntryWithoutTriangleIds) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).tri_id_first = fmt::kNoAttribute; });
  expect_refused_alone(p, {c.label, entry_name(c, k), "tri_id_first 0xFFFFFFFF: a piece's entry needs triangle ids"});
}

TEST_F(HostileAttributes, EmptyEntryThatPointsAtData) {
  // triangle_count 0 ("stores nothing") with its vertex_count and firsts left: SPEC §4.4's empty entry.
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  const size_t k = stored_entry(c);
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, k).triangle_count = 0; });
  expect_refused_alone(
      p, {c.label, entry_name(c, k),
          "triangle_count 0 (an entry that stores nothing) with vertex_count " + std::to_string(c.entries[k].vertex_count)});
}

TEST_F(HostileAttributes, TriangleCountNotTheMeshEntrys) {
  const std::string p = copy(segment_base());
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kSegmentAttributes, 0);
  const size_t k = stored_entry(c);
  const uint32_t n = c.entries[k].triangle_count;
  patch(p, c, [&](uint8_t* ch) {  // and the layout kept canonical (SPEC §4.4): later entries and the section move up one
    entry_at(ch, k).triangle_count = n - 1;
    for (size_t j = k + 1; j < c.entries.size(); ++j)
      if (entry_at(ch, j).triangle_count) entry_at(ch, j).triangle_first -= 1;
    auto* tris = section<std::array<uint32_t, 3>>(ch, SectionType::kAttrTriangles);
    const uint64_t last = c.entries[k].triangle_first + n - 1;  // the triangle dropped
    fmt::SectionEntry* se = section_entry(ch, SectionType::kAttrTriangles);
    std::memmove(&tris[last], &tris[last + 1], (se->count - last - 1) * sizeof tris[0]);
    se->count -= 1;
  });
  expect_refused(p, {c.label, entry_name(c, k),
                     "triangle_count " + std::to_string(n - 1) + ", the geometry entry has " + std::to_string(n) + " triangles"});
}

TEST_F(HostileAttributes, EntriesSharingTriangles) {
  // The last stored entry made to span the whole triangle section (and the whole id section): every range
  // inside its section, but together more than the sections hold, so the per-entry loops could repeat.
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  ASSERT_GE(c.entries.size(), 2u);
  const size_t k = c.entries.size() - 1;
  ASSERT_GT(c.entries[0].triangle_count, 0u);
  patch(p, c, [&](uint8_t* ch) {
    uint64_t n_tris = 0;
    section<std::array<uint32_t, 3>>(ch, SectionType::kAttrTriangles, &n_tris);
    fmt::AttributeEntry& e = entry_at(ch, k);
    e.triangle_first = 0;
    e.tri_id_first = 0;
    e.triangle_count = uint32_t(n_tris);
  });
  expect_refused_alone(p, {c.label, entry_name(c, k), "triangle_first 0, expected "});
}

// Found by fuzz_structures: an entry's normals moved by one vertex, still inside the section, shaded every
// hit of it with its neighbour's normals (exit 0, and --verify said OK). Sections hold the entries'
// elements in entry order (SPEC §4.4), so any moved range is refused.
TEST_F(HostileAttributes, NormalRangeMovedInsideItsSection) {
  const std::string p = copy(bases().lantern);
  const AttrChunk c = attr_chunk(p, fmt::ChunkKind::kPointAttributes, 0);
  ASSERT_GE(c.entries.size(), 2u);
  ASSERT_EQ(c.entries[0].normal_first, 0u);
  patch(p, c, [&](uint8_t* ch) { entry_at(ch, 0).normal_first = 1; });
  expect_refused_alone(p, {c.label, entry_name(c, 0), "normal_first 1, expected 0"});
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
