// rtpack-bench as a tool: exit codes, the JSON records, and that the answers behind them were checked.
// No timing is asserted (TESTING.md: timings never go in unit tests). Skipped when the tool is not built.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kTool = RTP_BINARY_DIR "/rtpack-bench";
const std::string kSamples = RTP_SOURCE_DIR "/samples";

// Shell-quotes a path (appending, not operator+: GCC 12 warns -Wrestrict on "'" + std::string).
std::string q(const std::string& path) {
  std::string r = "'";
  r += path;
  r += "'";
  return r;
}

struct ToolRun {
  int code = -1;
  std::string out;
};

ToolRun run(const std::string& args) {
  ToolRun r;
  std::string cmd = q(kTool);
  cmd += " ";
  cmd += args;
  cmd += " 2>/dev/null";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

class OracleBench : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(fs::exists(kTool)) << kTool << " is not built (rtp_tests depends on it)";
  }
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
  { FILE* f = std::fopen(bad.c_str(), "w"); ASSERT_NE(f, nullptr); std::fputs("{\"asset\": ", f); std::fclose(f); }
  EXPECT_EQ(run(q(bad.string())).code, 3);
  fs::remove(bad);
}

TEST_F(OracleBench, JsonRecordsAreCheckedAnswers) {
  const ToolRun r = run(q(kSamples + "/khronos/Suzanne/glTF/Suzanne.gltf") + " --rays 1000 --reps 1 --threads 1 "
                    "--kinds primary,shadow --json --build-stats");
  ASSERT_EQ(r.code, 0) << r.out;
  const json j = json::parse(r.out);
  ASSERT_TRUE(j.is_array());
  std::set<std::string> kinds, orders;
  std::set<int> widths;
  int builds = 0, sah = 0;
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
    EXPECT_EQ(rec["threads"], 1);
    EXPECT_EQ(rec["rays"], 1000);
    EXPECT_EQ(rec["query"], rec["kind"] == "shadow" ? "any" : "closest");
    EXPECT_GT(rec["rtpack_mrays"].get<double>(), 0);
    EXPECT_GT(rec["embree_mrays"].get<double>(), 0);
    EXPECT_NEAR(rec["ratio"].get<double>(), rec["rtpack_mrays"].get<double>() / rec["embree_mrays"].get<double>(), 1e-9);
    EXPECT_GT(rec["bytes_per_triangle"].get<double>(), 0);
    EXPECT_EQ(rec["failures"], 0);
    EXPECT_EQ(rec["agree"].get<uint64_t>() + rec["edge_ties"].get<uint64_t>() + rec["precision_ties"].get<uint64_t>() +
                  rec["skipped"].get<uint64_t>(),
              1000u);
  }
  EXPECT_EQ(kinds, (std::set<std::string>{"primary", "shadow"}));
  EXPECT_EQ(orders, (std::set<std::string>{"octant-stack", "active-list"}));
  EXPECT_EQ(widths, (std::set<int>{4, 8, 16}));
  EXPECT_EQ(builds, 3);
  EXPECT_EQ(sah, 6);  // W = 4, 8, 16 x collapse, split
}

}  // namespace
