// rtpack-bench as a tool: exit codes, the JSON records, and that the answers behind them were checked.
// No timing is asserted (TESTING.md: timings never go in unit tests). Skipped when the tool is not built.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "bench_run.h"
#include "package/write_package.h"
#include "trace/trace.h"

namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kTool = RTP_BINARY_DIR "/rtpack-bench";
const std::string kSamples = RTP_SOURCE_DIR "/samples";

using rtp::test::q;
using ToolRun = rtp::test::BenchRun;
inline ToolRun run(const std::string& args) { return rtp::test::run_bench(args); }

class OracleBench : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(fs::exists(kTool)) << kTool << " is not built (rtp_tests depends on it)"; }
};

TEST_F(OracleBench, ExitCodes) {
  EXPECT_EQ(run("").code, 1);
  EXPECT_EQ(run("--help").code, 0);
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --kinds nope").code, 1);
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --width 5").code, 1);
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --threads 0").code, 1);
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 0").code, 1);
  EXPECT_EQ(run("/nonexistent/scene.glb").code, 2);
  const fs::path bad = fs::temp_directory_path() / ("rtp_oracle_bench_bad_" + std::to_string(getpid()) + ".gltf");
  {
    FILE* f = std::fopen(bad.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("{\"asset\": ", f);
    std::fclose(f);
  }
  EXPECT_EQ(run(q(bad.string())).code, 3);
  fs::remove(bad);
}

TEST_F(OracleBench, JsonRecordsAreCheckedAnswers) {
  const ToolRun r = run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") +
                        " --rays 1000 --reps 1 --threads 1 "
                        "--kinds primary,shadow --json --build-stats --all");
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  ASSERT_TRUE(j.is_array());
  std::set<std::string> kinds, orders;
  std::set<int> widths;
  int builds = 0, sah = 0, primary = 0;
  for (const json& rec : j) {
    if (rec["type"] == "build") {
      ++builds;
      EXPECT_GT(rec["rtpack_build_s"].get<double>(), 0);
      EXPECT_GT(rec["embree_high_build_s"].get<double>(), 0);
      continue;
    }
    if (rec["type"] == "sah") {
      ++sah;
      EXPECT_EQ(rec["triangles"], 3936);
      EXPECT_GT(rec["sah"].get<double>(), 0);
      continue;
    }
    ASSERT_EQ(rec["type"], "trace");
    kinds.insert(rec["kind"].get<std::string>());
    orders.insert(rec["order"].get<std::string>());
    widths.insert(rec["width"].get<int>());
    // Primary rays are timed in packets of 16 (one record per width: packets walk in octant order),
    // the others one ray at a time in each order.
    const bool packets = rec["kind"] == "primary" && rec["isa"] != "scalar";
    EXPECT_EQ(rec["packet"], packets ? 16 : 0) << rec.dump();
    if (rec["kind"] == "primary") {
      ++primary;
      if (packets) {
        EXPECT_EQ(rec["order"], "octant-stack");
      }
    }
    EXPECT_EQ(rec["threads"], 1);
    EXPECT_EQ(rec["rays"], 1000);
    EXPECT_EQ(rec["query"], rec["kind"] == "shadow" ? "any" : "closest");
    EXPECT_GT(rec["rtpack_mrays"].get<double>(), 0);
    EXPECT_GT(rec["embree_mrays"].get<double>(), 0);
    EXPECT_NEAR(rec["ratio"].get<double>(), rec["rtpack_mrays"].get<double>() / rec["embree_mrays"].get<double>(), 1e-9);
    EXPECT_GT(rec["bytes_per_triangle"].get<double>(), 0);
    EXPECT_EQ(rec["failures"], 0);
    EXPECT_EQ(rec["agree"].get<uint64_t>() + rec["edge_ties"].get<uint64_t>() + rec["precision_ties"].get<uint64_t>() +
                  rec["skipped"].get<uint64_t>() + rec["embree_errors"].get<uint64_t>(),
              1000u);
  }
  EXPECT_EQ(kinds, (std::set<std::string>{"primary", "shadow"}));
  EXPECT_EQ(orders, (std::set<std::string>{"octant-stack", "active-list"}));
  EXPECT_EQ(widths, (std::set<int>{4, 8, 16}));
  EXPECT_EQ(builds, 3);
  if (j[0]["isa"] != "scalar") {
    EXPECT_EQ(primary, 3);
  }
  EXPECT_EQ(sah, 6);  // W = 4, 8, 16 x collapse, split
}

