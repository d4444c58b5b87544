// rtpack-bench --dag as a tool (a smoke test): its JSON records are complete and self-consistent, the
// hits with culling on were checked identical to culling off, and the package with DAGs is larger.
// No timing is asserted (TESTING.md: timings never go in unit tests).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "bench_run.h"

namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kTool = RTP_BINARY_DIR "/rtpack-bench";
const std::string kGallery = RTP_SOURCE_DIR "/samples/generated/gallery.glb";

using rtp::test::q;
using ToolRun = rtp::test::BenchRun;
inline ToolRun run(const std::string& args) { return rtp::test::run_bench(args); }

TEST(BenchDag, Usage) {
  ASSERT_TRUE(fs::exists(kTool)) << kTool << " is not built (rtp_tests depends on it)";
  EXPECT_EQ(run(q(kGallery) + " " + q(kGallery)).code, 1);          // several scenes need --dag
  EXPECT_EQ(run(q(kGallery) + " --dag --resolutions 48").code, 1);  // not a power of two
  EXPECT_EQ(run(q(kGallery) + " --dag --parts proxy,nope").code, 1);
  EXPECT_EQ(run(q(kGallery) + " --dag --convert").code, 1);
  EXPECT_EQ(run("/nonexistent/scene.glb --dag --parts convert").code, 2);
}

TEST(BenchDag, RecordsAreCompleteAndConsistent) {
  ASSERT_TRUE(fs::exists(kTool)) << kTool << " is not built (rtp_tests depends on it)";
  const ToolRun r = run(q(kGallery) + " --dag --rays 2000 --resolutions 32,64 --reps 1 --threads 1 --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  ASSERT_TRUE(j.is_array());
  std::map<std::string, int> types;
  for (const json& rec : j) ++types[rec.at("type").get<std::string>()];
  EXPECT_EQ(types["dag_model"], 1);
  EXPECT_EQ(types["dag_shared_pool"], 1);
  EXPECT_EQ(types["dag_sweep"], 4);  // 2 resolutions x {bounce, random}
  EXPECT_EQ(types["dag_convert"], 1);

  std::set<std::pair<uint32_t, std::string>> sweeps;
  for (const json& rec : j) {
    const std::string type = rec.at("type");
    EXPECT_FALSE(rec.at("cpu").get<std::string>().empty());
    if (type == "dag_model") {
      EXPECT_EQ(rec.at("resolution"), 128);
      EXPECT_EQ(rec.at("batching_points"), 1);
      const uint64_t cells = rec.at("set_cells"), svo = rec.at("svo_bytes"), dag = rec.at("dag_bytes"),
                     own = rec.at("own_pool_bytes");
      EXPECT_GT(cells, 0u);
      EXPECT_LE(cells, 128u * 128u * 128u);
      EXPECT_GT(own, 0u);
      EXPECT_LE(own, dag);  // the pool also shares nodes across levels
      EXPECT_LE(dag, svo);  // a DAG never stores more than the tree it was built from
      EXPECT_GE(rec.at("voxelize_ms").get<double>(), 0.0);
      EXPECT_EQ(rec.at("voxelize_threads"), 1);
    } else if (type == "dag_shared_pool") {
      const uint64_t alone = rec.at("alone_bytes"), shared = rec.at("shared_bytes");
      EXPECT_GT(shared, 0u);
      EXPECT_LE(shared, alone);
      EXPECT_EQ(rec.at("saving_bytes").get<int64_t>(), int64_t(alone) - int64_t(shared));
    } else if (type == "dag_sweep") {
      sweeps.insert({rec.at("resolution").get<uint32_t>(), rec.at("kind").get<std::string>()});
      EXPECT_EQ(rec.at("rays"), 2000);
      EXPECT_EQ(rec.at("hits_identical"), true);
      EXPECT_EQ(rec.at("mismatched_rays"), 0);
      const double rate = rec.at("cull_rate");
      EXPECT_GE(rate, 0.0);
      EXPECT_LE(rate, 1.0);
      const uint64_t visits = rec.at("point_visits"), culled = rec.at("culled_visits");
      EXPECT_LE(culled, visits);
      EXPECT_GT(visits, 0u);
      EXPECT_NEAR(rate, double(culled) / double(visits), 1e-12);
      // Culled points give no hit, so tfar shrinks alike and the same points are entered either way.
      EXPECT_EQ(rec.at("point_visits_no_cull").get<uint64_t>(), visits);
      const uint64_t pool = rec.at("pool_bytes");
      EXPECT_GT(pool, 0u);
      EXPECT_GT(rec.at("package_bytes").get<uint64_t>(), pool);
      EXPECT_LE(rec.at("hits").get<uint64_t>(), 2000u);
      EXPECT_GT(rec.at("hits").get<uint64_t>(), 0u) << "the rays must hit something";
      EXPECT_GT(rec.at("mrays_cull").get<double>(), 0.0);
      EXPECT_GT(rec.at("mrays_no_cull").get<double>(), 0.0);
    } else if (type == "dag_convert") {
      const uint64_t with = rec.at("package_bytes_dag"), without = rec.at("package_bytes_no_dag");
      EXPECT_GT(with, without);
      EXPECT_GT(rec.at("pool_bytes").get<uint64_t>(), 0u);
      EXPECT_GT(rec.at("pool_stored_bytes").get<uint64_t>(), 0u);
      uint64_t points = 0;
      for (const auto& [res, n] : rec.at("resolutions").items()) points += n.get<uint64_t>();
      EXPECT_EQ(points, rec.at("batching_points").get<uint64_t>());
    }
  }
  const std::set<std::pair<uint32_t, std::string>> want{{32, "bounce"}, {32, "random"}, {64, "bounce"}, {64, "random"}};
  EXPECT_EQ(sweeps, want);
}

}  // namespace RTP_UNITY_ID
}  // namespace
