// rtpack-inspect: --verify passes on packages written from real samples for every BVH width; a chunk
// corrupted with every checksum re-sealed (so only the invariant checks can see it) fails with exit 3
// naming that chunk; the JSON counts match the Scene; the reader-side BVH statistics equal the builder's;
// the culling-DAG block matches the pool chunk read directly, and DAG corruptions name the batching point.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <bit>
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
#include "layout/chunk_io.h"
#include "inspect/inspect.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "voxel/voxel.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

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
  ConvertReport report;
};

Written write(const char* rel, int w, const fs::path& path, int zstd_level = 9, bool dag = true) {
  ClusterOptions co;
  co.chunk_target = target(rel);
  Written out{plan_batching_points(scene(rel), co), path.string(), {}};
  ConvertOptions cv;
  cv.width = w;
  cv.leaf_width = w == 16 ? 8 : w;
  cv.zstd_level = zstd_level;
  cv.dag = dag;
  out.report = write_package(scene(rel), out.plan, out.path, cv);
  return out;
}

struct ToolRun {
  int code;
  std::string out, err;
};

ToolRun inspect(const std::string& args, const fs::path& dir) {
  const std::string cmd =
      std::string(RTP_BINARY_DIR) + "/rtpack-inspect " + args + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
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
      EXPECT_EQ(j["chunks"].size(), p.plan.points.size() + p.plan.segments.size() + 7);  // 7 resident (2.0: DAG pool)
      EXPECT_EQ(j["dag"]["grids"], p.plan.points.size());
      EXPECT_EQ(j["package_bytes"], fs::file_size(p.path));
      EXPECT_EQ(j["bvh"]["batching-point pieces"]["bvhs"], p.plan.pieces.size());
      EXPECT_EQ(j["bvh"]["instance BVHs"]["bvhs"], p.plan.points.size());
    }
}