// The default run is the quick one (W=8, octant order, every kind once per thread count); --all is the sweep
// (above). The table has a header and one row per record, each labelled as an in-memory B/tri.
// --multi-hit: one record per (kind, N), node culling checked against collect-all on every ray, and
// the rays counted on which Embree's gathering filter agrees.
TEST_F(OracleBench, MultiHitRecordsAreCheckedAnswers) {
  const std::string scene = q(kSamples + "/generated/gallery.glb");
  const ToolRun r = run(scene + " --multi-hit 1,8,64 --rays 600 --reps 1 --threads 1 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  ASSERT_EQ(j["records"].size(), 6u);  // random and bounce x 3 values of N
  std::set<std::string> kinds;
  for (const json& rec : j["records"]) {
    kinds.insert(rec["kind"].get<std::string>());
    EXPECT_TRUE(rec["same_as_collect_all"].get<bool>()) << rec.dump();
    const uint64_t rays = rec["rays"].get<uint64_t>();
    EXPECT_GT(rays, 0u);
    EXPECT_GE(rec["rays_agreeing_with_embree"].get<uint64_t>() * 100, rays * 99) << rec.dump();
    for (const char* k : {"node_culling_seconds", "collect_all_seconds", "embree_gather_seconds"})
      EXPECT_GT(rec[k].get<double>(), 0.0) << k;
    EXPECT_LE(rec["hits_per_ray"].get<double>(), rec["n"].get<double>());
  }
  EXPECT_EQ(kinds, (std::set<std::string>{"random", "bounce"}));
  EXPECT_EQ(run(scene + " --multi-hit 0").code, 1);
  EXPECT_EQ(run(scene + " --multi-hit 1,65").code, 1);
  EXPECT_EQ(run(scene + " --multi-hit 4 --convert").code, 1);
}

// --out-of-core: one record per (budget, culling) run, each the best of --reps interleaved runs (after an
// untimed warm-up, so no run pays the first touch of the cache's memory alone), every answer byte-identical to
// the in-core reference, and the visits and culled visits of the run reported.
TEST_F(OracleBench, OutOfCoreRecordsAreBestOfRepsAndChecked) {
  const std::string scene = kSamples + "/generated/forest-small.glb";
  const fs::path pkg = fs::temp_directory_path() / ("rtp_oracle_bench_ooc_" + std::to_string(getpid()) + ".rtp");
  const std::string convert = std::string(RTP_BINARY_DIR "/rtpack-convert") + " -q " + q(scene) + " -o " + q(pkg.string());
  ASSERT_EQ(std::system(convert.c_str()), 0) << convert;
  const ToolRun r = run(q(scene) + " --out-of-core " + q(pkg.string()) +
                        " --budgets 100,75 --kinds random,bounce --rays 2000 --reps 2 --threads 1 --json");
  fs::remove(pkg);
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  EXPECT_EQ(j.value("schema_version", 0), 3);
  size_t in_core = 0, ooc = 0;
  std::set<std::pair<double, bool>> runs;
  for (const json& rec : j["records"]) {
    if (rec["mode"] == "in_core") {
      ++in_core;
      EXPECT_GT(rec["seconds"].get<double>(), 0.0);
      continue;
    }
    ++ooc;
    runs.insert({rec["budget_percent"].get<double>(), rec["cull"].get<bool>()});
    EXPECT_EQ(rec["reps"].get<int>(), 2) << rec.dump();
    EXPECT_TRUE(rec["identical_to_in_core"].get<bool>()) << rec.dump();
    EXPECT_GT(rec["point_visits"].get<uint64_t>(), 0u) << rec.dump();
    EXPECT_LE(rec["culled_visits"].get<uint64_t>(), rec["point_visits"].get<uint64_t>());
    if (!rec["cull"].get<bool>()) {
      EXPECT_EQ(rec["culled_visits"].get<uint64_t>(), 0u) << rec.dump();
    }
    EXPECT_GT(rec["chunks_loaded"].get<uint64_t>(), 0u);
  }
  EXPECT_EQ(in_core, 2u);
  EXPECT_EQ(ooc, 8u);  // 2 kinds x 2 budgets x culling on and off
  EXPECT_EQ(runs.size(), 4u);
}

// --kinds path: the path workload at each budget with culling on and off, every image equal to the in-core
// render (else exit 4), visits and culled visits reported, Embree's time on the same paths in the run.
TEST_F(OracleBench, PathWorkloadRecordsEqualTheInCoreImage) {
  const std::string scene = kSamples + "/generated/forest-small.glb";
  const fs::path pkg = fs::temp_directory_path() / ("rtp_oracle_bench_path_" + std::to_string(getpid()) + ".rtp");
  const std::string convert =
      std::string(RTP_BINARY_DIR "/rtpack-convert") + " -q --chunk-target 2000 " + q(scene) + " -o " + q(pkg.string());
  ASSERT_EQ(std::system(convert.c_str()), 0) << convert;
  const ToolRun r = run(q(scene) + " --out-of-core " + q(pkg.string()) +
                        " --kinds path --budgets 100,20 --path-size 48x36 --paths-in-flight 256 --reps 1 --threads 1 --json");
  const ToolRun bad = run(q(scene) + " --out-of-core " + q(pkg.string()) + " --kinds path --path-size 48");
  fs::remove(pkg);
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  EXPECT_EQ(j["mode"], "path");
  EXPECT_GT(j["in_core"]["seconds"].get<double>(), 0.0);
  EXPECT_GT(j["in_core"]["rays"].get<uint64_t>(), uint64_t(48 * 36));  // camera rays and what they spawned
  EXPECT_GT(j["embree"]["seconds"].get<double>(), 0.0);
  EXPECT_LT(j["embree"]["pixels_differ"].get<uint64_t>(), uint64_t(48 * 36 / 20)) << j["embree"].dump();
  std::set<std::pair<double, bool>> runs;
  uint64_t culled = 0;
  std::map<double, uint64_t> peak;  // the most resident (tables + cache + rays) per budget
  for (const json& rec : j["records"]) {
    runs.insert({rec["budget_percent"].get<double>(), rec["cull"].get<bool>()});
    EXPECT_TRUE(rec["identical_to_in_core"].get<bool>()) << rec.dump();
    EXPECT_GT(rec["batching_point_visits"].get<uint64_t>(), 0u) << rec.dump();
    EXPECT_GT(rec["chunks_loaded"].get<uint64_t>(), 0u) << rec.dump();
    EXPECT_GT(rec["vs_embree"].get<double>(), 0.0);
    peak[rec["budget_percent"].get<double>()] =
        std::max(peak[rec["budget_percent"].get<double>()], rec["peak_resident_bytes"].get<uint64_t>());
    if (rec["cull"].get<bool>())
      culled += rec["culled_visits"].get<uint64_t>();
    else
      EXPECT_EQ(rec["culled_visits"].get<uint64_t>(), 0u) << rec.dump();
  }
  EXPECT_EQ(runs.size(), 4u);      // 2 budgets x culling on and off
  EXPECT_GT(culled, 0u);           // the forest's DAGs cull some of the queued visits
  EXPECT_LT(peak[20], peak[100]);  // the budget bounds what is resident
  EXPECT_EQ(bad.code, 1);          // --path-size without a height is a usage error
}

// --hot-rays N times each kind's first N rays over and over (the cost in instructions, data cached): the
// records say so, and the timed and checked rays are really only N distinct ones.
TEST_F(OracleBench, HotRaysRepeatTheFirstRays) {
  const std::string suzanne = q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 300 --reps 1 --threads 1 ";
  const ToolRun hot = run(suzanne + "--kinds random,shadow --hot-rays 7 --json");
  ASSERT_EQ(hot.code, 0) << hot.out;
  const ToolRun cold = run(suzanne + "--kinds random,shadow --json");
  ASSERT_EQ(cold.code, 0) << cold.out;
  for (const ToolRun* r : {&hot, &cold}) {
    const json j = json::parse(r->out);
    ASSERT_EQ(j.size(), 2u);
    for (const json& rec : j) {
      EXPECT_EQ(rec["rays"], 300);
      EXPECT_EQ(rec["failures"], 0);
      EXPECT_EQ(rec["agree"].get<uint64_t>() + rec["edge_ties"].get<uint64_t>() + rec["precision_ties"].get<uint64_t>() +
                    rec["skipped"].get<uint64_t>() + rec["embree_errors"].get<uint64_t>(),
                300u);
      if (r == &hot) {
        EXPECT_EQ(rec["hot_rays"], 7);
        EXPECT_GE(rec["distinct_rays"].get<uint64_t>(), 1u);
        EXPECT_LE(rec["distinct_rays"].get<uint64_t>(), 7u) << rec.dump();
      } else {
        EXPECT_EQ(rec["hot_rays"], 0);
        EXPECT_GT(rec["distinct_rays"].get<uint64_t>(), 250u) << rec.dump();
      }
    }
  }
  const ToolRun table = run(suzanne + "--kinds random --hot-rays 7");
  ASSERT_EQ(table.code, 0) << table.out;
  EXPECT_NE(table.out.find("hot rays: each kind's first 7 rays repeated"), std::string::npos) << table.out;
  EXPECT_EQ(run(suzanne + "--hot-rays 301").code, 1);
  EXPECT_EQ(run(suzanne + "--hot-rays 0").code, 1);
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --convert --hot-rays 4").code, 1);
}

TEST_F(OracleBench, DefaultsAreTheQuickRun) {
  const ToolRun r = run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 500 --reps 1 --threads 1 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  std::set<std::string> kinds;
  for (const json& rec : j) {
    ASSERT_EQ(rec["type"], "trace");  // no --build-stats: trace records only
    EXPECT_EQ(rec["width"], 8);
    EXPECT_EQ(rec["order"], "octant-stack");
    EXPECT_EQ(rec["threads"], 1);
    kinds.insert(rec["kind"].get<std::string>());
  }
  EXPECT_EQ(j.size(), 4u);
  EXPECT_EQ(kinds, (std::set<std::string>{"primary", "random", "bounce", "shadow"}));
  const ToolRun t = run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 500 --reps 1 --threads 1 --kinds random");
  ASSERT_EQ(t.code, 0) << t.out;
  EXPECT_NE(t.out.find("mem B/tri"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("\nrandom   closest   8 octant-stack   1 "), std::string::npos) << t.out;
  EXPECT_EQ(run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --convert --all").code, 1);
  // --primary-packet: the primary row's label says how its rays were traced; 0 = single rays.
  const std::string suzanne =
      q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 500 --reps 1 --threads 1 --kinds primary";
  if (static_cast<int>(rtp::detect_isa()) >= static_cast<int>(rtp::Isa::kAvx2)) {
    const ToolRun p16 = run(suzanne + " --isa avx2");
    ASSERT_EQ(p16.code, 0) << p16.out;
    EXPECT_NE(p16.out.find("\nprimary  closest   8 packet-16      1 "), std::string::npos) << p16.out;
  }
  const ToolRun p0 = run(suzanne + " --primary-packet 0 --json");
  ASSERT_EQ(p0.code, 0) << p0.out;
  EXPECT_EQ(json::parse(p0.out)[0]["packet"], 0);
  EXPECT_EQ(run(suzanne + " --primary-packet 3").code, 1);
}

// --convert: the tool's stdout and stderr, each into a file of `dir`; `env` is prefixed to the command.
struct FullRun {
  int code = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  FILE* f = std::fopen(p.c_str(), "rb");
  std::string s;
  if (!f) return s;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), f)) > 0) s.append(buf.data(), n);
  std::fclose(f);
  return s;
}

