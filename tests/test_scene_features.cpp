// Each glTF feature the importer supports, on fabricated files with known answers.
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "gltf_builder.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

class Feature : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
  Scene load(GltfBuilder& b) { return import_gltf(b.write_gltf(dir / "t.gltf")); }
};

std::vector<uint32_t> tri_indices(const Mesh& m) { return m.indices; }

const std::vector<float> kQuad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0};

TEST_F(Feature, TriangleStrip) {
  GltfBuilder b;
  b.add_mesh(b.add_positions(kQuad), b.add_indices(std::vector<uint8_t>{0, 1, 3, 2, 4}), 5);
  b.set_scene({b.add_node({{"mesh", 0}})});
  const Scene s = load(b);
  // glTF strip rule: triangle i = {i, i+1+i%2, i+2-i%2}
  EXPECT_EQ(tri_indices(s.meshes[0]), (std::vector<uint32_t>{0, 1, 3, 1, 2, 3, 3, 2, 4}));
  ASSERT_EQ(s.meshes[0].source.size(), 3u);
  EXPECT_EQ(s.meshes[0].source[2].triangle, 2u);
}

TEST_F(Feature, TriangleFan) {
  GltfBuilder b;
  b.add_mesh(b.add_positions(kQuad), b.add_indices(std::vector<uint32_t>{0, 1, 2, 3}), 6);
  b.set_scene({b.add_node({{"mesh", 0}})});
  EXPECT_EQ(tri_indices(load(b).meshes[0]), (std::vector<uint32_t>{1, 2, 0, 2, 3, 0}));
}

TEST_F(Feature, NonIndexedAndIndexWidths) {
  GltfBuilder b;
  const int pos = b.add_positions({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 2, 2, 0, 2, 0, 0});
  b.j["meshes"].push_back(
      {{"primitives",
        {{{"attributes", {{"POSITION", pos}}}},  // non-indexed: 2 triangles
         {{"attributes", {{"POSITION", pos}}}, {"indices", b.add_indices(std::vector<uint8_t>{5, 4, 3})}},
         {{"attributes", {{"POSITION", pos}}}, {"indices", b.add_indices(std::vector<uint16_t>{0, 2, 4})}},
         {{"attributes", {{"POSITION", pos}}}, {"indices", b.add_indices(std::vector<uint32_t>{1, 3, 5})}}}}});
  b.set_scene({b.add_node({{"mesh", 0}})});
  const Scene s = load(b);
  ASSERT_EQ(s.meshes.size(), 1u);
  const Mesh& m = s.meshes[0];
  ASSERT_EQ(m.triangle_count(), 5u);
  ASSERT_EQ(m.primitives.size(), 4u);
  // Each primitive appends its own 6 vertices; indices are rebased.
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 3, 4, 5, 11, 10, 9, 12, 14, 16, 19, 21, 23}));
  EXPECT_EQ(m.source[4].primitive, 3u);
  EXPECT_EQ(m.primitives[3].gltf_primitive, 3u);
}

TEST_F(Feature, InterleavedByteStride) {
  GltfBuilder b;
  // position xyz + 1 float of padding per vertex: stride 16
  const int view = b.add_view(std::vector<float>{0, 0, 0, -1, 5, 0, 0, -1, 0, 5, 0, -1}, 16);
  const int pos = b.add_accessor(view, 5126, "VEC3", 3);
  b.add_mesh(pos);
  b.set_scene({b.add_node({{"mesh", 0}})});
  const Scene s = load(b);
  EXPECT_EQ(s.meshes[0].positions[1], (Vec3f{5, 0, 0}));
  EXPECT_EQ(s.meshes[0].positions[2], (Vec3f{0, 5, 0}));
}

TEST_F(Feature, SparseAccessorOverridesAndZeroBase) {
  GltfBuilder b = one_triangle();
  const int iv = b.add_view(std::vector<uint8_t>{2, 0, 0, 0});
  const int vv = b.add_view(std::vector<float>{0, 7, 0});
  b.j["accessors"][0]["sparse"] = {
      {"count", 1}, {"indices", {{"bufferView", iv}, {"componentType", 5121}}}, {"values", {{"bufferView", vv}}}};
  EXPECT_EQ(load(b).meshes[0].positions[2], (Vec3f{0, 7, 0}));
  // No bufferView: zeros, then the sparse values.
  b.j["accessors"][0].erase("bufferView");
  const Scene s = load(b);
  EXPECT_EQ(s.meshes[0].positions[0], (Vec3f{0, 0, 0}));
  EXPECT_EQ(s.meshes[0].positions[2], (Vec3f{0, 7, 0}));
}

