// rtpack-validate and rtpack-trace --memory-budget as a user runs them (subprocesses): validation passes
// on every committed sample against Embree on the source and against the in-core tracer, fails (exit 3,
// naming rays) on a package with one wrong triangle re-sealed so that every checksum passes, and refuses
// bad usage clearly; rtpack-trace writes the same hit bytes in and out of core and reports the same keys.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "formats/bvh_layout.h"
#include "gltf_builder.h"
#include "package/convert.h"
#include "package_patch.h"
#include "reader/camera.h"
#include "layout/chunk_io.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

bool sanitized() { return std::getenv("RTP_SANITIZED") != nullptr; }
std::string ray_count() { return sanitized() ? "300" : "3000"; }

void convert_to(const std::string& in, const std::string& out, uint64_t points, int zstd = kDefaultZstdLevel) {
  ConvertSettings cs;
  cs.input = in;
  cs.output = out;
  cs.zstd_level = zstd;
  ConvertSettings dry = cs;
  dry.dry_run = true;
  cs.chunk_target = std::max<uint64_t>(64, convert_scene(dry).scene.instanced_triangles() / points);
  convert_scene(cs);
}

// A glTF whose meshes have no triangles converts (with a warning) to an empty package: it passes
// rtpack-inspect --verify, and rtpack-validate says there is nothing to trace (the header claimed culling
// DAGs the package did not hold, and validate refused its own default "--memory-budget 25%").
TEST(ValidateTool, AnEmptyPackageIsValidAndSaysSo) {
  const fs::path dir = temp_dir("validate_empty");
  const fs::path gltf = dir / "empty.gltf";
  std::ofstream(gltf) << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
                         R"("meshes":[{"primitives":[]}]})";
  const std::string pkg = (dir / "empty.rtp").string();
  const ToolResult c = run_tool("rtpack-convert", {gltf.string(), "-o", pkg}, dir);
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.err.find("no triangles"), std::string::npos) << c.err;
  const ToolResult v = run_tool("rtpack-inspect", {"--verify", pkg}, dir);
  EXPECT_EQ(v.code, 0) << v.out << v.err;
  const ToolResult a = run_tool("rtpack-validate", {pkg}, dir);
  EXPECT_EQ(a.code, 0) << a.out << a.err;
  EXPECT_NE(a.out.find("the package holds no triangles"), std::string::npos) << a.out;
  const ToolResult j = run_tool("rtpack-validate", {pkg, "--json"}, dir);
  ASSERT_EQ(j.code, 0) << j.out << j.err;
  const auto r = nlohmann::json::parse(j.out);
  EXPECT_TRUE(r.contains("schema_version"));
  EXPECT_TRUE(r["ok"].get<bool>());
  EXPECT_EQ(r["failures"], 0);
  EXPECT_TRUE(r["kinds"].empty());
}