FullRun run_full(const std::string& tool, const std::string& args, const fs::path& dir, const std::string& env = "") {
  std::string cmd = env;
  cmd += " ";
  cmd += q(tool);
  cmd += " ";
  cmd += args;
  cmd += " > ";
  cmd += q((dir / "stdout").string());
  cmd += " 2> ";
  cmd += q((dir / "stderr").string());
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "stdout"), slurp(dir / "stderr")};
}

class ConvertBench : public OracleBench {
 protected:
  fs::path dir;
  void SetUp() override {
    OracleBench::SetUp();
    dir = fs::temp_directory_path() / ("rtp_convert_bench_" + std::to_string(getpid()) + "_" +
                                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir / "tmp");
  }
  void TearDown() override { fs::remove_all(dir); }
};

// The record is structurally complete and true: the package it measured is the one rtpack-convert
// writes (byte for byte), its sections add up to the file, every time was measured (> 0).
TEST_F(ConvertBench, RecordDescribesTheConvertersPackage) {
  const std::string gallery = kSamples + "/generated/gallery.glb";
  const std::string convert_tool = RTP_BINARY_DIR "/rtpack-convert";
  ASSERT_TRUE(fs::exists(convert_tool));

  // 1. Default run: the package goes to a temporary file in $TMPDIR, deleted afterwards.
  const FullRun a = run_full(kTool, q(gallery) + " --convert --reps 1 --json", dir, "TMPDIR=" + q((dir / "tmp").string()));
  ASSERT_EQ(a.code, 0) << a.err;
  EXPECT_TRUE(fs::is_empty(dir / "tmp")) << "the temporary package was not deleted";
  const json ja = json::parse(a.out);
  ASSERT_TRUE(ja.is_array());
  ASSERT_EQ(ja.size(), 1u);
  const json& ra = ja[0];
  EXPECT_EQ(ra["type"], "convert");
  EXPECT_TRUE(ra["package"].is_null());
  EXPECT_EQ(ra["threads"], ra["hardware_threads"]);

  // 2. The same with --convert-output (kept) and one thread.
  const fs::path kept = dir / "bench.rtp";
  const FullRun b =
      run_full(kTool, q(gallery) + " --convert --reps 1 --json --threads 1 --convert-output " + q(kept.string()), dir);
  ASSERT_EQ(b.code, 0) << b.err;
  const json r = json::parse(b.out).at(0);
  ASSERT_TRUE(fs::exists(kept));
  EXPECT_EQ(r["package"], kept.string());
  EXPECT_EQ(r["threads"], 1);
  EXPECT_EQ(r["reps"], 1);
  EXPECT_EQ(r["scene"], gallery);
  EXPECT_EQ(r["input_bytes"].get<uint64_t>(), fs::file_size(gallery));
  EXPECT_EQ(r["input_total_bytes"], r["input_bytes"]);  // a .glb names no external file
  const uint64_t package_bytes = r["package_bytes"].get<uint64_t>();
  EXPECT_EQ(package_bytes, fs::file_size(kept));
  EXPECT_EQ(package_bytes, ra["package_bytes"].get<uint64_t>());  // same bytes for any thread count

  // 3. rtpack-convert with the same (default) options writes exactly the same file.
  const fs::path tool_out = dir / "tool.rtp";
  const FullRun c = run_full(convert_tool, q(gallery) + " -o " + q(tool_out.string()) + " --json", dir);
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_EQ(slurp(kept), slurp(tool_out)) << "rtpack-bench --convert and rtpack-convert wrote different packages";
  const json tool = json::parse(c.out);
  EXPECT_EQ(tool["package_bytes"].get<uint64_t>(), package_bytes);  // the whole file, TOC included
  EXPECT_EQ(tool["chunks"], r["chunks"]);
  EXPECT_EQ(tool["unique_triangles"], r["unique_triangles"]);
  EXPECT_EQ(tool["instanced_triangles"], r["instanced_triangles"]);
  EXPECT_EQ(r["instances"], 12);  // samples/generated/gallery.glb: 12 mesh nodes
  EXPECT_EQ(tool["batching_points"], r["batching_points"]);
  EXPECT_EQ(tool["mesh_segments"], r["mesh_segments"]);
  EXPECT_EQ(tool["chunk_target"], r["chunk_target"]);

  // Triangles and chunks.
  const uint64_t unique = r["unique_triangles"].get<uint64_t>(), chunks = r["chunks"].get<uint64_t>();
  EXPECT_GT(unique, 0u);
  EXPECT_GE(r["instanced_triangles"].get<uint64_t>(), unique);
  EXPECT_GT(chunks, 0u);
  EXPECT_EQ(r["bvh_width"], 8);
  EXPECT_EQ(r["leaf_width"], 8);
  EXPECT_EQ(r["zstd_level"], rtp::kDefaultZstdLevel);  // rtpack-convert's default

  // Sections: the chunks' stored bytes; the container (4 KiB header, TOC, alignment padding) is the rest.
  uint64_t stored = 0, section_chunks = 0;
  ASSERT_TRUE(r["sections"].is_object());
  ASSERT_FALSE(r["sections"].empty());
  for (const auto& [kind, s] : r["sections"].items()) {
    SCOPED_TRACE(kind);
    EXPECT_GT(s["stored_bytes"].get<uint64_t>(), 0u);
    EXPECT_GT(s["raw_bytes"].get<uint64_t>(), 0u);
    EXPECT_EQ(s["stored_bytes"], tool["sections"][kind]["stored_bytes"]);
    EXPECT_NEAR(s["bytes_per_unique_triangle"].get<double>(), double(s["stored_bytes"].get<uint64_t>()) / double(unique), 1e-9);
    stored += s["stored_bytes"].get<uint64_t>();
    section_chunks += s["chunks"].get<uint64_t>();
  }
  EXPECT_EQ(section_chunks, chunks);
  EXPECT_EQ(r["sections_stored_bytes"].get<uint64_t>(), stored);
  EXPECT_LE(stored, package_bytes);
  EXPECT_LT(package_bytes - stored, 4096 * (chunks + 2));
  EXPECT_EQ(r["container_bytes"].get<uint64_t>(), package_bytes - stored);
  EXPECT_NEAR(r["bytes_per_unique_triangle"].get<double>(), double(package_bytes) / double(unique), 1e-9);

  // Every time was measured; the ratios are the quotients of the printed times (never asserted on).
  const json& sec = r["seconds"];
  for (const char* stage : {"import", "prepare", "plan", "chunks"}) EXPECT_GT(sec[stage].get<double>(), 0) << stage;
  const double sum =
      sec["import"].get<double>() + sec["prepare"].get<double>() + sec["plan"].get<double>() + sec["chunks"].get<double>();
  EXPECT_NEAR(sec["total"].get<double>(), sum, 1e-9);
  EXPECT_NEAR(sec["without_import"].get<double>(), sum - sec["import"].get<double>(), 1e-9);
  const double embree = r["embree_high_build_seconds"].get<double>();
  EXPECT_GT(embree, 0);
  EXPECT_GT(r["embree_geometries"].get<uint64_t>(), 0u);
  EXPECT_NEAR(r["ratio_embree_over_convert"].get<double>(), embree / sec["total"].get<double>(), 1e-9);
  EXPECT_NEAR(r["ratio_embree_over_convert_without_import"].get<double>(), embree / sec["without_import"].get<double>(), 1e-9);
  EXPECT_NEAR(r["ratio_embree_over_chunks"].get<double>(), embree / sec["chunks"].get<double>(), 1e-9);
  EXPECT_GT(r["peak_rss_mib_convert"].get<double>(), 0);
  EXPECT_GE(r["peak_rss_mib"].get<double>(), r["peak_rss_mib_convert"].get<double>());
}