TEST_F(Feature, QuantizedPositions) {
  GltfBuilder b;
  b.j["extensionsRequired"] = {"KHR_mesh_quantization"};
  // normalized signed short: 32767 -> 1.0, -32768 -> -1.0 (clamped)
  const int ns =
      b.add_accessor(b.add_view(std::vector<int16_t>{0, 0, 0, 32767, 0, 0, -32768, 16384, 0, 0}), 5122, "VEC3", 3, true);
  // non-normalized unsigned byte: raw integers
  const int ub =
      b.add_accessor(b.add_view(std::vector<uint8_t>{0, 0, 0, 0, 200, 0, 0, 0, 0, 3, 0, 0}, 4), 5121, "VEC3", 3, false);
  b.add_mesh(ns);
  b.add_mesh(ub);
  b.set_scene({b.add_node({{"mesh", 0}}), b.add_node({{"mesh", 1}, {"scale", {0.5, 0.5, 0.5}}})});
  const Scene s = load(b);
  EXPECT_EQ(s.meshes[0].positions[1], (Vec3f{1, 0, 0}));
  EXPECT_EQ(s.meshes[0].positions[2].x, -1.f);
  EXPECT_FLOAT_EQ(s.meshes[0].positions[2].y, float(16384 / 32767.0));
  EXPECT_EQ(s.meshes[1].positions[1], (Vec3f{200, 0, 0}));
  EXPECT_EQ(s.bounds.hi.x, 100.0);  // the node scale dequantizes
}

