// rtpack-inspect: --verify passes on packages written from real samples for every BVH width; a chunk
// corrupted with every checksum re-sealed (so only the invariant checks can see it) fails with exit 3
// naming that chunk; the JSON counts match the Scene; the reader-side BVH statistics equal the builder's.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstring>
#include <fstream>
#include <functional>
#include <map>

#include "bvh/bvh.h"
#include "cluster/cluster.h"
#include "formats/chunk.h"
#include "formats/top_level.h"
#include "gltf_builder.h"
#include "package_patch.h"
#include "package/inspect.h"
#include "package/package.h"
#include "package/write_package.h"
#include "scene/import.h"

namespace rtp::test {
namespace {

namespace fs = std::filesystem;

const char* kLantern = "samples/khronos/Lantern/glTF/Lantern.gltf";
const char* kForest = "samples/generated/forest-small.glb";

const Scene& scene(const char* rel) {
  static std::map<std::string, Scene> cache;
  auto it = cache.find(rel);
  if (it == cache.end()) it = cache.emplace(rel, import_gltf((source_dir() / rel).string())).first;
  return it->second;
}

// Small chunk targets so both samples give several batching points (and Lantern several pieces).
uint64_t target(const char* rel) { return rel == kLantern ? 1000 : 200000; }

struct Written {
  Plan plan;
  std::string path;
};

Written write(const char* rel, int w, const fs::path& path, int zstd_level = 9) {
  ClusterOptions co;
  co.chunk_target = target(rel);
  Written out{plan_batching_points(scene(rel), co), path.string()};
  ConvertOptions cv;
  cv.width = w;
  cv.leaf_width = w == 16 ? 8 : w;
  cv.zstd_level = zstd_level;
  write_package(scene(rel), out.plan, out.path, cv);
  return out;
}

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun inspect(const std::string& args, const fs::path& dir) {
  const std::string cmd = std::string(RTP_BINARY_DIR) + "/rtpack-inspect " + args + " > " + (dir / "out").string() + " 2> " +
                          (dir / "err").string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "out"), slurp(dir / "err")};
}

// The TOC index and label of chunk (kind, id).
std::pair<size_t, std::string> chunk_of(const std::string& path, fmt::ChunkKind kind, uint64_t id) {
  PackageReader r(path);
  const int64_t i = r.find(kind, id);
  EXPECT_GE(i, 0);
  return {size_t(i), chunk_label(r.toc()[size_t(i)], size_t(i))};
}

class Inspect : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(Inspect, VerifyPassesAndJsonCountsMatchTheSceneForEveryWidth) {
  for (const char* rel : {kLantern, kForest})
    for (int w : {4, 8, 16}) {
      SCOPED_TRACE(std::string(rel) + " W=" + std::to_string(w));
      const Written p = write(rel, w, dir / "p.rtp");
      const Scene& s = scene(rel);
      ASSERT_GT(p.plan.points.size(), 2u);
      const ToolRun r = inspect("--verify --json --chunks " + p.path, dir);
      ASSERT_EQ(r.code, 0) << r.out << r.err;
      const auto j = nlohmann::json::parse(r.out);
      EXPECT_EQ(j["problems"]["count"], 0u) << j["problems"].dump(2);
      EXPECT_TRUE(j["verified"].get<bool>());
      EXPECT_EQ(j["header"]["bvh_width"], w);
      EXPECT_EQ(j["header"]["unique_triangles"], s.unique_triangles());
      EXPECT_EQ(j["header"]["instanced_triangles"], s.instanced_triangles());
      EXPECT_EQ(j["instances"], s.instances.size());
      EXPECT_EQ(j["meshes"], s.meshes.size());
      const auto& bp = j["batching_points"];
      EXPECT_EQ(bp["count"], p.plan.points.size());
      EXPECT_EQ(bp["pieces"], p.plan.pieces.size());
      uint64_t instances = 0, unique = 0, instanced = 0;
      for (const auto& pt : p.plan.points) {
        instances += pt.instances.size();
        unique += pt.unique_triangles;
        instanced += pt.instanced_triangles;
      }
      EXPECT_EQ(bp["instances"], instances);
      EXPECT_EQ(bp["unique_triangles"], unique);
      EXPECT_EQ(bp["instanced_triangles"], instanced);
      EXPECT_EQ(unique + instanced, s.instanced_triangles());  // every placed triangle in one point
      EXPECT_EQ(j["mesh_segments"]["count"], p.plan.segments.size());
      EXPECT_EQ(j["chunks"].size(), p.plan.points.size() + p.plan.segments.size() + 6);
      EXPECT_EQ(j["file_bytes"], fs::file_size(p.path));
      EXPECT_EQ(j["bvh"]["batching-point pieces"]["bvhs"], p.plan.pieces.size());
      EXPECT_EQ(j["bvh"]["instance BVHs"]["bvhs"], p.plan.points.size());
    }
}