// The convert options validate re-applies to --source are the package's (metadata /options): when they do
// not fit the source, the message says so instead of naming an option the user never passed ("--scene 7:
// the file has 1 scenes").
TEST(ValidateTool, RecordedOptionsThatDoNotFitTheSourceAreNamedAsThePackages) {
  const fs::path dir = temp_dir("validate_options");
  const std::string src = (source_dir() / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string();
  const std::string pkg = (dir / "s.rtp").string();
  ASSERT_EQ(run_tool("rtpack-convert", {"-q", src, "--zstd-level", "0", "-o", pkg}, dir).code, 0);
  size_t meta = 0;
  {
    const PackageReader r(pkg);
    while (meta < r.toc().size() && r.toc()[meta].kind != uint32_t(fmt::ChunkKind::kMetadata)) ++meta;
    ASSERT_LT(meta, r.toc().size());
  }
  bool patched = false;
  patch_chunk(pkg, meta, [&](uint8_t* c, size_t n) {
    std::string text(reinterpret_cast<const char*>(c), n);
    const size_t at = text.find("\"scene\":0,");
    if (at == std::string::npos) return;
    c[at + 8] = '7';  // the same length: the chunk keeps its size
    patched = true;
  });
  ASSERT_TRUE(patched);
  const ToolResult r = run_tool("rtpack-validate", {pkg, "--source", src, "--rays", "100"}, dir);
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("metadata /options, the convert options the package records, do not apply to --source"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("scene 7"), std::string::npos) << r.err;
}

TEST(ValidateTool, PassesOnEverySampleAgainstEmbreeAndInCore) {
  const fs::path dir = temp_dir("validate");
  const fs::path s = source_dir() / "samples";
  for (const fs::path& src : {s / "generated/gallery.glb", s / "generated/forest-small.glb", s / "generated/far.glb",
                              s / "khronos/FlightHelmet/glTF/FlightHelmet.gltf", s / "khronos/BoomBox/glTF/BoomBox.gltf",
                              s / "khronos/Lantern/glTF/Lantern.gltf", s / "khronos/Suzanne/glTF/Suzanne.gltf"}) {
    SCOPED_TRACE(src.string());
    const std::string pkg = (dir / (src.stem().string() + ".rtp")).string();
    convert_to(src.string(), pkg, 30);
    const ToolResult a =
        run_tool("rtpack-validate", {pkg, "--source", src.string(), "--rays", ray_count(), "--json"}, dir, {}, 300);
    ASSERT_EQ(a.code, 0) << a.out << a.err;
    const auto j = nlohmann::json::parse(a.out);
    EXPECT_TRUE(j["ok"].get<bool>());
    EXPECT_EQ(j["reference"], "embree");
    ASSERT_EQ(j["kinds"].size(), 7u);
    EXPECT_EQ(j["kinds"][6]["kind"], "path");
    uint64_t embree_errors = 0;
    for (const auto& k : j["kinds"]) {
      EXPECT_EQ(k["failures"], 0) << k.dump();
      EXPECT_GT(k["rays"].get<uint64_t>(), 0u) << k.dump();
      embree_errors += k["reference_errors"].get<uint64_t>();
      if (src.stem() == "far") {  // far from the origin the double reference settles the precision ties
        EXPECT_EQ(k["precision_ties"], 0) << k.dump();
      }
    }
    // far.glb's instances sit at 3e6 with translations float cannot hold: Embree's float matrices miss
    // by more than its triangles, and the double reference must say so.
    if (src.stem() == "far") {
      EXPECT_GT(embree_errors, 0u);
    }
    EXPECT_LE(j["out_of_core"]["peak_cache_bytes"].get<uint64_t>(), j["out_of_core"]["memory_budget"].get<uint64_t>());
    const ToolResult b = run_tool("rtpack-validate", {pkg, "--rays", ray_count()}, dir, {}, 300);
    EXPECT_EQ(b.code, 0) << b.out << b.err;
    EXPECT_NE(b.out.find("ok: every answer agrees"), std::string::npos) << b.out;
  }
  fs::remove_all(dir);
}

// The real assets nobody here wrote (skips without ../shared/assets): every model and scene, and
// DamagedHelmet (the other Khronos assets are committed in samples/ and covered above).
TEST(ValidateTool, PassesOnSharedAssets) {
  const fs::path root = shared_assets();
  RTP_NEED_SHARED(root);
  std::vector<fs::path> files;
  for (const char* sub : {"models", "scenes"})
    for (const auto& e : fs::directory_iterator(root / sub))
      if (e.path().extension() == ".glb") files.push_back(e.path());
  files.push_back(root / "khronos/DamagedHelmet/glTF-Binary/DamagedHelmet.glb");
  std::sort(files.begin(), files.end());
  const fs::path dir = temp_dir("validate_shared");
  size_t validated = 0;
  for (const fs::path& src : files) {
    if (!fs::exists(src)) {
      if (shared_assets_required()) ADD_FAILURE() << src << " is absent, and RTP_REQUIRE_SHARED is set";
      continue;
    }
    SCOPED_TRACE(src.string());
    const std::string pkg = (dir / (src.stem().string() + ".rtp")).string();
    convert_to(src.string(), pkg, 30);
    const ToolResult r = run_tool(
        "rtpack-validate", {pkg, "--source", src.string(), "--rays", sanitized() ? "100" : "1000", "--json"}, dir, {}, 600);
    ASSERT_EQ(r.code, 0) << r.out << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_TRUE(j["ok"].get<bool>()) << r.out;
    ++validated;
  }
  std::printf("rtpack-validate: %zu shared assets pass against Embree\n", validated);
  EXPECT_GE(validated, 10u);
  fs::remove_all(dir);
}

// One triangle collapsed to a point: the triangle that most of the camera's primary rays hit, in the mesh
// segment that stores its (instanced) mesh, every lane that holds it; the chunk re-sealed, so container and
// structural checks pass. Embree on the source disagrees on the rays through it.
TEST(ValidateTool, FailsOnAWrongTriangleNamingTheRays) {
  const fs::path dir = temp_dir("validate_bad");
  const std::string src = (source_dir() / "samples/generated/gallery.glb").string();
  const std::string pkg = (dir / "gallery.rtp").string();
  convert_to(src, pkg, 8, 0);
  const ToolResult good =
      // 3000 rays even when sanitized: at 300 no path ray of the sanitized run met the one broken triangle.
      run_tool("rtpack-validate", {pkg, "--source", src, "--rays", "3000", "--kinds", "primary,path"}, dir, {}, 300);
  ASSERT_EQ(good.code, 0) << good.out << good.err;
  ConvertSettings dry;
  dry.input = src;
  dry.dry_run = true;
  const Scene scene = convert_scene(dry).scene;
  size_t index = 0;
  uint32_t mesh = 0, prim = 0, B = 0;
  {
    const PackageReader r(pkg);
    B = r.header().leaf_width;
    const auto tracer = load_package_in_core(r);
    const CameraRays cam = camera_rays(r, 160, 120);
    std::vector<fmt::Hit> hits(cam.rays.size());
    tracer->closest(cam.rays.data(), hits.data(), hits.size(), {});
    std::map<std::pair<uint32_t, uint32_t>, int> count;
    for (const fmt::Hit& h : hits)
      if (h.t < INFINITY) ++count[{scene.instances[h.instance].mesh, h.prim}];
    ASSERT_FALSE(count.empty());
    const auto most =
        std::max_element(count.begin(), count.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    mesh = most->first.first, prim = most->first.second;
    const AlignedBytes mb = r.read(size_t(r.find(fmt::ChunkKind::kMeshes, 0)));
    const ChunkView mv(mb.data(), mb.size(), uint32_t(fmt::ChunkKind::kMeshes), "mesh table");
    uint64_t n = 0;
    const uint32_t segment = mv.get<fmt::MeshInfo>(fmt::SectionType::kMeshTable, n)[mesh].segment;
    ASSERT_NE(segment, 0xFFFFFFFFu) << "gallery's meshes are instanced: in mesh segments";
    index = size_t(r.find(fmt::ChunkKind::kMeshSegment, segment));
  }
  uint64_t collapsed = 0;
  patch_chunk(pkg, index, [&](uint8_t* chunk, size_t) {
    const fmt::SectionEntry* blocks = section_entry(chunk, fmt::SectionType::kBlocks);
    const fmt::SectionEntry* entries = section_entry(chunk, fmt::SectionType::kMeshEntries);
    ASSERT_TRUE(blocks && entries);
    for (uint64_t e = 0; e < entries->count; ++e) {
      const auto* me = reinterpret_cast<const fmt::MeshEntry*>(chunk + entries->offset) + e;
      if (me->id != mesh) continue;
      for (uint64_t b = me->block_first; b < uint64_t(me->block_first) + me->block_count; ++b) {
        float* f = reinterpret_cast<float*>(chunk + blocks->offset + b * blocks->elem_size);
        const uint32_t* prims = reinterpret_cast<const uint32_t*>(f + 9 * B);
        for (uint32_t l = 0; l < B; ++l)
          if (prims[l] == prim) {
            for (int a = 0; a < 3; ++a) f[(3 + a) * B + l] = f[(6 + a) * B + l] = f[a * B + l];  // v1 = v2 = v0
            ++collapsed;
          }
      }
    }
  });
  ASSERT_GT(collapsed, 0u);
  const ToolResult bad =
      // 3000 rays even when sanitized: at 300 no path ray of the sanitized run met the one broken triangle.
      run_tool("rtpack-validate", {pkg, "--source", src, "--rays", "3000", "--kinds", "primary,path"}, dir, {}, 300);
  EXPECT_EQ(bad.code, 3) << bad.out << bad.err;
  EXPECT_NE(bad.out.find("FAIL primary ray "), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("FAIL path ray "), std::string::npos) << bad.out;  // the ray stream's answers are judged too
  EXPECT_NE(bad.out.find("FAILED: some answers are wrong"), std::string::npos) << bad.out;
  EXPECT_NE(bad.err.find("rays answered wrongly"), std::string::npos) << bad.err;
  fs::remove_all(dir);
}

TEST(ValidateTool, UsageErrorsAreClear) {
  const fs::path dir = temp_dir("validate_usage");
  const fs::path s = source_dir() / "samples";
  const std::string pkg = (dir / "gallery.rtp").string();
  convert_to((s / "generated/gallery.glb").string(), pkg, 8);
  const ToolResult kind = run_tool("rtpack-validate", {pkg, "--kinds", "primary,sideways"}, dir);
  EXPECT_EQ(kind.code, 1);
  EXPECT_NE(kind.err.find("'sideways' is not a ray kind"), std::string::npos) << kind.err;
  const ToolResult other =
      run_tool("rtpack-validate", {pkg, "--source", (s / "khronos/Suzanne/glTF/Suzanne.gltf").string()}, dir);
  EXPECT_EQ(other.code, 1);
  EXPECT_NE(other.err.find("is not the scene of this package"), std::string::npos) << other.err;
  const ToolResult small = run_tool("rtpack-validate", {pkg, "--memory-budget", "1KiB"}, dir);
  EXPECT_EQ(small.code, 1);
  EXPECT_NE(small.err.find("below the minimum of"), std::string::npos) << small.err;
  const ToolResult unit = run_tool("rtpack-validate", {pkg, "--memory-budget", "12 parsecs"}, dir);
  EXPECT_EQ(unit.code, 1);
  EXPECT_NE(unit.err.find("--memory-budget 12 parsecs"), std::string::npos) << unit.err;
  // An explicit empty --kinds used to validate the default kinds, and --seed -1 ran as seed 2^64 - 1.
  const ToolResult none = run_tool("rtpack-validate", {pkg, "--kinds", ""}, dir);
  EXPECT_EQ(none.code, 1);
  EXPECT_NE(none.err.find("--kinds: empty"), std::string::npos) << none.err;
  for (const char* seed : {"-1", "1.5", "18446744073709551616", ""}) {
    const ToolResult bad = run_tool("rtpack-validate", {pkg, "--seed", seed, "--rays", "10"}, dir);
    EXPECT_EQ(bad.code, 1) << seed;
    EXPECT_NE(bad.err.find("expected an integer from 0 to 18446744073709551615"), std::string::npos) << seed << ": " << bad.err;
  }
  const ToolResult top = run_tool("rtpack-validate", {pkg, "--seed", "18446744073709551615", "--rays", "10"}, dir);
  EXPECT_EQ(top.code, 0) << top.err;
  fs::remove_all(dir);
}

// rtpack-trace: --memory-budget gives the in-core hit bytes; --json has the same keys on both paths.
TEST(TraceOutOfCore, SameHitsAndTheSameJsonKeys) {
  const fs::path dir = temp_dir("trace_ooc");
  const std::string pkg = (dir / "forest.rtp").string();
  convert_to((source_dir() / "samples/generated/forest-small.glb").string(), pkg, 60);
  const std::string rays = (dir / "rays.bin").string();
  const ToolResult in = run_tool(
      "rtpack-trace", {pkg, "--make-camera-rays", "200x150", "--rays", rays, "--hits", (dir / "in.bin").string(), "--json"}, dir);
  ASSERT_EQ(in.code, 0) << in.err;
  const auto ji = nlohmann::json::parse(in.out);
  std::vector<std::string> traced;  // the budgets that ran (a refused one is checked, then skipped)
  for (const char* budget : {"100%", "10%", "5%"}) {
    SCOPED_TRACE(budget);
    const ToolResult out = run_tool(
        "rtpack-trace", {pkg, "--rays", rays, "--hits", (dir / "out.bin").string(), "--memory-budget", budget, "--json"}, dir);
    if (out.code == 1) {  // below this package's minimum: said so, nothing written
      EXPECT_NE(out.out.find("below the minimum of"), std::string::npos) << out.out;
      EXPECT_FALSE(fs::exists(dir / "out.bin"));
      continue;
    }
    ASSERT_EQ(out.code, 0) << out.err;
    EXPECT_EQ(slurp_file(dir / "in.bin"), slurp_file(dir / "out.bin"));
    const auto jo = nlohmann::json::parse(out.out);
    EXPECT_EQ(jo["mode"], "out of core");
    EXPECT_LE(jo["peak_cache_bytes"].get<uint64_t>(), jo["memory_budget"].get<uint64_t>());
    for (const auto& [key, value] : ji.items()) EXPECT_TRUE(jo.contains(key)) << key;
    for (const auto& [key, value] : jo.items()) EXPECT_TRUE(ji.contains(key)) << key;
    EXPECT_EQ(jo["hits"], ji["hits"]);
    fs::remove(dir / "out.bin");
    traced.push_back(budget);
  }
  // 100 % of the on-demand bytes is never below the minimum: the comparison above ran at least there.
  ASSERT_FALSE(traced.empty());
  EXPECT_EQ(traced.front(), "100%");
  fs::remove_all(dir);
}

// DAG culling: off in core unless --cull (there it cost 1.3-2.4x the time it saved), on out of core unless
// --no-cull; the hits are the same bytes every way, and the JSON says which and why.
TEST(TraceCulling, OffInCoreOnOutOfCoreSameHits) {
  const fs::path dir = temp_dir("trace_cull");
  const std::string pkg = (dir / "gallery.rtp").string();
  convert_to((source_dir() / "samples/generated/gallery.glb").string(), pkg, 8);
  const std::string rays = (dir / "rays.bin").string();
  const ToolResult base =
      run_tool("rtpack-trace",
               {pkg, "--make-camera-rays", "160x120", "--rays", rays, "--hits", (dir / "base.bin").string(), "--json"}, dir);
  ASSERT_EQ(base.code, 0) << base.err;
  const auto jb = nlohmann::json::parse(base.out);
  EXPECT_EQ(jb["mode"], "in core");
  EXPECT_EQ(jb["culling"], "off (in core; --cull tests the DAGs)");
  EXPECT_EQ(jb["culled_visits"], 0);
  EXPECT_GT(jb["batching_point_visits"].get<uint64_t>(), 0u);
  struct Case {
    std::vector<std::string> args;
    const char* culling;
    bool culls;  // in core every DAG is tested; out of core only small queues are (docs/user-guide.md)
  };
  for (const Case& c : {Case{{"--cull"}, "on", true}, Case{{"--memory-budget", "100%"}, "on", false},
                        Case{{"--memory-budget", "100%", "--no-cull"}, "off (--no-cull)", false}}) {
    std::vector<std::string> args = {pkg, "--rays", rays, "--hits", (dir / "h.bin").string(), "--json"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    SCOPED_TRACE(c.args.back());
    const ToolResult r = run_tool("rtpack-trace", args, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["culling"], c.culling);
    // gallery's camera sees empty space in some points' boxes: in core, culling on culls visits.
    if (c.culls) {
      EXPECT_GT(j["culled_visits"].get<uint64_t>(), 0u);
    }
    EXPECT_EQ(slurp_file(dir / "base.bin"), slurp_file(dir / "h.bin"));
    fs::remove(dir / "h.bin");
  }
  const ToolResult both =
      run_tool("rtpack-trace", {pkg, "--rays", rays, "--hits", (dir / "x.bin").string(), "--cull", "--no-cull"}, dir);
  EXPECT_EQ(both.code, 1);
  EXPECT_FALSE(fs::exists(dir / "x.bin"));
  fs::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
