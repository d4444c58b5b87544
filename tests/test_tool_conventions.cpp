// Conventions every rtpack tool follows: `--version`, and non-glTF input named by its magic bytes with a
// hint on how to convert it (a JSON parse error "at byte 1" tells the user nothing).
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "formats/package.h"
#include "gltf_builder.h"
#include "tool_run.h"

namespace rtp::test {
namespace {

namespace fs = std::filesystem;

class Conventions : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
  fs::path write(const std::string& name, const std::string& bytes) {
    std::ofstream(dir / name, std::ios::binary) << bytes;
    return dir / name;
  }
};

TEST_F(Conventions, EveryToolAnswersVersion) {
  const std::string format =
      "\\(package format " + std::to_string(fmt::kVersionMajor) + "\\." + std::to_string(fmt::kVersionMinor) + "\\)";
  for (const std::string tool : {"rtpack-convert", "rtpack-inspect", "rtpack-trace", "rtpack-bench", "rtpack-make-scene"}) {
    const ToolResult r = run_tool(tool, {"--version"}, dir);
    EXPECT_EQ(r.code, 0) << tool << ": " << r.err;
    EXPECT_TRUE(std::regex_match(r.out, std::regex(tool + " [0-9]+\\.[0-9]+\\.[0-9]+ " + format + "\n"))) << tool << ": '" << r.out << "'";
    EXPECT_TRUE(r.err.empty()) << tool << ": " << r.err;
  }
}

TEST_F(Conventions, NonGltfInputIsNamedWithAConversionHint) {
  const struct {
    std::string file, bytes, says;
  } cases[] = {
      {"bunny.obj", "# Blender v2.9 OBJ File\nmtllib bunny.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "looks like a Wavefront OBJ file"},
      {"plain.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "looks like a Wavefront OBJ file"},
      {"model.fbx", std::string("Kaydara FBX Binary  \0\x1a\0", 23), "looks like an FBX file"},
      {"scan.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 3\n", "looks like a PLY file"},
      {"part.stl", "solid part\n facet normal 0 0 1\n", "looks like an ASCII STL file"},
      {"scene.usdz", std::string("PK\x03\x04\x14\0\0\0", 8), "looks like a ZIP archive"},
      {"scene.dae", "<?xml version=\"1.0\"?>\n<COLLADA xmlns=\"http://www.collada.org\">", "looks like a COLLADA (.dae) file"},
      {"scene.gltf.zst", std::string("\x28\xb5\x2f\xfd\x20\x10", 6), "looks like a zstd-compressed file"},
      {"noise.glb", std::string("\x01\x02\x03\x04\xfe\xff\x00\x7f\x55", 9), "first bytes: 01 02 03 04 fe ff 00 7f"},
  };
  for (const auto& c : cases) {
    const fs::path in = write(c.file, c.bytes), out = dir / "out.rtp";
    const ToolResult r = run_tool("rtpack-convert", {in.string(), "-o", out.string()}, dir);
    EXPECT_EQ(r.code, 3) << c.file << ": " << r.err;
    EXPECT_NE(r.err.find(in.string() + ": not a glTF file"), std::string::npos) << c.file << ": " << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.file << ": " << r.err;
    EXPECT_NE(r.err.find("assimp export"), std::string::npos) << c.file << ": " << r.err;
    EXPECT_EQ(r.err.find("invalid JSON"), std::string::npos) << c.file << ": " << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.file;
  }
  // A package given as input is named as one.
  const fs::path pkg = dir / "g.rtp";
  ASSERT_EQ(run_tool("rtpack-convert", {(source_dir() / "samples/generated/gallery.glb").string(), "-q", "-o", pkg.string()}, dir).code, 0);
  const ToolResult r = run_tool("rtpack-convert", {pkg.string(), "--dry-run"}, dir);
  EXPECT_EQ(r.code, 3);
  EXPECT_NE(r.err.find("an rtpack package (.rtp): it is already converted"), std::string::npos) << r.err;
}

TEST_F(Conventions, JsonTextStillReachesTheParser) {
  // White space before the JSON object is valid glTF; broken JSON is still reported by byte.
  GltfBuilder b = one_triangle();
  const fs::path good = b.write_gltf(dir / "t.gltf");
  const std::string text = slurp_file(good);
  const fs::path spaced = write("spaced.gltf", "\n \t\r\n" + text);
  const ToolResult ok = run_tool("rtpack-convert", {spaced.string(), "--dry-run"}, dir);
  EXPECT_EQ(ok.code, 0) << ok.err;
  const fs::path broken = write("broken.gltf", "[1, 2");
  const ToolResult bad = run_tool("rtpack-convert", {broken.string(), "--dry-run"}, dir);
  EXPECT_EQ(bad.code, 3);
  EXPECT_NE(bad.err.find("invalid JSON (truncated file?)"), std::string::npos) << bad.err;
  const fs::path empty = write("empty.gltf", "");
  const ToolResult none = run_tool("rtpack-convert", {empty.string(), "--dry-run"}, dir);
  EXPECT_EQ(none.code, 3);
  EXPECT_EQ(none.err.find("not a glTF file"), std::string::npos) << none.err;
}

}  // namespace
}  // namespace rtp::test
