// Hostile glTF values, codecs, depth and declared sizes (issue 10): each case must end in exit 3 with
// a message that starts with (or names) the JSON pointer of the offending value, and the codec where
// one is involved, never an internal error, a crash or an allocation the file does not back.
// Cases that crashed or allocated gigabytes before are run as subprocesses of the tools (a crash or an
// out-of-memory then fails the test instead of killing the test binary).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/json_checked.h"
#include "gltf_builder.h"
#include "package_patch.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

struct ToolRun {
  int code;  // exit code, or -signal
  std::string err;
};

// Runs `tool args` (stderr captured), optionally under an address-space limit (KiB) so an allocation
// the file does not back fails fast instead of using the machine's memory.
ToolRun run_tool(const std::string& tool, const std::string& args, const fs::path& dir, long limit_kib = 0) {
  std::string cmd;
#if !defined(RTP_SANITIZED_BUILD)
  if (limit_kib) cmd = "ulimit -v " + std::to_string(limit_kib) + "; ";
#else
  (void)limit_kib;  // ASan reserves terabytes of address space: no limit there
#endif
  cmd += std::string(RTP_BINARY_DIR) + "/" + tool + " " + args + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return {code, slurp(dir / "err")};
}

std::pair<std::string, ExitCode> import_error(const std::string& path) {
  try {
    import_gltf(path);
  } catch (const Error& e) {
    return {e.what(), e.code()};
  }
  ADD_FAILURE() << path << " was accepted";
  return {"", ExitCode::kOk};
}

// A .gltf whose buffers are given explicitly (buffer 0: the builder's data as a data URI). Pass
// nlohmann::json::array({...}): a braced {one_json} is that json itself under clang (CWG 2137), an
// array of it under GCC.
std::string write_with_buffers(GltfBuilder& b, const nlohmann::json& extra_buffers, const fs::path& p) {
  nlohmann::json d = b.j;
  d["buffers"] =
      nlohmann::json::array({{{"byteLength", b.bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(b.bin)}}});
  for (const auto& x : extra_buffers) d["buffers"].push_back(x);
  std::ofstream(p, std::ios::binary) << d.dump();
  return p.string();
}

// One triangle whose POSITION view is EXT_meshopt_compression-compressed into fallback buffer 1; the
// "compressed" bytes are buffer 0's raw floats (not meshopt data).
GltfBuilder meshopt_triangle() {
  GltfBuilder b = one_triangle();
  b.j["bufferViews"][0]["buffer"] = 1;
  b.j["bufferViews"][0]["byteOffset"] = 0;
  b.j["bufferViews"][0]["extensions"]["EXT_meshopt_compression"] = {
      {"buffer", 0}, {"byteOffset", 0}, {"byteLength", 36}, {"byteStride", 12}, {"count", 3}, {"mode", "ATTRIBUTES"}};
  return b;
}
const nlohmann::json kFallback = {{"byteLength", 36}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}};

class HostileGltf : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }

  // Exit 3 and the exact message, from the .gltf and from the same document as .glb.
  void expect(GltfBuilder b, const std::string& message) {
    const auto [msg, code] = import_error(b.write_gltf(dir / "t.gltf"));
    EXPECT_EQ(msg, message);
    EXPECT_EQ(code, ExitCode::kInputInvalid);
    const auto [msg2, code2] = import_error(b.write_glb(dir / "t.glb"));
    EXPECT_EQ(msg2, message);
    EXPECT_EQ(code2, ExitCode::kInputInvalid);
  }
  void expect_file(const std::string& path, const std::string& message) {
    const auto [msg, code] = import_error(path);
    EXPECT_EQ(msg, message);
    EXPECT_EQ(code, ExitCode::kInputInvalid);
  }
  // rtpack-convert --dry-run exits 3 and its message contains every one of `parts`.
  void expect_convert(const std::string& input, const std::vector<std::string>& parts, long limit_kib = 0) {
    const ToolRun r = run_tool("rtpack-convert", "--dry-run -q " + input, dir, limit_kib);
    EXPECT_EQ(r.code, 3) << r.err;
    for (const auto& p : parts) EXPECT_NE(r.err.find(p), std::string::npos) << "missing '" << p << "' in: " << r.err;
  }
};

// --- malformed JSON values: exit 3 with the pointer, never nlohmann's type_error --------------------