// --no-dag: the package rtpack-convert --no-dag writes (no DAG pool, smaller), said in the record, so a
// run beside the default one shows what the culling DAGs cost the convert.
TEST_F(ConvertBench, NoDagTimesTheConvertersNoDagPackage) {
  const std::string scene = kSamples + "/generated/forest-small.glb";
  const fs::path with = dir / "with.rtp", without = dir / "without.rtp", tool_out = dir / "tool.rtp";
  const std::string common = q(scene) + " --convert --reps 1 --threads 1 --json --convert-output ";
  const FullRun a = run_full(kTool, common + q(with.string()), dir);
  ASSERT_EQ(a.code, 0) << a.err;
  const json ra = json::parse(a.out).at(0);
  const FullRun b = run_full(kTool, common + q(without.string()) + " --no-dag", dir);
  ASSERT_EQ(b.code, 0) << b.err;
  const json rb = json::parse(b.out).at(0);
  EXPECT_EQ(ra["dag"], true);
  EXPECT_EQ(rb["dag"], false);
  EXPECT_TRUE(ra["sections"].contains("dag_pool")) << ra["sections"].dump();
  EXPECT_FALSE(rb["sections"].contains("dag_pool")) << rb["sections"].dump();
  EXPECT_LT(rb["package_bytes"].get<uint64_t>(), ra["package_bytes"].get<uint64_t>());
  EXPECT_EQ(rb["chunks"].get<uint64_t>() + 1, ra["chunks"].get<uint64_t>());  // the pool is one chunk
  const FullRun c = run_full(RTP_BINARY_DIR "/rtpack-convert", q(scene) + " --no-dag -q -o " + q(tool_out.string()), dir);
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_EQ(slurp(without), slurp(tool_out)) << "rtpack-bench --convert --no-dag and rtpack-convert --no-dag differ";
  EXPECT_NE(b.err.find("no culling DAGs (--no-dag)"), std::string::npos) << b.err;
  EXPECT_EQ(run(q(scene) + " --no-dag").code, 1);  // needs --convert
}

