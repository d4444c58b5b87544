// Every rejection of the importer: exact message naming the JSON pointer, the documented exit code,
// and no crash. The broken files are fabricated here.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "gltf_builder.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

// Imports `path` and returns the error (message, code); fails the test if the import succeeds.
std::pair<std::string, ExitCode> import_error(const std::string& path) {
  try {
    import_gltf(path);
  } catch (const Error& e) {
    return {e.what(), e.code()};
  }
  ADD_FAILURE() << path << " was accepted";
  return {"", ExitCode::kOk};
}

class Reject : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
  void expect(GltfBuilder b, const std::string& message, ExitCode code = ExitCode::kInputInvalid) {
    const auto [msg, c] = import_error(b.write_gltf(dir / "t.gltf"));
    EXPECT_EQ(msg, message);
    EXPECT_EQ(c, code);
    const auto [msg2, c2] = import_error(b.write_glb(dir / "t.glb"));  // same verdict from a .glb
    EXPECT_EQ(msg2, message);
  }
};

TEST_F(Reject, IndexOutOfRange) {
  GltfBuilder b;
  std::vector<float> xyz(1024 * 3, 0.f);
  for (size_t i = 0; i < xyz.size(); ++i) xyz[i] = float(i % 7);
  const int pos = b.add_positions(xyz);
  const int idx = b.add_indices(std::vector<uint32_t>{0, 1, 1207});
  b.add_mesh(pos, idx);
  b.add_mesh(pos, idx);
  b.add_mesh(pos, idx);
  b.add_mesh(pos, b.add_indices(std::vector<uint32_t>{0, 1, 2, 5, 1207, 3}));
  b.set_scene({b.add_node({{"mesh", 3}})});
  expect(b, "/meshes/3/primitives/0/indices: index 1207 out of range (1024 vertices)");
}

TEST_F(Reject, AccessorReferenceOutOfRange) {
  GltfBuilder b = one_triangle();
  b.j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 7;
  expect(b, "/meshes/0/primitives/0/attributes/POSITION: accessor 7 out of range (2 accessors)");
}

TEST_F(Reject, NodeMeshReferenceOutOfRange) {
  GltfBuilder b = one_triangle();
  b.j["nodes"][0]["mesh"] = 4;
  expect(b, "/nodes/0/mesh: mesh 4 out of range (1 meshes)");
}

TEST_F(Reject, SceneNodeOutOfRange) {
  GltfBuilder b = one_triangle();
  b.j["scenes"][0]["nodes"] = {0, 9};
  expect(b, "/scenes/0/nodes/1: node 9 out of range (1 nodes)");
}

TEST_F(Reject, DefaultSceneOutOfRange) {
  GltfBuilder b = one_triangle();
  b.j["scene"] = 2;
  expect(b, "/scene: scene 2 out of range (1 scenes)");
}

TEST_F(Reject, AccessorOverrunsBufferView) {
  GltfBuilder b = one_triangle();
  b.j["accessors"][0]["count"] = 4;  // 4 × 12 bytes, the view holds 36
  expect(b, "/accessors/0: needs 48 bytes but bufferView 0 has 36 (accessor overruns its bufferView)");
}

TEST_F(Reject, AccessorByteOffsetOverrun) {
  GltfBuilder b = one_triangle();
  b.j["accessors"][1]["byteOffset"] = 2;
  expect(b, "/accessors/1: needs 8 bytes but bufferView 1 has 6 (accessor overruns its bufferView)");
}

TEST_F(Reject, BufferViewOverrunsBuffer) {
  GltfBuilder b = one_triangle();
  b.j["bufferViews"][1]["byteLength"] = 100;
  b.j["accessors"][1]["count"] = 3;
  expect(b, "/bufferViews/1: bytes 36..136 overrun buffer 0 (42 bytes)");
}

TEST_F(Reject, NodeCycle) {
  GltfBuilder b = one_triangle();
  b.add_node({{"children", {2}}});
  b.add_node({{"children", {1}}, {"mesh", 0}});
  expect(b, "/nodes/1: node cycle (node 1 is its own ancestor)");
}

TEST_F(Reject, NodeIsItsOwnChild) {
  GltfBuilder b = one_triangle();
  b.j["nodes"][0]["children"] = {0};
  expect(b, "/nodes/0/children/0: node cycle: node 0 is its own child");
}

