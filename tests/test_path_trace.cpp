// rtpack-trace --path-trace (issue 54): a path tracer on the streaming API gives the same PNG bytes in
// core and at budgets of 100 %, 25 % and 5 %, on 1 and 2 threads, with culling on and off; the image is
// a picture (hits shaded, not all sky) that depends on the seed; the report counts what it did, wave by
// wave; its peak RSS at a small budget stays below the in-core render's; usage errors exit 1 and a
// failed render leaves no PNG.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "gltf_builder.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

std::string read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

class PathTrace : public ::testing::Test {
 protected:
  static fs::path dir, package;
  static void SetUpTestSuite() {
    dir = temp_dir("PathTrace");
    const fs::path glb = dir / "forest.glb";
    package = dir / "forest.rtp";
    ToolResult r = run_tool("rtpack-make-scene", {"forest", "--unique", "--count", "40", "-o", glb.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
    r = run_tool("rtpack-convert", {glb.string(), "-q", "--chunk-target", "20000", "-o", package.string()}, dir);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  static void TearDownTestSuite() { fs::remove_all(dir); }

  // Renders with `extra` options; returns the JSON report and the PNG's bytes.
  static std::pair<nlohmann::json, std::string> render(const std::string& name, std::vector<std::string> extra) {
    const fs::path png = dir / (name + ".png");
    std::vector<std::string> args = {
        package.string(),    "--path-trace", png.string(), "--size", "160x120", "--spp", "2", "--bounces", "2",
        "--paths-in-flight", "8192",         "--json"};
    args.insert(args.end(), extra.begin(), extra.end());
    const ToolResult r = run_tool("rtpack-trace", args, dir, {}, 120);
    EXPECT_EQ(r.code, 0) << name << ": " << r.err;
    if (r.code != 0) return {};
    return {nlohmann::json::parse(r.out), read_bytes(png)};
  }
};
fs::path PathTrace::dir, PathTrace::package;

TEST_F(PathTrace, SameImageBytesForEveryBudgetThreadCountAndCulling) {
  const auto [in_core, want] = render("in_core", {});
  ASSERT_FALSE(want.empty());
  EXPECT_FALSE(in_core["out_of_core"].get<bool>());
  EXPECT_EQ(in_core["paths"].get<uint64_t>(), 160u * 120u * 2u);
  EXPECT_EQ(in_core["waves"].size(), 5u);  // 38,400 paths, 8,192 at a time
  EXPECT_GT(in_core["total"]["rays"].get<uint64_t>(), in_core["paths"].get<uint64_t>()) << "no bounce or shadow rays";
  uint64_t loads_at_5 = 0;
  for (int percent : {100, 25, 5})
    for (int threads : {1, 2})
      for (bool cull : {true, false}) {
        std::vector<std::string> extra = {"--memory-budget", std::to_string(percent) + "%", "--threads", std::to_string(threads)};
        if (!cull) extra.push_back("--no-cull");
        const std::string name = "b" + std::to_string(percent) + "_t" + std::to_string(threads) + (cull ? "_cull" : "_nocull");
        const auto [j, png] = render(name, extra);
        ASSERT_TRUE(j.is_object()) << name;
        EXPECT_TRUE(j["out_of_core"].get<bool>()) << name;
        EXPECT_EQ(j["total"]["rays"], in_core["total"]["rays"]) << name << ": the paths took other rays";
        EXPECT_TRUE(png == want) << name << ": the image differs from the in-core render";
        if (cull) {
          EXPECT_GT(j["total"]["culled_visits"].get<uint64_t>(), 0u) << name;
        } else {
          EXPECT_EQ(j["total"]["culled_visits"].get<uint64_t>(), 0u) << name;
        }
        if (percent == 5 && cull) loads_at_5 = j["total"]["chunks_loaded"].get<uint64_t>();
      }
  EXPECT_GT(loads_at_5, 0u);
  // Refilled paths (a new path whenever one ends, one flush): the same paths, the same rays, the same image.
  for (const char* budget : {"100%", "5%"}) {
    const auto [j, png] =
        render(std::string("refill_") + (budget[0] == '1' ? "100" : "5"), {"--refill", "--memory-budget", budget});
    ASSERT_TRUE(j.is_object()) << budget;
    EXPECT_TRUE(j["refill"].get<bool>());
    EXPECT_EQ(j["waves"].size(), 1u) << budget << ": a refilled render is one flush";
    EXPECT_EQ(j["total"]["rays"], in_core["total"]["rays"]) << budget;
    EXPECT_TRUE(png == want) << budget << ": the refilled image differs from the in-core render";
  }
}

TEST_F(PathTrace, TheImageIsAPictureThatDependsOnTheSeed) {
  const auto [a, png_a] = render("seed1", {"--seed", "1"});
  const auto [b, png_b] = render("seed2", {"--seed", "2"});
  ASSERT_FALSE(png_a.empty());
  EXPECT_NE(png_a, png_b) << "the seed changed nothing";
  // Primary rays hit (the trees fill a part of the camera's view), and shadow rays and bounces follow.
  const nlohmann::json& t = a["total"];
  EXPECT_GT(t["batching_point_visits"].get<uint64_t>(), 1000u);
  EXPECT_GT(t["rays"].get<uint64_t>(), a["paths"].get<uint64_t>() + 1000u);
}

TEST_F(PathTrace, UsageErrorsAndAFailedRenderLeaveNoImage) {
  const fs::path png = dir / "never.png";
  ToolResult r = run_tool("rtpack-trace", {package.string(), "--path-trace", png.string(), "--any"}, dir);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("--any"), std::string::npos) << r.err;
  r = run_tool("rtpack-trace", {package.string(), "--image", png.string(), "--spp", "4"}, dir);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("--path-trace"), std::string::npos) << r.err;
  r = run_tool("rtpack-trace", {package.string(), "--path-trace", png.string(), "--memory-budget", "1000"}, dir);
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("minimum"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("internal"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(png));
}

TEST_F(PathTrace, ASmallBudgetHoldsLessThanInCore) {
  const fs::path png = dir / "rss.png";
  const std::vector<std::string> common = {package.string(), "--path-trace", png.string(), "--size", "160x120", "--json"};
  std::vector<std::string> small = common;
  small.insert(small.end(), {"--memory-budget", "5%"});
  const ToolResult in_core = run_tool("rtpack-trace", common, dir, {}, 120);
  const ToolResult ooc = run_tool("rtpack-trace", small, dir, {}, 120);
  ASSERT_EQ(in_core.code, 0) << in_core.err;
  ASSERT_EQ(ooc.code, 0) << ooc.err;
  const nlohmann::json j = nlohmann::json::parse(ooc.out);
  EXPECT_LT(j["total"]["peak_resident_bytes"].get<uint64_t>(), j["geometry_bytes"].get<uint64_t>());
  if (in_core.max_rss_kib > 0 && ooc.max_rss_kib > 0) {
    EXPECT_LT(ooc.max_rss_kib, in_core.max_rss_kib);
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