// Each repetition converts into a new file (the last one's package is removed untimed), but an output
// that is a character device is written in place and never unlinked: a device node made here (root
// only) stands for /dev/null, which a removal run as root would delete.
TEST_F(ConvertBench, RepetitionsNeverUnlinkADeviceOutput) {
  const fs::path null_dev = dir / "null";
  if (::mknod(null_dev.c_str(), S_IFCHR | 0666, ::makedev(1, 3)) != 0) GTEST_SKIP() << "mknod: " << std::strerror(errno);
  const std::string gallery = q(kSamples + "/generated/gallery.glb");
  const FullRun a = run_full(kTool, gallery + " --convert --reps 2 --threads 1 --convert-output " + q(null_dev.string()), dir);
  EXPECT_EQ(a.code, 0) << a.err;
  struct stat st {};
  ASSERT_EQ(::lstat(null_dev.c_str(), &st), 0) << "the device node is gone";
  EXPECT_TRUE(S_ISCHR(st.st_mode)) << "the device node was replaced";
  const fs::path kept = dir / "kept.rtp";  // a regular file: each repetition's is replaced, the last one stays
  const FullRun b = run_full(kTool, gallery + " --convert --reps 2 --threads 1 --convert-output " + q(kept.string()), dir);
  EXPECT_EQ(b.code, 0) << b.err;
  EXPECT_TRUE(fs::is_regular_file(kept));
}