TEST_F(Reject, NodeWithTwoParents) {
  GltfBuilder b = one_triangle();
  b.add_node({{"children", {0}}});
  b.add_node({{"children", {0}}});
  b.set_scene({1, 2});
  expect(b, "/nodes/2/children/0: node 0 already has parent 1 (the node hierarchy must be a forest)");
}

TEST_F(Reject, UnknownRequiredExtensionsAreListed) {
  GltfBuilder b = one_triangle();
  b.j["extensionsRequired"] = {"KHR_mesh_quantization", "EXT_foo", "KHR_bar"};
  expect(b, "/extensionsRequired: unsupported required extensions: EXT_foo, KHR_bar");
}

TEST_F(Reject, GpuInstancingAttributeCountsDiffer) {
  GltfBuilder b = one_triangle();
  const int t = b.add_accessor(b.add_view(std::vector<float>(6, 0.f)), 5126, "VEC3", 2);
  const int s = b.add_accessor(b.add_view(std::vector<float>(9, 1.f)), 5126, "VEC3", 3);
  b.j["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", t}, {"SCALE", s}};
  expect(b, "/nodes/0/extensions/EXT_mesh_gpu_instancing/attributes/SCALE: count 3 differs from the other attributes (2)");
}

// Instances are composed in parallel; the one reported is still the lowest-numbered bad one, with the
// serial loop's message (two bad instances, in different parallel ranges).
TEST_F(Reject, GpuInstanceOutOfFloatRangeIsTheFirstOne) {
  GltfBuilder b = one_triangle();
  std::vector<float> scale(3 * 10000, 1.f);
  for (size_t k = 0; k < 3; ++k) scale[3 * 9000 + k] = scale[3 * 5000 + k] = 3e38f;
  const int s = b.add_accessor(b.add_view(scale), 5126, "VEC3", 10000);
  b.j["nodes"][0]["scale"] = {10, 10, 10};  // 3e39 in the world transform: beyond float
  b.j["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"SCALE", s}};
  expect(b, "/nodes/0/scale: world transform of EXT_mesh_gpu_instancing instance 5000 is not finite in float (entry 3e+39)");
}

TEST_F(Reject, IndicesOfWrongType) {
  GltfBuilder b = one_triangle();
  b.j["accessors"][1]["componentType"] = 5122;  // signed short
  expect(b, "/meshes/0/primitives/0/indices: indices must be SCALAR unsigned byte/short/int (accessor 1)");
}

TEST_F(Reject, NotGltf2) {
  GltfBuilder b = one_triangle();
  b.j["asset"]["version"] = "1.0";
  expect(b, "/asset/version: not a glTF 2.x file");
}

TEST_F(Reject, TruncatedGlb) {
  const std::string bytes = one_triangle().glb_bytes();
  for (size_t cut : {size_t(0), size_t(7), size_t(19), size_t(40), bytes.size() / 2, bytes.size() - 1}) {
    std::ofstream(dir / "cut.glb", std::ios::binary).write(bytes.data(), std::streamsize(cut));
    const auto [msg, code] = import_error((dir / "cut.glb").string());
    EXPECT_EQ(code, ExitCode::kInputInvalid) << "cut at " << cut;
    if (cut >= 20) {
      EXPECT_EQ(msg, "truncated file: .glb header declares " + std::to_string(bytes.size()) + " bytes but the file has " +
                         std::to_string(cut));
    } else if (cut >= 4) {
      EXPECT_EQ(msg, "truncated file: " + std::to_string(cut) + " bytes is too short for a .glb header");
    }
  }
}

TEST_F(Reject, TruncatedGltfJson) {
  GltfBuilder b = one_triangle();
  const std::string path = b.write_gltf(dir / "t.gltf");
  const auto size = fs::file_size(path);
  fs::resize_file(path, size / 2);
  const auto [msg, code] = import_error(path);
  EXPECT_EQ(code, ExitCode::kInputInvalid);
  EXPECT_EQ(msg.rfind("invalid JSON (truncated file?) at byte " + std::to_string(size / 2 + 1) + ":", 0), 0u) << msg;
}

TEST_F(Reject, TruncatedExternalBuffer) {
  GltfBuilder b = one_triangle();
  const std::string path = b.write_gltf_external(dir / "t.gltf", "t.bin");
  fs::resize_file(dir / "t.bin", 20);
  const auto [msg, code] = import_error(path);
  EXPECT_EQ(msg, "/buffers/0: byteLength is 42 but only 20 bytes are there (truncated file?)");
  EXPECT_EQ(code, ExitCode::kInputInvalid);
}

TEST_F(Reject, MissingExternalBufferIsAnIoError) {
  GltfBuilder b = one_triangle();
  const std::string path = b.write_gltf_external(dir / "t.gltf", "t.bin");
  fs::remove(dir / "t.bin");
  const auto [msg, code] = import_error(path);
  EXPECT_EQ(msg, "/buffers/0/uri: cannot open 't.bin' (looked in " + dir.string() + ")");
  EXPECT_EQ(code, ExitCode::kInputIo);
}

TEST_F(Reject, CurrentDirectoryIsNeverSearched) {
  GltfBuilder b = one_triangle();
  fs::create_directories(dir / "sub");
  const std::string path = b.write_gltf_external(dir / "sub" / "t.gltf", "t.bin");
  fs::rename(dir / "sub" / "t.bin", dir / "t.bin");  // only findable from the current directory
  const fs::path old = fs::current_path();
  fs::current_path(dir);
  const auto [msg, code] = import_error(path);
  fs::current_path(old);
  EXPECT_EQ(code, ExitCode::kInputIo) << msg;
}

TEST_F(Reject, GlbOf4GiBOrMore) {
  // A sparse file: no real disk use.
  const fs::path p = dir / "huge.glb";
  std::ofstream(p, std::ios::binary) << one_triangle().glb_bytes();
  fs::resize_file(p, (uint64_t(1) << 32) + 16);
  const auto [msg, code] = import_error(p.string());
  EXPECT_EQ(msg,
            "file is 4294967312 bytes: glTF/.glb files of 4 GiB or more are not supported (the .glb length field is 32-bit)");
  EXPECT_EQ(code, ExitCode::kInputInvalid);
}

TEST_F(Reject, MissingFile) {
  const auto [msg, code] = import_error((dir / "nope.glb").string());
  EXPECT_EQ(code, ExitCode::kInputIo);
  EXPECT_NE(msg.find("no such file"), std::string::npos);
}

TEST_F(Reject, SparseIndexOutOfRange) {
  GltfBuilder b = one_triangle();
  const int iv = b.add_view(std::vector<uint16_t>{5, 0});
  const int vv = b.add_view(std::vector<float>{9, 9, 9});
  b.j["accessors"][0]["sparse"] = {
      {"count", 1}, {"indices", {{"bufferView", iv}, {"componentType", 5123}}}, {"values", {{"bufferView", vv}}}};
  expect(b, "/meshes/0/primitives/0/attributes/POSITION/sparse/indices: index 5 out of range (3 elements)");
}

TEST_F(Reject, MeshoptViewInconsistent) {
  GltfBuilder b = one_triangle();
  b.j["bufferViews"][0]["extensions"]["EXT_meshopt_compression"] = {
      {"buffer", 0}, {"byteOffset", 0}, {"byteLength", 10}, {"byteStride", 12}, {"count", 2}, {"mode", "ATTRIBUTES"}};
  expect(b, "/bufferViews/0/extensions/EXT_meshopt_compression: count 2 × byteStride 12 != byteLength 36");
}

// Random corruption of a real sample: any outcome but a crash (ASan/UBSan run this too).
TEST_F(Reject, BitFlippedSamplesNeverCrash) {
  const fs::path src = source_dir() / "samples/khronos/Lantern/glTF-Draco/Lantern.gltf";
  ASSERT_TRUE(fs::exists(src));
  std::ifstream in(src, std::ios::binary);
  const std::string original((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  fs::copy_file(src.parent_path() / "Lantern.bin", dir / "Lantern.bin");
  uint64_t state = 12345;
  int rejected = 0;
  for (int trial = 0; trial < 200; ++trial) {
    std::string s = original;
    for (int k = 0; k < 3; ++k) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      s[(state >> 33) % s.size()] ^= char(1u << ((state >> 20) % 8));
    }
    std::ofstream(dir / "Lantern.gltf", std::ios::binary) << s;
    try {
      import_gltf((dir / "Lantern.gltf").string());
    } catch (const Error& e) {
      EXPECT_NE(e.code(), ExitCode::kInternal);
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);  // the flips must hit something
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
