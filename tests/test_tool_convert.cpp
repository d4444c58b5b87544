// End-to-end: rtpack-convert --dry-run as a user runs it (exit codes, messages, JSON summary).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <fstream>
#include <map>

#include "gltf_builder.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

struct ToolRun {
  int code;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

ToolRun tool(const std::string& name, const std::string& args, const fs::path& dir) {
  const std::string cmd =
      std::string(RTP_BINARY_DIR) + "/" + name + " " + args + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "out"), slurp(dir / "err")};
}
ToolRun convert(const std::string& args, const fs::path& dir) { return tool("rtpack-convert", args, dir); }

class Convert : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
};

TEST_F(Convert, DryRunJsonSummary) {
  const fs::path p = source_dir() / "samples/generated/gallery.glb";
  const ToolRun r = convert("--dry-run --json " + p.string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["instances"].get<int>(), 12);
  EXPECT_EQ(j["mirrored_instances"].get<int>(), 1);
  EXPECT_EQ(j["meshes"].get<int>(), 5);
  EXPECT_EQ(j["unique_triangles"].get<uint64_t>(), 15366u);
  EXPECT_EQ(j["instanced_triangles"].get<uint64_t>(), 35540u);
  EXPECT_EQ(j["cameras"].size(), 2u);
  EXPECT_EQ(j["bounds"]["min"].size(), 3u);
  EXPECT_TRUE(j["warnings"].empty());
  EXPECT_EQ(j["preparation"]["triangles_after"].get<uint64_t>(), 15366u);
}

// OpenMesh's half-edge figures only with --topology: null without (not analysed), counts with.
TEST_F(Convert, TopologyIsAnalysedOnlyWhenAsked) {
  const fs::path p = source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf";
  const ToolRun plain = convert("--dry-run --json " + p.string(), dir);
  ASSERT_EQ(plain.code, 0) << plain.err;
  const auto a = nlohmann::json::parse(plain.out)["preparation"];
  EXPECT_TRUE(a["nonmanifold_faces"].is_null());
  EXPECT_TRUE(a["nonmanifold_vertices"].is_null());
  EXPECT_TRUE(a["boundary_edges"].is_number_unsigned());
  const ToolRun asked = convert("--dry-run --json --topology " + p.string(), dir);
  ASSERT_EQ(asked.code, 0) << asked.err;
  const auto b = nlohmann::json::parse(asked.out)["preparation"];
  EXPECT_TRUE(b["nonmanifold_faces"].is_number_unsigned());
  EXPECT_TRUE(b["nonmanifold_vertices"].is_number_unsigned());
  EXPECT_EQ(a["boundary_edges"], b["boundary_edges"]);
  const ToolRun text = convert("--dry-run --topology " + p.string(), dir);
  EXPECT_NE(text.out.find("half-edge topology"), std::string::npos) << text.out;
}

TEST_F(Convert, TextSummaryNamesCountsAndBounds) {
  const ToolRun r = convert("--dry-run " + (source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf").string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("unique triangles     5,394"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bounds min"), std::string::npos);
  EXPECT_NE(r.out.find("LanternPole_Lantern"), std::string::npos);
}

TEST_F(Convert, UniformSubdivisionQuadruples) {
  const ToolRun r =
      convert("--dry-run --json --subdivide 2 " + (source_dir() / "samples/khronos/Lantern/glTF/Lantern.gltf").string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["unique_triangles"].get<uint64_t>(), 5394u * 16u);
}

TEST_F(Convert, AdaptiveSubdivisionMeetsTarget) {
  const ToolRun r =
      convert("--dry-run --json --subdivide-to 0.5 " + (source_dir() / "samples/generated/gallery.glb").string(), dir);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const auto& per = j["preparation"]["adaptive"]["per_mesh"];
  ASSERT_EQ(per.size(), 5u);
  int refined = 0, untouched = 0;
  for (const auto& m : per) {
    EXPECT_FALSE(m["hit_cap"].get<bool>());
    EXPECT_LT(m["longest_world_edge_after"].get<double>(), 0.5);
    if (m["longest_world_edge_before"].get<double>() < 0.5) {
      EXPECT_EQ(m["levels"].get<int>(), 0);
      ++untouched;
    } else {
      EXPECT_GT(m["levels"].get<int>(), 0);
      EXPECT_EQ(m["triangles_after"].get<uint64_t>(), m["triangles_before"].get<uint64_t>() << (2 * m["levels"].get<int>()));
      ++refined;
    }
  }
  EXPECT_GT(refined, 0);
}

TEST_F(Convert, BrokenFileExitCodeAndMessage) {
  GltfBuilder b = one_triangle();
  b.j["accessors"][1]["count"] = 3;
  b.j["nodes"][0]["mesh"] = 3;
  const std::string p = b.write_glb(dir / "broken.glb");
  const ToolRun r = convert("--dry-run " + p, dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_EQ(r.err, "error: " + p + ": /nodes/0/mesh: mesh 3 out of range (1 meshes)\n");
  EXPECT_TRUE(r.out.empty());
}

TEST_F(Convert, MissingInputExitCode) {
  const ToolRun r = convert("--dry-run " + (dir / "nope.glb").string(), dir);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("no such file"), std::string::npos) << r.err;
}