TEST_F(ConvertBench, BadInputAndUsage) {
  const FullRun missing = run_full(kTool, q((dir / "no-such-scene.glb").string()) + " --convert --reps 1", dir);
  EXPECT_EQ(missing.code, 2);
  EXPECT_NE(missing.err.find("no-such-scene.glb"), std::string::npos) << missing.err;
  EXPECT_TRUE(fs::is_empty(dir / "tmp"));

  const std::string gallery = q(kSamples + "/generated/gallery.glb");
  const FullRun unwritable = run_full(kTool, gallery + " --convert --reps 1 --convert-output /nonexistent/dir/x.rtp", dir);
  EXPECT_EQ(unwritable.code, 4);
  EXPECT_NE(unwritable.err.find("/nonexistent/dir/x.rtp"), std::string::npos) << unwritable.err;

  EXPECT_EQ(run(gallery + " --convert-output x.rtp").code, 1);  // needs --convert
  EXPECT_EQ(run(gallery + " --zstd-level 3").code, 1);          // needs --convert
  EXPECT_EQ(run(gallery + " --convert --build-stats").code, 1);
  EXPECT_EQ(run(gallery + " --convert --rays 100").code, 1);
  EXPECT_EQ(run(gallery + " --convert --bvh-width 5").code, 1);
  EXPECT_EQ(run(gallery + " --convert --threads 0").code, 1);
}

}  // namespace RTP_UNITY_ID
}  // namespace