TEST_F(Inspect, TextReportNamesEverySection) {
  const Written p = write(kForest, 8, dir / "f.rtp");
  const ToolRun r = inspect("--verify --chunks " + p.path, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* s : {"triangles     15,366 unique, 9,219,600 instanced", "chunk sizes", "mesh segment (on demand)",
                        "batching points ", "triangles (unique + instanced) per point", "mesh segments ",
                        "segment meshes:", "instance BVHs:", "c_box", "verify: OK", "perspective", "DAG pool (resident)",
                        "culling DAGs    pool ", "  resolutions   ", "  sharing       ", "  set cells     "})
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
  c.push_back(
      {"piece prim id duplicated", kLantern, fmt::ChunkKind::kBatchingPoint, 3, "stored more than once", [](uint8_t* chunk) {
         fmt::MeshEntry* e = section<fmt::MeshEntry>(chunk, SectionType::kMeshEntries);
         fmt::LeafBlock<8>* b = section<fmt::LeafBlock<8>>(chunk, SectionType::kBlocks) + e[0].block_first;
         ASSERT_GE(e[0].block_count, 2u);
         b[0].prim[0] = b[1].prim[0];
       }});
  c.push_back({"piece box coordinate", kLantern, fmt::ChunkKind::kBatchingPoint, 2, "not inside", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kNodes,
                                  [](fmt::WideNode<8>& n) { n.lo[0][0] = (n.lo[0][0] + n.hi[0][0]) / 2; });
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
  c.push_back({"segment prim id", kForest, fmt::ChunkKind::kMeshSegment, 0, "prim 16777215 out of range",
               [](uint8_t* chunk) { section<fmt::LeafBlock<8>>(chunk, SectionType::kBlocks)[5].prim[0] = 0x00FFFFFFu; }});
  c.push_back({"instance BVH box", kForest, fmt::ChunkKind::kBatchingPoint, 4, "instance BVH", [](uint8_t* chunk) {
                 corrupt_nodes<8>(chunk, SectionType::kInstanceNodes,
                                  [](fmt::WideNode<8>& n) { n.hi[2][0] = n.lo[2][0] + (n.hi[2][0] - n.lo[2][0]) / 4; });
               }});
  c.push_back({"instance id duplicated", kForest, fmt::ChunkKind::kBatchingPoint, 5, "referenced", [](uint8_t* chunk) {
                 uint32_t* ids = section<uint32_t>(chunk, SectionType::kInstanceIds);
                 ids[1] = ids[0];
               }});
  c.push_back({"global instance id", kForest, fmt::ChunkKind::kBatchingPoint, 6, "places in", [](uint8_t* chunk) {
                 uint32_t* g = section<uint32_t>(chunk, SectionType::kGlobalIds);
                 g[0] = g[1];
               }});
  // SPEC §2.5: the instance table names where each record is; a wrong place is caught at decode by every
  // reader (a point out of range here; a wrong local index names the point chunk: test_hostile_tables.cpp).
  c.push_back({"instance table point", kForest, fmt::ChunkKind::kInstances, 0, "batching point 65536 out of range",
               [](uint8_t* chunk) { section<fmt::InstanceRef>(chunk, SectionType::kInstanceRefs)[2].point = 65536; }});
  c.push_back({"top-level parent pointer", kForest, fmt::ChunkKind::kTopLevelBvh, 0, "child 1 names parent",
               [](uint8_t* chunk) { section<fmt::TopNode>(chunk, SectionType::kTopNodes)[1].slot ^= 1; }});
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
    // Without --verify: no crash on the broken structure; the statistics print (exit 0), or, when the
    // structural checks every reader runs at decode catch it (formats/SPEC.md §4.6), exit 3.
    const ToolRun plain = inspect(p.path, dir);
    EXPECT_TRUE(plain.code == 0 || plain.code == 3) << plain.code << plain.err;
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

// The culling DAGs as stored, read straight through PackageReader / ChunkView (not the inspector).
struct StoredDags {
  std::vector<uint32_t> words;
  std::vector<uint64_t> leaves;
  std::vector<fmt::DagGrid> grids;
  bool pool = false, grids_section = false;
  voxel::DagView view() const { return {words.data(), words.size(), leaves.data(), leaves.size()}; }
};

StoredDags stored_dags(const std::string& path) {
  PackageReader r(path);
  StoredDags d;
  const int64_t pi = r.find(fmt::ChunkKind::kDagPool, 0);
  if (pi >= 0) {
    const AlignedBytes b = r.read(size_t(pi));
    const ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kDagPool), "pool");
    d.pool = true;
    d.words = v.copy<uint32_t>(fmt::SectionType::kDagNodes);
    d.leaves = v.copy<uint64_t>(fmt::SectionType::kDagLeaves);
  }
  const int64_t di = r.find(fmt::ChunkKind::kBatchingPoints, 0);
  EXPECT_GE(di, 0);
  const AlignedBytes b = r.read(size_t(di));
  const ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kBatchingPoints), "descriptors");
  d.grids_section = v.has(fmt::SectionType::kPointGrids);
  d.grids = v.copy<fmt::DagGrid>(fmt::SectionType::kPointGrids, false);
  return d;
}