TEST_F(Convert, UsageErrors) {
  const std::string p = (source_dir() / "samples/generated/gallery.glb").string();
  EXPECT_EQ(convert(p, dir).code, 1);                           // no output and no --dry-run
  EXPECT_EQ(convert("--dry-run --scene 4 " + p, dir).code, 1);  // no such scene
  EXPECT_EQ(convert("--dry-run --subdivide 1 --subdivide-to 2 " + p, dir).code, 1);
  EXPECT_EQ(convert("--bogus " + p, dir).code, 1);
  // Numbers: NaN and inf are refused (CLI11's ranges let NaN through: --subdivide-to nan was ignored), and
  // the message says what was expected.
  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"--subdivide-to nan", "--subdivide-to: expected a positive number, got nan"},
           {"--subdivide-to inf", "--subdivide-to: expected a positive number, got inf"},
           {"--threads 0", "--threads: expected a positive number, got 0"},
           {"--weld -1", "--weld: expected a number >= 0, got -1"},
           {"--weld 1e400", "--weld: expected a number >= 0, got 1e400"},
           {"--chunk-target x", "--chunk-target: expected a number from 1 to 9.0072e+15, got 'x'"},
           {"--chunk-target 99999999999999999999999",
            "--chunk-target: expected a number from 1 to 9.0072e+15, got 99999999999999999999999"}}) {
    const ToolRun r = convert("--dry-run " + args + " " + p, dir);
    EXPECT_EQ(r.code, 1) << args;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
  }
  // A uniform subdivision beyond the machine's memory is refused before any work (it used to run for
  // minutes towards the out-of-memory killer): FlightHelmet's 94,722 triangles at 8 levels are 6.2e9,
  // about 515 GiB at 89 bytes each (MeshPrepare.UniformSubdivisionBeyondMemoryIsRefused checks the
  // limit itself with a set memory size).
  {
    const std::string helmet = (source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf").string();
    const ToolRun r = convert("--subdivide 8 -o " + (dir / "h.rtp").string() + " " + helmet, dir);
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("--subdivide 8: would make 6207700992 triangles from 94722"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("of memory here; use fewer levels"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "h.rtp"));
  }
  const ToolRun spacing = tool("rtpack-make-scene", "gallery --count 2 --spacing nan -o " + (dir / "g.glb").string(), dir);
  EXPECT_EQ(spacing.code, 1);
  EXPECT_NE(spacing.err.find("--spacing: expected a number from 0.001 to 100000, got nan"), std::string::npos) << spacing.err;
  EXPECT_FALSE(fs::exists(dir / "g.glb"));
  // --seed -1 used to make the forest of seed 2^64 - 1 (CLI11 wraps negative text into a uint64_t).
  const ToolRun seed = tool("rtpack-make-scene", "forest --count 2 --seed -1 -o " + (dir / "f.glb").string(), dir);
  EXPECT_EQ(seed.code, 1);
  EXPECT_NE(seed.err.find("--seed: expected an integer from 0 to 18446744073709551615, got '-1'"), std::string::npos) << seed.err;
  EXPECT_FALSE(fs::exists(dir / "f.glb"));
}

// zstd's fast (negative) levels: a valid package, smaller than stored chunks, whose chunks decompress to
// the same bytes as level 1's (same hits for the same rays); below -7 and above 22 refused.
TEST_F(Convert, FastZstdLevels) {
  const std::string p = (source_dir() / "samples/generated/gallery.glb").string();
  std::map<int, uintmax_t> bytes;
  std::map<int, std::string> hits;
  for (const int level : {0, 1, -3}) {
    const std::string pkg = (dir / std::string("z").append(std::to_string(level)).append(".rtp")).string();
    const ToolRun c = convert("-q --zstd-level " + std::to_string(level) + " " + p + " -o " + pkg, dir);
    ASSERT_EQ(c.code, 0) << level << ": " << c.err;
    bytes[level] = fs::file_size(pkg);
    const std::string bin = std::string(RTP_BINARY_DIR) + "/";
    const fs::path rays = dir / "r.rays", out = dir / std::string("h").append(std::to_string(level)).append(".hits");
    ASSERT_EQ(std::system((bin + "rtpack-inspect --verify " + pkg + " > /dev/null").c_str()), 0) << level;
    ASSERT_EQ(std::system((bin + "rtpack-trace " + pkg + " --make-camera-rays 16x16 --rays " + rays.string() + " --hits " +
                           out.string() + " > /dev/null")
                              .c_str()),
              0)
        << level;
    hits[level] = slurp(out);
  }
  EXPECT_LT(bytes[-3], bytes[0]);
  EXPECT_LT(bytes[1], bytes[-3]);  // the fast level trades bytes for speed
  EXPECT_FALSE(hits[1].empty());
  EXPECT_EQ(hits[-3], hits[1]);
  EXPECT_EQ(hits[0], hits[1]);
  for (const char* bad : {"-8", "23"}) {
    const ToolRun r = convert(std::string("-q --zstd-level ") + bad + " " + p + " -o " + (dir / "bad.rtp").string(), dir);
    EXPECT_EQ(r.code, 1) << bad;
    EXPECT_NE(r.err.find("not in range -7 to 22"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "bad.rtp"));
  }
}

TEST_F(Convert, WarningsGoToStderr) {
  GltfBuilder b = one_triangle();
  b.j["meshes"][0]["primitives"].push_back({{"attributes", {{"POSITION", 0}}}, {"mode", 1}});
  const std::string p = b.write_gltf(dir / "w.gltf");
  ToolRun r = convert("--dry-run " + p, dir);
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.err, "warning: " + p + ": /meshes/0: 1 point/line primitives skipped\n");
  r = convert("--dry-run -q " + p, dir);
  EXPECT_TRUE(r.err.empty());
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
