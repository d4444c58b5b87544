// Conventions every rtpack tool follows: `--version`, and non-glTF input named by its magic bytes with a
// hint on how to convert it (a JSON parse error "at byte 1" tells the user nothing).
#include <gtest/gtest.h>

#include <fstream>
#include <regex>

#include "formats/package.h"
#include "reader/reader.h"
#include "gltf_builder.h"
#include "tool_run.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

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
    EXPECT_TRUE(std::regex_match(r.out, std::regex(tool + " [0-9]+\\.[0-9]+\\.[0-9]+ " + format + "\n")))
        << tool << ": '" << r.out << "'";
    EXPECT_TRUE(r.err.empty()) << tool << ": " << r.err;
  }
}

TEST_F(Conventions, NonGltfInputIsNamedWithAConversionHint) {
  const struct {
    std::string file, bytes, says;
  } cases[] = {
      {"bunny.obj", "# Blender v2.9 OBJ File\nmtllib bunny.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
       "looks like a Wavefront OBJ file"},
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
  ASSERT_EQ(
      run_tool("rtpack-convert", {(source_dir() / "samples/generated/gallery.glb").string(), "-q", "-o", pkg.string()}, dir).code,
      0);
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

TEST_F(Conventions, InputBytesAreWhatTheConverterReads) {
  // FlightHelmet.gltf: the JSON and its 3 MB .bin are read; its 15 images are named, never read (the
  // texture files are not in samples/, so they count 0 bytes).
  const fs::path helmet = source_dir() / "samples/khronos/FlightHelmet/glTF/FlightHelmet.gltf";
  const ToolResult r =
      run_tool("rtpack-convert", {helmet.string(), "--json", "-q", "-o", (dir / "h.rtp").string()}, dir, {}, 120);
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  const uint64_t gltf = fs::file_size(helmet), bin = fs::file_size(helmet.parent_path() / "FlightHelmet.bin");
  EXPECT_EQ(j["input_bytes"].get<uint64_t>(), gltf + bin);
  EXPECT_EQ(j["input_files"]["gltf_bytes"].get<uint64_t>(), gltf);
  EXPECT_EQ(j["input_files"]["buffer_bytes"].get<uint64_t>(), bin);
  EXPECT_EQ(j["input_files"]["buffer_files"].get<int>(), 1);
  EXPECT_EQ(j["input_files"]["images_not_read"].get<int>(), 15);
  EXPECT_EQ(j["input_files"]["image_file_bytes_not_read"].get<uint64_t>(), 0u);
  EXPECT_EQ(j["instances"].get<uint64_t>(), 6u);
  EXPECT_DOUBLE_EQ(j["bytes_per_instance"].get<double>(), double(j["package_bytes"].get<uint64_t>()) / 6.0);

  // A .gltf with an external buffer, an image file that exists and one that does not: the buffer is read,
  // the images are counted (the present one by its size); the summary says what was read and what not.
  GltfBuilder b = one_triangle();
  b.write_gltf_external(dir / "t.gltf", "t.bin");
  nlohmann::json d = nlohmann::json::parse(slurp_file(dir / "t.gltf"));
  // A third image names a file outside the glTF's directory: counted, never sized (its size would tell
  // the --json reader what exists there).
  const fs::path outside = dir.parent_path() / (dir.filename().string() + "-outside.png");
  std::ofstream(outside, std::ios::binary) << std::string(777, 'y');
  d["images"] =
      nlohmann::json::array({{{"uri", "tex%20a.png"}}, {{"uri", "missing.png"}}, {{"uri", "../" + outside.filename().string()}}});
  std::ofstream(dir / "t.gltf", std::ios::binary | std::ios::trunc) << d.dump();
  write("tex a.png", std::string(1234, 'x'));
  const ToolResult t =
      run_tool("rtpack-convert", {(dir / "t.gltf").string(), "--json", "-q", "-o", (dir / "t.rtp").string()}, dir);
  ASSERT_EQ(t.code, 0) << t.err;
  const auto tj = nlohmann::json::parse(t.out);
  EXPECT_EQ(tj["input_bytes"].get<uint64_t>(), fs::file_size(dir / "t.gltf") + fs::file_size(dir / "t.bin"));
  fs::remove(outside);
  EXPECT_EQ(tj["input_files"]["images_not_read"].get<int>(), 3);
  EXPECT_EQ(tj["input_files"]["image_file_bytes_not_read"].get<uint64_t>(), 1234u);
  const ToolResult text = run_tool("rtpack-convert", {(dir / "t.gltf").string(), "-o", (dir / "t.rtp").string()}, dir);
  ASSERT_EQ(text.code, 0) << text.err;
  EXPECT_NE(text.out.find(" read ("), std::string::npos) << text.out;
  EXPECT_NE(text.out.find(" glTF + 1 buffer "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("3 images not read"), std::string::npos) << text.out;
  // One triangle placed once: no bytes per instance (they would be the whole package's).
  EXPECT_NE(text.out.find("B per unique triangle, no mesh instanced)"), std::string::npos) << text.out;
  EXPECT_EQ(text.out.find("B per instance"), std::string::npos) << text.out;
  // A .glb holds its buffer: input bytes = the file.
  const fs::path glb = source_dir() / "samples/generated/gallery.glb";
  const ToolResult gt = run_tool("rtpack-convert", {glb.string(), "-o", (dir / "g.rtp").string()}, dir);
  ASSERT_EQ(gt.code, 0) << gt.err;
  EXPECT_NE(gt.out.find(" B per instance)"), std::string::npos) << "gallery places its meshes more than once: " << gt.out;
  const ToolResult g = run_tool("rtpack-convert", {glb.string(), "--json", "-q", "-o", (dir / "g.rtp").string()}, dir);
  ASSERT_EQ(g.code, 0) << g.err;
  EXPECT_EQ(nlohmann::json::parse(g.out)["input_bytes"].get<uint64_t>(), fs::file_size(glb));
  EXPECT_EQ(nlohmann::json::parse(g.out)["input_files"]["buffer_files"].get<int>(), 0);
}

// Every --json output of every tool, success or failure, carries schema_version and tool_version;
// failures are {"error": {"code", "input", "pointer", "message"}} with the exit code (docs/json.md).
TEST_F(Conventions, EveryJsonOutputCarriesTheSchemaVersion) {
  const std::string suz = (source_dir() / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string();
  const std::string pkg = (dir / "s.rtp").string(), rays = (dir / "r.rays").string(), hits = (dir / "h.hits").string();
  ASSERT_EQ(run_tool("rtpack-convert", {suz, "-q", "-o", pkg}, dir).code, 0);
  ASSERT_EQ(run_tool("rtpack-trace", {pkg, "--make-camera-rays", "8x8", "--rays", rays, "--hits", hits}, dir).code, 0);
  const struct {
    std::string tool;
    std::vector<std::string> args;
  } runs[] = {
      {"rtpack-convert", {suz, "--dry-run", "--json"}},
      {"rtpack-convert", {suz, "--json", "-o", (dir / "t.rtp").string()}},
      {"rtpack-inspect", {pkg, "--json"}},
      {"rtpack-inspect", {pkg, "--json", "--verify", "--chunks"}},
      {"rtpack-trace", {pkg, "--rays", rays, "--hits", hits, "--json"}},
      {"rtpack-trace", {pkg, "--image", (dir / "i.png").string(), "--size", "8x8", "--json"}},
      {"rtpack-bench",
       {suz, "--rays", "256", "--reps", "1", "--threads", "1", "--width", "4", "--order", "octant", "--kinds", "random",
        "--json"}},
      {"rtpack-bench", {suz, "--convert", "--reps", "1", "--threads", "1", "--json"}},
  };
  for (const auto& r : runs) {
    const ToolResult t = run_tool(r.tool, r.args, dir, {}, 120);
    ASSERT_EQ(t.code, 0) << r.tool << ": " << t.err;
    const auto j = nlohmann::json::parse(t.out);
    const std::vector<nlohmann::json> objects = j.is_array() ? std::vector<nlohmann::json>(j.begin(), j.end()) : std::vector{j};
    ASSERT_FALSE(objects.empty()) << r.tool;
    for (const auto& o : objects) {
      EXPECT_EQ(o.value("schema_version", 0), 3) << r.tool << ": " << o.dump().substr(0, 200);
      EXPECT_EQ(o.value("tool_version", "").rfind(r.tool + " ", 0), 0u) << r.tool;
    }
  }
  // Failures: a glTF error names its pointer; a package error has none; the text still goes to stderr.
  GltfBuilder b = one_triangle();
  b.j["nodes"][0]["mesh"] = 3;
  const std::string bad = b.write_glb(dir / "bad.glb");
  const ToolResult e = run_tool("rtpack-convert", {bad, "--json", "-o", (dir / "bad.rtp").string()}, dir);
  EXPECT_EQ(e.code, 3);
  const auto ej = nlohmann::json::parse(e.out);
  EXPECT_EQ(ej["schema_version"], 3);
  EXPECT_EQ(ej["error"]["code"], 3);
  EXPECT_EQ(ej["error"]["input"], bad);
  EXPECT_EQ(ej["error"]["pointer"], "/nodes/0/mesh");
  EXPECT_EQ(ej["error"]["message"], "/nodes/0/mesh: mesh 3 out of range (1 meshes)");
  EXPECT_EQ(e.err, "error: " + bad + ": /nodes/0/mesh: mesh 3 out of range (1 meshes)\n");
  const std::string trunc = write("cut.rtp", slurp_file(pkg).substr(0, 5000)).string();
  for (const std::string tool : {"rtpack-inspect", "rtpack-trace"}) {
    std::vector<std::string> args = {trunc, "--json"};
    if (tool == "rtpack-trace") args.insert(args.end(), {"--rays", rays, "--hits", (dir / "h2").string()});
    const ToolResult f = run_tool(tool, args, dir);
    EXPECT_EQ(f.code, 3) << tool << ": " << f.err;
    const auto fj = nlohmann::json::parse(f.out);
    EXPECT_EQ(fj["schema_version"], 3) << tool;
    EXPECT_EQ(fj["error"]["code"], 3) << tool;
    EXPECT_TRUE(fj["error"]["pointer"].is_null()) << tool;
    EXPECT_NE(fj["error"]["message"].get<std::string>().find("truncated"), std::string::npos) << tool << ": " << f.out;
  }
  const ToolResult m = run_tool("rtpack-bench", {(dir / "none.glb").string(), "--convert", "--json"}, dir);
  EXPECT_EQ(m.code, 2);
  EXPECT_EQ(nlohmann::json::parse(m.out)["error"]["code"], 2);
}

// Every failure under --json is an `error` envelope on stdout, whatever stage refused it (docs/json.md):
// a command line CLI11 refuses, a tool's own check of its options, and inspect --verify finding problems
// (which keeps its report beside the error). Without --json, stdout stays empty on a usage error.
TEST_F(Conventions, UsageErrorsAndFailedVerifyUnderJsonAreEnvelopes) {
  const std::string suz = (source_dir() / "samples/khronos/Suzanne/glTF/Suzanne.gltf").string();
  const std::string pkg = (dir / "s.rtp").string();
  ASSERT_EQ(run_tool("rtpack-convert", {suz, "-q", "-o", pkg}, dir).code, 0);
  const struct {
    std::string tool;
    std::vector<std::string> args;
    std::string expect;  // in error.message
  } runs[] = {
      {"rtpack-convert", {suz, "--no-such-option"}, "--no-such-option"},
      {"rtpack-convert", {suz}, "-o OUTPUT is required"},
      {"rtpack-convert", {suz, "-o", (dir / "x.rtp").string(), "--bvh-width", "4", "--leaf-width", "16"}, "not a supported pair"},
      {"rtpack-convert", {suz, "--threads"}, "--threads"},
      {"rtpack-inspect", {pkg, "--no-such-option"}, "--no-such-option"},
      {"rtpack-trace", {pkg, "--rays"}, "--rays"},
      {"rtpack-validate", {pkg, "--rays", "many"}, "many"},
      {"rtpack-bench", {suz, "--kinds", "sideways"}, "sideways"},
      {"rtpack-bench", {suz, "--width", "7"}, "--width"},
  };
  for (const auto& r : runs) {
    std::vector<std::string> with = r.args;
    with.insert(with.begin(), "--json");  // first: a value-less option at the end must not take it
    const ToolResult t = run_tool(r.tool, with, dir);
    EXPECT_EQ(t.code, 1) << r.tool << ": " << t.err;
    ASSERT_TRUE(nlohmann::json::accept(t.out)) << r.tool << " stdout: " << t.out;
    const auto j = nlohmann::json::parse(t.out);
    EXPECT_EQ(j.value("schema_version", 0), 3) << r.tool;
    EXPECT_EQ(j["error"]["code"], 1) << r.tool;
    EXPECT_NE(j["error"]["message"].get<std::string>().find(r.expect), std::string::npos) << r.tool << ": " << t.out;
    EXPECT_NE(t.err.find(r.expect), std::string::npos) << r.tool << ": the text still reaches stderr: " << t.err;
    const ToolResult plain = run_tool(r.tool, r.args, dir);
    EXPECT_EQ(plain.code, 1) << r.tool;
    EXPECT_EQ(plain.out, "") << r.tool;
  }
  EXPECT_EQ(run_tool("rtpack-inspect", {"--version", "--json"}, dir).out.find("error"), std::string::npos);

  // One flipped byte in a chunk, its checksum left alone: --verify reports it and carries the error.
  {
    const PackageReader reader(pkg);
    std::fstream f(pkg, std::ios::binary | std::ios::in | std::ios::out);
    const uint64_t at = reader.toc()[0].offset + 100;
    f.seekg(std::streamoff(at));
    const char c = char(f.get() ^ 0x5A);
    f.seekp(std::streamoff(at));
    f.put(c);
  }
  const ToolResult v = run_tool("rtpack-inspect", {pkg, "--verify", "--json"}, dir);
  EXPECT_EQ(v.code, 3) << v.err;
  const auto vj = nlohmann::json::parse(v.out);
  EXPECT_EQ(vj["error"]["code"], 3);
  EXPECT_NE(vj["error"]["message"].get<std::string>().find("checksum mismatch"), std::string::npos) << v.out;
  EXPECT_GE(vj["problems"]["count"].get<uint64_t>(), 1u);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
