// Progress and -v of rtpack-convert (issue 12): the import shows a percentage while it computes the exact
// bounds of instances, the chunks stage moves by work (triangles and instances), every progress line
// shows the same RSS measure as the summary (peak), and -v adds stage lines the default does not print.
// RTP_PROGRESS=1 makes the progress visible off a terminal, one line per update.
#include <gtest/gtest.h>

#include <regex>
#include <sstream>

#include "gltf_builder.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

class ConvertProgress : public ::testing::Test {
 protected:
  static fs::path dir, forest;
  static void SetUpTestSuite() {
    dir = temp_dir("ConvertProgress");
    forest = dir / "forest.glb";
    const ToolResult r =
        run_tool("rtpack-make-scene", {"forest", "--count", "5000", "--refine", "0", "-o", forest.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir); }
};
fs::path ConvertProgress::dir, ConvertProgress::forest;

TEST_F(ConvertProgress, ImportReportsTheBoundsOfInstancesPassByPass) {
  std::vector<std::pair<uint64_t, uint64_t>> calls;
  ImportOptions opt;
  opt.on_progress = [&](uint64_t d, uint64_t t) { calls.push_back({d, t}); };
  const Scene scene = import_gltf(forest.string(), opt);
  ASSERT_EQ(scene.instances.size(), 5000u);
  ASSERT_EQ(calls.size(), 2u);  // one step per pass over the instances, in instances' worth of work
  for (size_t i = 0; i < calls.size(); ++i) {
    EXPECT_EQ(calls[i].second, 5000u);
    EXPECT_EQ(calls[i].first, 5000u * (i + 1) / 2);
  }
  // The bounds do not depend on the progress callback: the same as without it, and the
  // brute-force reference: every vertex a triangle uses, through its instance's transform (the same double
  // arithmetic: row · v + t).
  const Scene plain = import_gltf(forest.string());
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(scene.bounds.lo[k], plain.bounds.lo[k]);
    EXPECT_EQ(scene.bounds.hi[k], plain.bounds.hi[k]);
  }
  Aabb all;
  for (const Instance& inst : scene.instances) {
    const Mesh& m = scene.meshes[inst.mesh];
    for (const uint32_t vi : m.indices) {
      const Vec3d v = to_d(m.positions[vi]);
      Vec3d w;
      for (int row = 0; row < 3; ++row)
        w[row] =
            inst.transform(row, 0) * v.x + inst.transform(row, 1) * v.y + inst.transform(row, 2) * v.z + inst.transform(row, 3);
      all.grow(w);
    }
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(all.lo[k], scene.bounds.lo[k]) << k;
    EXPECT_EQ(all.hi[k], scene.bounds.hi[k]) << k;
  }
}

TEST_F(ConvertProgress, LinesShowPeakRssAndTheChunksStageMovesByWork) {
  const ToolResult r =
      run_tool("rtpack-convert", {forest.string(), "-o", (dir / "f.rtp").string()}, dir, {"RTP_PROGRESS=1"}, 300);
  ASSERT_EQ(r.code, 0) << r.err;
  std::istringstream in(r.err);
  std::string line, stage;
  double last_pct = -1;
  bool bounds_done = false, chunks_done = false;
  size_t updates = 0;
  const std::regex upd(R"(^(.+?) +([0-9.]+)%(  ([0-9]+)/([0-9]+))?  ETA [0-9]+ s  peak RSS ([0-9]+) MiB$)");
  while (std::getline(in, line)) {
    if (line.size() > 4 && line.compare(line.size() - 4, 4, " ...") == 0) {
      stage = line.substr(0, line.size() - 4);
      last_pct = -1;
      continue;
    }
    std::smatch m;
    if (!std::regex_match(line, m, upd)) continue;
    ++updates;
    ASSERT_EQ(m[1].str(), stage) << line;
    const double pct = std::stod(m[2].str());
    EXPECT_GE(pct, last_pct) << line;  // never backwards within a stage
    last_pct = pct;
    EXPECT_GT(std::stod(m[6].str()), 0) << line;
    if (stage == "import: exact bounds of instances") {
      EXPECT_TRUE(m[3].matched) << line;  // counts: instances
      bounds_done |= m[4].str() == "5000" && m[5].str() == "5000";
    }
    if (stage == "chunks") {
      EXPECT_FALSE(m[3].matched) << line;  // work units are shown as a percentage only
      chunks_done |= pct == 100.0;
    }
  }
  EXPECT_TRUE(bounds_done) << r.err;
  EXPECT_TRUE(chunks_done) << r.err;
  EXPECT_GE(updates, 2u);
  // The summary's RSS is the same measure: "peak RSS".
  EXPECT_NE(r.out.find("peak RSS"), std::string::npos) << r.out;
}

TEST_F(ConvertProgress, VerboseAddsStageLinesAndTheDefaultDoesNot) {
  const ToolResult v =
      run_tool("rtpack-convert", {forest.string(), "-v", "--threads", "1", "-o", (dir / "v.rtp").string()}, dir, {}, 300);
  ASSERT_EQ(v.code, 0) << v.err;
  for (const char* s : {"stage import", "stage prepare", "stage batching points", "stage chunks", "peak RSS"})
    EXPECT_NE(v.err.find(s), std::string::npos) << s << "\n" << v.err;
  std::string settings = "settings: 1 threads, W=8, B=8, zstd level ";
  settings += std::to_string(kDefaultZstdLevel);
  EXPECT_NE(v.err.find(settings), std::string::npos) << settings << "\n" << v.err;
  const ToolResult d = run_tool("rtpack-convert", {forest.string(), "-o", (dir / "d.rtp").string()}, dir, {}, 300);
  ASSERT_EQ(d.code, 0) << d.err;
  EXPECT_EQ(d.err.find("stage "), std::string::npos) << d.err;
  EXPECT_EQ(d.err.find("settings:"), std::string::npos) << d.err;
  // Same package either way: -v only adds to stderr.
  EXPECT_EQ(slurp_file(dir / "v.rtp"), slurp_file(dir / "d.rtp"));
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