TEST_F(HostileGltf, PrimitiveModeIsAString) {
  GltfBuilder b = one_triangle();
  b.j["meshes"][0]["primitives"][0]["mode"] = "4";
  expect(b, "/meshes/0/primitives/0/mode: not an integer");
}

TEST_F(HostileGltf, SparseIndicesComponentTypeIsAString) {
  GltfBuilder b = one_triangle();
  const int iv = b.add_view(std::vector<uint16_t>{1, 0});
  const int vv = b.add_view(std::vector<float>{9, 9, 9});
  b.j["accessors"][0]["sparse"] = {
      {"count", 1}, {"indices", {{"bufferView", iv}, {"componentType", "5123"}}}, {"values", {{"bufferView", vv}}}};
  expect(b, "/accessors/0/sparse/indices/componentType: not an integer");
}

TEST_F(HostileGltf, CameraTypeIsANumber) {
  GltfBuilder b = one_triangle();
  b.j["cameras"] = {{{"type", 1}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}}};
  expect(b, "/cameras/0/type: not a string");
}

TEST_F(HostileGltf, PerspectiveCameraWithoutYfov) {
  GltfBuilder b = one_triangle();
  b.j["cameras"] = {{{"type", "perspective"}, {"perspective", {{"znear", 0.1}}}}};
  expect(b, "/cameras/0/perspective/yfov: missing");
}