TEST_F(Inspect, TextReportNamesEverySection) {
  const Written p = write(kForest, 8, dir / "f.rtp");
  const ToolRun r = inspect("--verify --chunks " + p.path, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* s : {"triangles     15,366 unique, 9,219,600 instanced", "chunk sizes", "mesh segment (on demand)",
                        "batching points ", "triangles (unique + instanced) per point", "mesh segments ", "segment meshes:",
                        "instance BVHs:", "c_box", "verify: OK", "perspective"})
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r.out;
}

// Each corruption is re-sealed (chunk CRC, TOC CRC, header CRC): only an invariant can catch it.
struct Corruption {
  const char* name;
  const char* sample;
  fmt::ChunkKind kind;
  uint64_t id;
  const char* expect;  // a phrase of the problem
  std::function<void(uint8_t*)> edit;
};

template <int W>
void corrupt_nodes(uint8_t* chunk, fmt::SectionType type, const std::function<void(fmt::WideNode<W>&)>& f) {
  fmt::WideNode<W>* n = section<fmt::WideNode<W>>(chunk, type);
  ASSERT_NE(n, nullptr);
  f(n[0]);
}

std::vector<Corruption> corruptions() {
  using fmt::SectionType;
  std::vector<Corruption> c;
  c.push_back({"piece prim id duplicated", kLantern, fmt::ChunkKind::kBatchingPoint, 3, "stored more than once",
               [](uint8_t* chunk) {
                 fmt::MeshEntry* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
                 fmt::LeafBlock<8>* b = section<fmt::LeafBlock<8>>(chunk, SectionType::kBlocks) + e[0].block_first;
                 ASSERT_GE(e[0].block_count, 2u);
                 b[0].prim[0] = b[1].prim[0];
               }});
  c.push_back({"piece box coordinate", kLantern, fmt::ChunkKind::kBatchingPoint, 2, "not inside", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kNodes, [](fmt::WideNode<8>& n) { n.lo[0][0] = (n.lo[0][0] + n.hi[0][0]) / 2; });
               }});
  c.push_back({"piece child reference", kLantern, fmt::ChunkKind::kBatchingPoint, 1, "out of range", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kNodes, [](fmt::WideNode<8>& n) { n.child[0] = 0x7FFFFFF0u; });
               }});
  c.push_back({"segment box coordinate", kForest, fmt::ChunkKind::kMeshSegment, 0, "not inside", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kNodes, [](fmt::WideNode<8>& n) { n.hi[1][1] = n.lo[1][1]; });
               }});
  c.push_back({"octant order", kForest, fmt::ChunkKind::kMeshSegment, 0, "front to back", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kNodes, [](fmt::WideNode<8>& n) {
                   for (int o = 0; o < 8; ++o) std::swap(n.order[o][0], n.order[o][1]);
                 });
               }});
  c.push_back({"padding lane", kLantern, fmt::ChunkKind::kBatchingPoint, 4, "padding lane differs", [](uint8_t* chunk) {
                 uint64_t nb = 0;
                 fmt::LeafBlock<8>* b = section<fmt::LeafBlock<8>>(chunk, SectionType::kBlocks, &nb);
                 for (uint64_t k = 0; k < nb; ++k)
                   if (b[k].prim[7] == b[k].prim[6]) {  // a padded block: move a padding lane's vertex
                     b[k].v2[0][7] = b[k].v2[0][7] * 0.5f + 1.0f;
                     return;
                   }
                 FAIL() << "no padded block";
               }});
  c.push_back({"segment prim id", kForest, fmt::ChunkKind::kMeshSegment, 0, "prim ids out of range", [](uint8_t* chunk) {
                 section<fmt::LeafBlock<8>>(chunk, SectionType::kBlocks)[5].prim[0] = 0x00FFFFFFu;
               }});
  c.push_back({"instance BVH box", kForest, fmt::ChunkKind::kBatchingPoint, 4, "instance BVH", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kInstanceNodes, [](fmt::WideNode<8>& n) {
                   n.hi[2][0] = n.lo[2][0] + (n.hi[2][0] - n.lo[2][0]) / 4;
                 });
               }});
  c.push_back({"instance id duplicated", kForest, fmt::ChunkKind::kBatchingPoint, 5, "referenced", [](uint8_t* chunk) {
                 uint32_t* ids = section<uint32_t>(chunk, SectionType::kInstanceIds);
                 ids[1] = ids[0];
               }});
  c.push_back({"global instance id", kForest, fmt::ChunkKind::kBatchingPoint, 6, "differ", [](uint8_t* chunk) {
                 uint32_t* g = section<uint32_t>(chunk, SectionType::kGlobalIds);
                 g[0] = g[1];
               }});
  c.push_back({"top-level parent pointer", kForest, fmt::ChunkKind::kTopLevelBvh, 0, "parent/slot/depth", [](uint8_t* chunk) {
                 section<fmt::TopNode>(chunk, SectionType::kTopNodes)[1].slot ^= 1;
               }});
  return c;
}