TEST_F(Feature, GpuInstancingWithNormalizedRotation) {
  GltfBuilder b = one_triangle();
  b.j["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
  const int t = b.add_accessor(b.add_view(std::vector<float>{10, 0, 0, 20, 0, 0, 30, 0, 0}), 5126, "VEC3", 3);
  // 90° about z as a normalized short quaternion (0, 0, 0.7071, 0.7071), identity, and 180° about y.
  const int16_t h = 23170;
  const int r =
      b.add_accessor(b.add_view(std::vector<int16_t>{0, 0, h, h, 0, 0, 0, 32767, 0, 32767, 0, 0}), 5122, "VEC4", 3, true);
  const int sc = b.add_accessor(b.add_view(std::vector<float>{1, 1, 1, 2, 2, 2, 1, 1, 1}), 5126, "VEC3", 3);
  b.j["nodes"][0]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", t}, {"ROTATION", r}, {"SCALE", sc}};
  b.j["nodes"][0]["translation"] = {0, 100, 0};  // the node transform applies after the instance TRS
  const Scene s = load(b);
  ASSERT_EQ(s.instances.size(), 3u);
  EXPECT_EQ(s.meshes.size(), 1u);
  // instance 0: (1,0,0) rotated 90° about z -> (0,1,0), then +(10,0,0), then +(0,100,0)
  const Vec3d p = s.instances[0].transform.apply({1, 0, 0});
  EXPECT_NEAR(p.x, 10, 1e-4);
  EXPECT_NEAR(p.y, 101, 1e-4);
  EXPECT_NEAR(s.instances[1].transform.apply({1, 0, 0}).x, 22, 1e-6);
  EXPECT_NEAR(s.instances[2].transform.apply({1, 0, 0}).x, 29, 1e-4);
  EXPECT_EQ(s.instances[2].gpu_instance, 2u);
  EXPECT_EQ(s.instances[2].node, 0u);
  for (const auto& i : s.instances) EXPECT_FALSE(i.mirrored);
  EXPECT_EQ(s.instanced_triangles(), 3u);
}

TEST_F(Feature, HierarchyMatrixTrsAndMirror) {
  GltfBuilder b = one_triangle();
  // root (matrix: translate x+5) -> child (TRS: scale -1 in x) -> grandchild (mesh)
  b.j["nodes"] = nlohmann::json::array();
  b.add_node({{"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1}}, {"children", {1}}});
  b.add_node({{"scale", {-1, 1, 1}}, {"children", {2}}});
  b.add_node({{"mesh", 0}, {"translation", {1, 0, 0}}});
  b.add_node({{"mesh", 0}});  // a second user of the same mesh
  b.set_scene({0, 3});
  const Scene s = load(b);
  ASSERT_EQ(s.meshes.size(), 1u);  // shared, not copied
  ASSERT_EQ(s.instances.size(), 2u);
  EXPECT_TRUE(s.instances[0].mirrored);
  EXPECT_FALSE(s.instances[1].mirrored);
  const Vec3d p = s.instances[0].transform.apply({1, 0, 0});  // local x=1 -> +1 -> mirrored -2 -> +5 = 3
  EXPECT_DOUBLE_EQ(p.x, 3.0);
  EXPECT_EQ(s.bounds.lo.x, 0.0);
  EXPECT_EQ(s.bounds.hi.x, 4.0);
}

TEST_F(Feature, SceneSelection) {
  GltfBuilder b = one_triangle();
  b.add_node({{"mesh", 0}, {"translation", {0, 0, 9}}});
  b.j["scenes"].push_back({{"nodes", {1}}});
  b.j["scene"] = 1;
  const std::string p = b.write_gltf(dir / "t.gltf");
  EXPECT_EQ(import_gltf(p).bounds.lo.z, 9.0);  // the default scene
  ImportOptions o;
  o.scene = 0;
  EXPECT_EQ(import_gltf(p, o).bounds.lo.z, 0.0);
  o.scene = 2;
  try {
    import_gltf(p, o);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "--scene 2: the file has 2 scenes");
    EXPECT_EQ(e.code(), ExitCode::kUsage);
  }
}

TEST_F(Feature, ContainersGiveTheSameScene) {
  GltfBuilder b = one_triangle();
  const Scene a = import_gltf(b.write_gltf(dir / "a.gltf"));
  const Scene g = import_gltf(b.write_glb(dir / "b.glb"));
  const std::string ext = b.write_gltf_external(dir / "c.gltf", "c%20bin.bin");  // percent-encoded uri
  fs::rename(dir / "c%20bin.bin", dir / "c bin.bin");
  const Scene e = import_gltf(ext);
  EXPECT_EQ(a.meshes[0].positions, g.meshes[0].positions);
  EXPECT_EQ(a.meshes[0].positions, e.meshes[0].positions);
  EXPECT_EQ(a.meshes[0].indices, e.meshes[0].indices);
}

TEST_F(Feature, WarningsForSkippedContent) {
  GltfBuilder b = one_triangle();
  const int pos = 0;
  // mesh 1: two line primitives + one point primitive + one triangle primitive without POSITION
  b.j["meshes"].push_back({{"primitives",
                            {{{"attributes", {{"POSITION", pos}}}, {"mode", 1}},
                             {{"attributes", {{"POSITION", pos}}}, {"mode", 3}},
                             {{"attributes", {{"POSITION", pos}}}, {"mode", 0}},
                             {{"attributes", {{"NORMAL", pos}}}}}}});
  b.add_node({{"mesh", 1}});
  // mesh 2: a NaN vertex
  const int bad = b.add_positions({0, 0, 0, 1, 0, 0, 0, 1, 0, NAN, 0, 0});
  b.add_mesh(bad, b.add_indices(std::vector<uint16_t>{0, 3, 1, 3, 2, 1, 0, 1, 2}));
  b.add_node({{"mesh", 2}});
  // an image whose file does not exist, a texture and material using it: not an error
  b.j["images"] = {{{"uri", "missing.png"}}};
  b.j["textures"] = {{{"source", 0}}};
  b.set_scene({0, 1, 2});
  const Scene s = load(b);
  EXPECT_EQ(s.warnings, (std::vector<std::string>{"/meshes/1/primitives/3: no POSITION attribute, primitive skipped",
                                                  "/meshes/1: 3 point/line primitives skipped",
                                                  "/meshes/1: no triangles; its instances are dropped",
                                                  "/meshes/2/primitives/0: dropped 2 triangles with NaN/Inf positions"}));
  ASSERT_EQ(s.meshes.size(), 2u);
  EXPECT_EQ(s.meshes[1].triangle_count(), 1u);
  EXPECT_EQ(s.meshes[1].source[0].triangle, 2u);  // the surviving triangle keeps its number
}

TEST_F(Feature, CamerasWithScaleStripped) {
  GltfBuilder b = one_triangle();
  b.j["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.1}, {"aspectRatio", 1.5}}}},
                    {{"type", "orthographic"}, {"orthographic", {{"xmag", 2}, {"ymag", 3}, {"znear", 0}, {"zfar", 50}}}}};
  b.add_node({{"camera", 0}, {"translation", {1, 2, 3}}, {"scale", {4, 4, 4}}});
  b.add_node({{"camera", 1}, {"scale", {2, 3, 4}}, {"rotation", {0, 0.7071067811865476, 0, 0.7071067811865476}}});
  b.set_scene({0, 1, 2});
  const Scene s = load(b);
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_EQ(s.cameras[0].type, Camera::Type::kPerspective);
  EXPECT_DOUBLE_EQ(s.cameras[0].yfov, 0.8);
  EXPECT_EQ(s.cameras[0].world(0, 0), 1.f);
  EXPECT_EQ(s.cameras[0].world(1, 3), 2.f);
  EXPECT_EQ(s.cameras[1].type, Camera::Type::kOrthographic);
  EXPECT_DOUBLE_EQ(s.cameras[1].ymag, 3.0);
  // rotation 90° about y, scale removed: columns are unit vectors
  for (int c = 0; c < 3; ++c) {
    double n = 0;
    for (int r = 0; r < 3; ++r) n += double(s.cameras[1].world(r, c)) * s.cameras[1].world(r, c);
    EXPECT_NEAR(n, 1.0, 1e-6);
  }
  EXPECT_NEAR(s.cameras[1].world(0, 2), 1.0, 1e-6);  // camera -z looks along world -x
}

TEST_F(Feature, Determinism) {
  const fs::path p = source_dir() / "samples/khronos/FlightHelmet/FlightHelmet-meshopt.glb";
  const Scene a = import_gltf(p.string()), c = import_gltf(p.string());
  ASSERT_EQ(a.meshes.size(), c.meshes.size());
  for (size_t m = 0; m < a.meshes.size(); ++m) {
    EXPECT_EQ(a.meshes[m].positions, c.meshes[m].positions);
    EXPECT_EQ(a.meshes[m].indices, c.meshes[m].indices);
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