TEST_F(Inspect, DagBlockMatchesThePoolChunkAndTheConverter) {
  for (const char* rel : {kLantern, kForest}) {
    SCOPED_TRACE(rel);
    const Written p = write(rel, 8, dir / "d.rtp");
    const StoredDags d = stored_dags(p.path);
    ASSERT_TRUE(d.pool && d.grids_section);
    ASSERT_EQ(d.grids.size(), p.plan.points.size());
    ASSERT_FALSE(d.words.empty());
    const uint64_t raw = d.words.size() * 4 + d.leaves.size() * 8;  // the pool's raw section bytes
    EXPECT_EQ(raw, p.report.dag_pool_bytes);
    // Nodes: the writer packs them back to back (formats/dag.h layout), every one reachable.
    uint64_t nodes = 0, off = 0;
    while (off < d.words.size()) {
      ++nodes;
      off += fmt::dag_node_words(d.words[off]);
    }
    EXPECT_EQ(off, d.words.size());
    std::map<uint32_t, uint64_t> resolutions;
    uint64_t set_cells = 0, separate = 0;
    for (const fmt::DagGrid& g : d.grids) {
      ++resolutions[g.resolution];
      ASSERT_EQ(voxel::check_dag(g, d.view()), "");
      set_cells += voxel::decode_dag(g, d.view()).count();  // O(R^3): fine for a test
      separate += voxel::dag_reachable_bytes(g, d.view());
    }
    EXPECT_EQ(resolutions, p.report.dag_resolutions);
    EXPECT_EQ(set_cells, p.report.dag_set_cells);

    ToolRun r = inspect("--verify --json " + p.path, dir);
    ASSERT_EQ(r.code, 0) << r.out << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["dag_pool_bytes"], raw);
    const auto& dag = j["dag"];
    EXPECT_TRUE(dag["present"].get<bool>());
    EXPECT_EQ(dag["pool_bytes"], raw);
    EXPECT_EQ(dag["nodes"], nodes);
    EXPECT_EQ(dag["node_words"], d.words.size());
    EXPECT_EQ(dag["leaves"], d.leaves.size());
    EXPECT_EQ(dag["unreachable_bytes"], 0u);
    EXPECT_EQ(dag["grids"], d.grids.size());
    EXPECT_EQ(dag["set_cells"], set_cells);
    EXPECT_EQ(dag["separate_bytes"], separate);
    EXPECT_EQ(separate, p.report.dag_separate_bytes);  // = each point's DAG as the converter built it alone
    EXPECT_GE(separate, raw);                          // the pool is the union of every point's DAG
    EXPECT_NEAR(dag["sharing"].get<double>(), double(separate) / double(raw), 1e-12);
    EXPECT_NEAR(dag["bytes_per_point"].get<double>(), double(raw) / double(d.grids.size()), 1e-9);
    EXPECT_EQ(dag["malformed_grids"], 0u);
    std::map<uint32_t, uint64_t> listed;  // {"128": points, ...} as in rtpack-convert --json
    for (const auto& [r, n] : dag["resolutions"].items()) listed[uint32_t(std::stoul(r))] = n.get<uint64_t>();
    EXPECT_EQ(listed, resolutions);

    r = inspect(p.path, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("culling DAGs    pool "), std::string::npos) << r.out;
    const auto finest = resolutions.rbegin();
    const std::string res = std::to_string(finest->second) + " at " + std::to_string(finest->first) + "^3";
    EXPECT_NE(r.out.find("  resolutions   " + res), std::string::npos) << res << "\n" << r.out;
  }
}

TEST_F(Inspect, NoDagPackageSaysSoInOneLine) {
  const Written p = write(kForest, 8, dir / "n.rtp", 9, /*dag=*/false);
  const StoredDags d = stored_dags(p.path);
  EXPECT_FALSE(d.pool || d.grids_section);
  ToolRun r = inspect("--verify --json --chunks " + p.path, dir);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["dag_pool_bytes"], 0u);
  EXPECT_FALSE(j["dag"]["present"].get<bool>());
  EXPECT_EQ(j["dag"]["grids"], 0u);
  EXPECT_EQ(j["chunks"].size(), p.plan.points.size() + p.plan.segments.size() + 6);
  r = inspect("--verify " + p.path, dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\nculling DAGs    none (converted with --no-dag)\n"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("resolutions"), std::string::npos) << r.out;
}

// True when some line of `out` holds `label`, then `who`, then `what`.
bool names(const std::string& out, const std::string& label, const std::string& who, const std::string& what) {
  for (size_t at = out.find(label); at != std::string::npos; at = out.find(label, at + 1)) {
    const std::string line = out.substr(at, out.find('\n', at) - at);
    const size_t w = line.find(who);
    if (w != std::string::npos && line.find(what, w) != std::string::npos) return true;
  }
  return false;
}