TEST_F(HostileGltf, MeshoptModeIsNotAString) {
  GltfBuilder b = meshopt_triangle();
  b.j["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["mode"] = 0;
  expect_file(write_with_buffers(b, nlohmann::json::array({kFallback}), dir / "t.gltf"),
              "/bufferViews/0/extensions/EXT_meshopt_compression/mode: not a string");
}

TEST_F(HostileGltf, MeshoptByteLengthMissing) {
  GltfBuilder b = meshopt_triangle();
  b.j["bufferViews"][0]["extensions"]["EXT_meshopt_compression"].erase("byteLength");
  expect_file(write_with_buffers(b, nlohmann::json::array({kFallback}), dir / "t.gltf"),
              "/bufferViews/0/extensions/EXT_meshopt_compression/byteLength: missing");
}

TEST_F(HostileGltf, MeshoptFallbackIsNotABoolean) {
  GltfBuilder b = meshopt_triangle();
  nlohmann::json fb = kFallback;
  fb["extensions"]["EXT_meshopt_compression"]["fallback"] = "yes";
  expect_file(write_with_buffers(b, nlohmann::json::array({fb}), dir / "t.gltf"),
              "/buffers/1/extensions/EXT_meshopt_compression/fallback: not a boolean");
}

// --- codecs -----------------------------------------------------------------------------------------

TEST_F(HostileGltf, MeshoptCorruptDataNamesTheBufferView) {
  GltfBuilder b = meshopt_triangle();  // raw floats are not a meshopt vertex stream
  const auto [msg, code] = import_error(write_with_buffers(b, nlohmann::json::array({kFallback}), dir / "t.gltf"));
  EXPECT_EQ(code, ExitCode::kInputInvalid);
  EXPECT_EQ(msg.rfind("/bufferViews/0/extensions/EXT_meshopt_compression: meshopt decoding failed", 0), 0u) << msg;
}

// A copy of the Draco Lantern with `edit` applied to its JSON and `edit_bin` to its buffer.
std::string draco_lantern(const fs::path& dir, const std::function<void(nlohmann::json&)>& edit,
                          const std::function<void(std::string&)>& edit_bin = nullptr) {
  const fs::path src = source_dir() / "samples/khronos/Lantern/glTF-Draco";
  nlohmann::json j = nlohmann::json::parse(slurp(src / "Lantern.gltf"));
  edit(j);
  std::ofstream(dir / "Lantern.gltf", std::ios::binary) << j.dump();
  std::string bin = slurp(src / "Lantern.bin");
  if (edit_bin) edit_bin(bin);
  std::ofstream(dir / "Lantern.bin", std::ios::binary) << bin;
  return (dir / "Lantern.gltf").string();
}

TEST_F(HostileGltf, DracoAttributeIdNotInThePayload) {
  const std::string p = draco_lantern(dir, [](nlohmann::json& j) {
    j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["POSITION"] = 99;
  });
  expect_convert(p, {"/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression/attributes/POSITION: "
                     "Draco attribute id 99 is not in the payload"});
}

TEST_F(HostileGltf, DracoCorruptPayloadNamesThePrimitive) {
  const std::string p = draco_lantern(
      dir, [](nlohmann::json&) {},
      [](std::string& bin) {
        for (size_t i = 0; i < 64; ++i) bin[i] = char(0xA5);  // mesh 0's Draco payload starts at byte 0
      });
  expect_convert(p, {"/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression: Draco decode failed"});
}

TEST_F(HostileGltf, DracoAttributeWithWrongComponentCount) {
  const std::string p = draco_lantern(dir, [](nlohmann::json& j) {
    auto& d = j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"];
    d["POSITION"] = d["TEXCOORD_0"];  // a 2-component attribute for a VEC3 accessor
  });
  expect_convert(p, {"/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression/attributes/POSITION: Draco "
                     "attribute 0 has 2 components but accessor 4 has 3"});
}

// --- depth ------------------------------------------------------------------------------------------

TEST_F(HostileGltf, DeeplyNestedJsonIsRejectedBeforeParsing) {
  GltfBuilder b = one_triangle();
  const std::string gltf = b.write_gltf(dir / "ok.gltf");
  std::string text = slurp(gltf);
  const std::string deep = "\"extras\":" + std::string(20000, '[') + std::string(20000, ']') + ",";
  text.insert(1, deep);
  std::ofstream(dir / "deep.gltf", std::ios::binary) << text;
  expect_convert((dir / "deep.gltf").string(), {"JSON nested more than 256 levels deep"});
}

TEST_F(HostileGltf, BracketsInsideStringsDoNotCountAsNesting) {
  GltfBuilder b = one_triangle();
  // 1000 brackets inside strings, one of them behind an escaped quote: not nesting.
  b.j["asset"]["extras"] = {{"a", std::string(1000, '[')}, {"b", "\"" + std::string(1000, '{') + "\\"}};
  b.j["asset"]["extras"]["c"] = nlohmann::json::array({nlohmann::json::array({nlohmann::json::array()})});
  EXPECT_NO_THROW(import_gltf(b.write_gltf(dir / "t.gltf")));
  EXPECT_NO_THROW(jsonc::check_depth(std::string(jsonc::kMaxJsonDepth, '[') + std::string(jsonc::kMaxJsonDepth, ']'), ""));
  EXPECT_THROW(jsonc::check_depth(std::string(jsonc::kMaxJsonDepth + 1, '{'), ""), Error);
}

// --- declared sizes before allocation ----------------------------------------------------------------

TEST_F(HostileGltf, AccessorWithoutBufferViewIsBounded) {
  GltfBuilder b = one_triangle();
  b.j["accessors"][0].erase("bufferView");
  b.j["accessors"][0]["count"] = 100000000;  // 1.2 GB of zeros (3.4 GB as read) from a 1 KB file
  b.j["meshes"][0]["primitives"][0].erase("indices");
  expect_convert(b.write_gltf(dir / "t.gltf"), {"/accessors/0/count: 100000000 elements without a bufferView"}, 1000000);
}

TEST_F(HostileGltf, IndicesAccessorWithoutBufferViewNamesThePrimitive) {  // was tinygltf's "accessor[1] invalid bufferView"
  GltfBuilder b = one_triangle();
  const auto ia = b.j["meshes"][0]["primitives"][0]["indices"].get<size_t>();
  b.j["accessors"][ia].erase("bufferView");
  expect(b, "/meshes/0/primitives/0/indices: accessor " + std::to_string(ia) +
                " has no bufferView (indices must be stored in a buffer; all-zero indices make no triangle)");
}

TEST_F(HostileGltf, MeshoptDeclaredSizeBeyondTheCodecsExpansion) {
  GltfBuilder b = meshopt_triangle();
  const uint64_t count = uint64_t(1) << 28;  // 3 GiB decoded from 36 compressed bytes
  b.j["bufferViews"][0]["byteLength"] = 12 * count;
  b.j["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]["count"] = count;
  nlohmann::json fb = kFallback;
  fb["byteLength"] = 12 * count;
  expect_convert(write_with_buffers(b, nlohmann::json::array({fb}), dir / "t.gltf"),
                 {"/bufferViews/0/extensions/EXT_meshopt_compression: meshopt cannot decode 3221225472 bytes from 36"}, 1000000);
}

// --- transforms that overflow float -------------------------------------------------------------------

TEST_F(HostileGltf, NodeMatrixOverflowingFloatNamesTheNode) {
  GltfBuilder b = one_triangle();
  b.j["nodes"][0]["matrix"] = {1e39, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  const auto [msg, code] = import_error(b.write_gltf(dir / "t.gltf"));
  EXPECT_EQ(code, ExitCode::kInputInvalid);
  EXPECT_EQ(msg.rfind("/nodes/0/matrix: world transform is not finite in float", 0), 0u) << msg;
}

TEST_F(HostileGltf, WorldCoordinatesOverflowingFloatNameTheNode) {
  GltfBuilder b;
  const int pos = b.add_positions({0, 0, 0, 10, 0, 0, 0, 10, 0});
  b.add_mesh(pos);
  const int leaf = b.add_node({{"mesh", 0}});
  b.set_scene({b.add_node({{"children", {leaf}}}), b.add_node({{"mesh", 0}, {"scale", {1e38, 1, 1}}})});
  expect(b, "/nodes/2: world transform puts vertices of mesh0 at |coordinate| 1e+39, not finite in float");
}

// --- package metadata cameras (rtpack-trace, rtpack-inspect) -----------------------------------------

class HostileMetadata : public HostileGltf {
 protected:
  std::string pkg = (dir / "p.rtp").string();
  void SetUp() override {
    const ToolRun r =
        run_tool("rtpack-convert",
                 "-q --zstd-level 0 --no-dag " + (source_dir() / "samples/generated/gallery.glb").string() + " -o " + pkg, dir);
    ASSERT_EQ(r.code, 0) << r.err;
  }
  // Replaces `from` by `to` (same length) inside the first camera of the metadata JSON, CRCs re-sealed.
  void patch_camera(const std::string& from, const std::string& to) {
    ASSERT_EQ(from.size(), to.size());
    const PackageReader reader(pkg);
    const int64_t mi = reader.find(fmt::ChunkKind::kMetadata, 0);
    ASSERT_GE(mi, 0);
    bool done = false;
    patch_chunk(pkg, size_t(mi), [&](uint8_t* chunk, size_t) {
      uint64_t n = 0;
      char* text = section<char>(chunk, fmt::SectionType::kJson, &n);
      ASSERT_NE(text, nullptr);
      std::string s(text, n);
      const size_t cams = s.find("\"cameras\":[{");
      ASSERT_NE(cams, std::string::npos) << s;
      const size_t at = s.find(from, cams);
      ASSERT_NE(at, std::string::npos) << s;
      std::copy(to.begin(), to.end(), text + at);  // in place, same length: no terminator
      done = true;
    });
    ASSERT_TRUE(done);
  }
  ToolRun trace() {
    return run_tool("rtpack-trace",
                    pkg + " --make-camera-rays 8x8 --rays " + (dir / "r.bin").string() + " --hits " + (dir / "h.bin").string(),
                    dir);
  }
};

TEST_F(HostileMetadata, CameraNameIsANumber) {
  // "name":"<n chars>" -> "name":<n+2 digits>
  const ToolRun before = run_tool("rtpack-inspect", "--json " + pkg, dir);
  ASSERT_EQ(before.code, 0) << before.err;
  const auto j = nlohmann::json::parse(slurp(dir / "out"));
  const std::string name = j["metadata"]["cameras"][0]["name"].get<std::string>();
  patch_camera("\"name\":\"" + name + "\"", "\"name\":" + std::string(name.size() + 2, '7'));
  const ToolRun r = run_tool("rtpack-inspect", pkg, dir);
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("/cameras/0/name: not a string"), std::string::npos) << r.err;
}

TEST_F(HostileMetadata, CameraWithoutWorld) {
  patch_camera("\"world\":", "\"wxrld\":");
  const ToolRun r = trace();
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("/cameras/0/world: missing"), std::string::npos) << r.err;
  const ToolRun i = run_tool("rtpack-inspect", pkg, dir);
  EXPECT_EQ(i.code, 3) << i.err;
  EXPECT_NE(i.err.find("/cameras/0/world: missing"), std::string::npos) << i.err;
}

TEST_F(HostileMetadata, CameraWithoutYfov) {
  patch_camera("\"yfov\":", "\"yfxv\":");
  const ToolRun r = trace();
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("/cameras/0/yfov: missing"), std::string::npos) << r.err;
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