TEST_F(Inspect, ResealedCorruptionIsNamedByChunkWithExitCode3) {
  for (const Corruption& c : corruptions()) {
    SCOPED_TRACE(c.name);
    const Written p = write(c.sample, 8, dir / "c.rtp", 0);  // zstd level 0: stored uncompressed
    ASSERT_EQ(inspect("--verify " + p.path, dir).code, 0);
    const auto [index, label] = chunk_of(p.path, c.kind, c.id);
    patch_chunk(p.path, index, [&](uint8_t* bytes, size_t) { c.edit(bytes); });
    const ToolRun r = inspect("--verify " + p.path, dir);
    EXPECT_EQ(r.code, 3) << r.out;
    EXPECT_NE(r.out.find("verify: FAILED"), std::string::npos) << r.out;
    // Some problem line names the corrupted chunk and says what is wrong.
    bool named = false;
    for (size_t at = r.out.find(label); at != std::string::npos; at = r.out.find(label, at + 1)) {
      const size_t eol = r.out.find('\n', at);
      named |= r.out.substr(at, eol - at).find(c.expect) != std::string::npos;
    }
    EXPECT_TRUE(named) << "expected '" << label << ": ... " << c.expect << "' in\n" << r.out;
    // Without --verify the statistics still print (no crash on the broken structure).
    EXPECT_EQ(inspect(p.path, dir).code, 0);
  }
}