// DAG corruptions, each re-sealed: only --verify catches them, naming the batching point.
TEST_F(Inspect, DagCorruptionIsNamedByBatchingPointWithExitCode3) {
  struct Case {
    const char* name;
    fmt::ChunkKind kind;                                           // the chunk edited and named (0: the header)
    std::function<std::string(uint8_t*, const StoredDags&)> edit;  // returns "who" (the batching point)
    const char* expect;
  };
  // The first batching point whose root is a node with a child reference.
  auto node_point = [](const StoredDags& d) {
    for (size_t p = 0; p < d.grids.size(); ++p) {
      const uint32_t root = d.grids[p].root;
      if (d.grids[p].resolution > 4 && root < d.words.size() &&
          (fmt::dag_child_mask(d.words[root]) & ~fmt::dag_full_mask(d.words[root])) != 0)
        return p;
    }
    ADD_FAILURE() << "no grid with a node root";
    return size_t(0);
  };
  const std::vector<Case> cases = {
      {"pool word out of range", fmt::ChunkKind::kDagPool,
       [&](uint8_t* chunk, const StoredDags& d) {
         const size_t p = node_point(d);
         section<uint32_t>(chunk, fmt::SectionType::kDagNodes)[d.grids[p].root + 1] = 0x7FFFFFF0u;
         return "batching point " + std::to_string(p) + "'s DAG";
       },
       "out of range"},
      {"grid resolution 3", fmt::ChunkKind::kBatchingPoints,
       [&](uint8_t* chunk, const StoredDags& d) {
         const size_t p = d.grids.size() / 2;
         section<fmt::DagGrid>(chunk, fmt::SectionType::kPointGrids)[p].resolution = 3;
         return "batching point " + std::to_string(p) + ": grid";
       },
       "resolution 3 is not a power of two"},
      {"leaf emptied", fmt::ChunkKind::kDagPool,
       [&](uint8_t* chunk, const StoredDags&) {
         section<uint64_t>(chunk, fmt::SectionType::kDagLeaves)[0] = 0;
         return std::string("batching point ");
       },
       "is empty or full"},
      {"one grid too few", fmt::ChunkKind::kBatchingPoints,
       [&](uint8_t* chunk, const StoredDags&) {
         --section_entry(chunk, fmt::SectionType::kPointGrids)->count;
         return std::string("section (22)");
       },
       "grids for"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const Written p = write(kForest, 8, dir / "c.rtp", 0);  // zstd level 0: stored uncompressed
    const StoredDags d = stored_dags(p.path);
    const auto [index, label] = chunk_of(p.path, c.kind, 0);
    std::string who;
    patch_chunk(p.path, index, [&](uint8_t* bytes, size_t) { who = c.edit(bytes, d); });
    const ToolRun r = inspect("--verify " + p.path, dir);
    EXPECT_EQ(r.code, 3) << r.out;
    EXPECT_NE(r.out.find("verify: FAILED"), std::string::npos) << r.out;
    EXPECT_TRUE(names(r.out, label, who, c.expect)) << "expected '" << label << ": " << who << "... " << c.expect << "' in\n"
                                                    << r.out;
    // Plain rtpack-inspect refuses what the tracer refuses (exit 3, same message); the statistics still print.
    const ToolRun plain = inspect(p.path, dir);
    EXPECT_EQ(plain.code, 3);
    EXPECT_TRUE(names(plain.out, label, who, c.expect)) << plain.out;
    EXPECT_NE(plain.out.find("DAG pool"), std::string::npos) << plain.out;
    EXPECT_EQ(inspect("--json " + p.path, dir).code, 3);
  }
}

TEST_F(Inspect, DagHeaderFlagMustMatchThePool) {
  const Written p = write(kLantern, 8, dir / "f.rtp", 0);
  patch_header(p.path, [](fmt::Header& h) { h.flags &= ~fmt::kFlagDag; });
  ToolRun r = inspect("--verify " + p.path, dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.out.find("header: the package holds culling DAGs, but flag kFlagDag (4) is not set"), std::string::npos) << r.out;

  const Written q = write(kLantern, 8, dir / "g.rtp", 0, /*dag=*/false);
  patch_header(q.path, [](fmt::Header& h) { h.flags |= fmt::kFlagDag; });
  r = inspect("--verify " + q.path, dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.out.find("header: flag kFlagDag (4) is set, but the package has no DAG pool"), std::string::npos) << r.out;
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
  const BvhShape s =
      mesh_bvh_shape<W, B>(bvh.nodes.data(), bvh.nodes.size(), bvh.blocks.data(), bvh.blocks.size(), bvh.root, &ck);
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

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