TEST_F(Inspect, ChecksumMismatchIsNamedAndTheListIsCapped) {
  const Written p = write(kLantern, 8, dir / "k.rtp", 0);
  const auto [index, label] = chunk_of(p.path, fmt::ChunkKind::kBatchingPoint, 2);
  {  // one flipped byte, CRC left alone
    std::string f = slurp(p.path);
    f[PackageReader(p.path).toc()[index].offset + 200] ^= char(0xFF);
    std::ofstream(p.path, std::ios::binary | std::ios::trunc).write(f.data(), std::streamsize(f.size()));
  }
  ToolRun r = inspect("--verify " + p.path, dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.out.find(label + ": checksum mismatch"), std::string::npos) << r.out;

  // Every prim of every piece of a point out of range: many problems, 20 listed, the rest counted.
  const Written q = write(kLantern, 8, dir / "m.rtp", 0);
  const auto [qi, ql] = chunk_of(q.path, fmt::ChunkKind::kBatchingPoint, 0);
  patch_chunk(q.path, qi, [](uint8_t* chunk, size_t) {
    uint64_t nb = 0;
    fmt::LeafBlock<8>* b = section<fmt::LeafBlock<8>>(chunk, fmt::SectionType::kBlocks, &nb);
    for (uint64_t k = 0; k < nb; ++k) std::memset(b[k].v0, 0x7F, sizeof b[k].v0);  // huge vertices: outside every box
  });
  r = inspect("--verify --json " + q.path, dir);
  EXPECT_EQ(r.code, 3);
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_GT(j["problems"]["count"].get<uint64_t>(), 20u);
  EXPECT_EQ(j["problems"]["listed"].size(), 20u);
  r = inspect("--verify " + q.path, dir);
  EXPECT_NE(r.out.find("more"), std::string::npos);
}

TEST_F(Inspect, UnreadableAndMalformedFiles) {
  EXPECT_EQ(inspect((dir / "missing.rtp").string(), dir).code, 2);
  fs::create_directories(dir);
  std::ofstream(dir / "junk.rtp", std::ios::binary) << std::string(8192, 'x');
  const ToolRun r = inspect("--verify " + (dir / "junk.rtp").string(), dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("bad magic"), std::string::npos) << r.err;
  EXPECT_EQ(inspect("", dir).code, 1);
}

// The reader-side statistics reproduce the builder's (lib/bvh BvhStats) from the stored nodes alone.
template <int W, int B>
void expect_same_stats(const Mesh& m) {
  const MeshBvh<W, B> bvh = build_mesh_bvh<W, B>(m);
  Problems problems;
  std::vector<uint32_t> prims;
  BvhCheck ck;
  ck.problems = &problems;
  ck.label = m.name;
  ck.prims = &prims;
  const BvhShape s = mesh_bvh_shape<W, B>(bvh.nodes.data(), bvh.nodes.size(), bvh.blocks.data(), bvh.blocks.size(), bvh.root, &ck);
  EXPECT_EQ(problems.count(), 0u) << (problems.listed().empty() ? "" : problems.listed()[0]);
  EXPECT_EQ(prims.size(), m.triangle_count());
  EXPECT_NEAR(s.c_box, bvh.stats.c_box, 1e-9 * bvh.stats.c_box);
  EXPECT_NEAR(s.c_tri, bvh.stats.c_tri, 1e-9 * bvh.stats.c_tri);
  EXPECT_NEAR(s.branching, bvh.stats.branching, 1e-12);
  EXPECT_NEAR(s.leaf_fill, bvh.stats.leaf_fill, 1e-12);
  EXPECT_EQ(s.max_depth, bvh.stats.max_depth);
  EXPECT_EQ(s.nodes, bvh.stats.nodes);
  EXPECT_EQ(s.leaves, bvh.stats.leaves);
  EXPECT_EQ(s.blocks, bvh.stats.blocks);
  EXPECT_EQ(s.primitives, bvh.stats.primitives);
}

TEST_F(Inspect, BvhStatisticsMatchTheBuilder) {
  for (const char* rel : {kLantern, kForest})
    for (const Mesh& m : scene(rel).meshes) {
      SCOPED_TRACE(m.name);
      expect_same_stats<4, 4>(m);
      expect_same_stats<8, 8>(m);
      expect_same_stats<16, 8>(m);
    }
}

}  // namespace
}  // namespace rtp::test
