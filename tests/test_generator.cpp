// rtpack-make-scene: determinism, structure of the written .glb (parsed directly), exit codes, and what
// rtp::import_gltf makes of the generated scenes.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/math.h"
#include "scene/import.h"

namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kTool = RTP_BINARY_DIR "/rtpack-make-scene";
const std::string kSource = RTP_SOURCE_DIR;

std::string quote(const std::string& s) { return "'" + s + "'"; }

std::vector<uint8_t> read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

uint32_t le32(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b.at(at)) | uint32_t(b.at(at + 1)) << 8 | uint32_t(b.at(at + 2)) << 16 | uint32_t(b.at(at + 3)) << 24;
}

struct Glb {
  json doc;
  std::vector<uint8_t> bin;
};

// Parses a .glb by hand (header, JSON chunk, BIN chunk) and checks the container invariants.
Glb parse_glb(const fs::path& p) {
  const std::vector<uint8_t> b = read_bytes(p);
  Glb g;
  EXPECT_GE(b.size(), 28u) << p;
  if (b.size() < 28) return g;
  EXPECT_EQ(le32(b, 0), 0x46546C67u);
  EXPECT_EQ(le32(b, 4), 2u);
  EXPECT_EQ(le32(b, 8), b.size());
  const uint32_t json_len = le32(b, 12);
  EXPECT_EQ(le32(b, 16), 0x4E4F534Au);
  EXPECT_EQ(json_len % 4, 0u);
  g.doc = json::parse(b.begin() + 20, b.begin() + 20 + json_len);
  const size_t bin_at = 20 + json_len;
  const uint32_t bin_len = le32(b, bin_at);
  EXPECT_EQ(le32(b, bin_at + 4), 0x004E4942u);
  EXPECT_EQ(bin_at + 8 + bin_len, b.size());
  g.bin.assign(b.begin() + long(bin_at) + 8, b.end());
  EXPECT_EQ(g.doc["buffers"][0]["byteLength"].get<size_t>(), g.bin.size());
  return g;
}

// Column-major glTF node matrix or TRS -> Mat4d.
rtp::Mat4d local_matrix(const json& n) {
  if (n.contains("matrix")) {
    std::array<double, 16> v{};
    for (size_t i = 0; i < 16; ++i) v[i] = n["matrix"][i].get<double>();
    return rtp::Mat4d::from_column_major(v.data());
  }
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  for (size_t i = 0; i < 3; ++i) {
    if (n.contains("translation")) t[i] = n["translation"][i].get<double>();
    if (n.contains("scale")) s[i] = n["scale"][i].get<double>();
  }
  for (size_t i = 0; i < 4; ++i)
    if (n.contains("rotation")) q[i] = n["rotation"][i].get<double>();
  return rtp::Mat4d::from_trs(t, q, s);
}

struct NodeWorld {
  size_t node;
  rtp::Mat4d world;
  int depth;  // 1 = scene root
};

std::vector<NodeWorld> world_nodes(const json& doc) {
  std::vector<NodeWorld> out;
  std::function<void(size_t, const rtp::Mat4d&, int)> visit = [&](size_t i, const rtp::Mat4d& parent, int depth) {
    const json& n = doc["nodes"][i];
    const rtp::Mat4d w = parent * local_matrix(n);
    out.push_back({i, w, depth});
    if (n.contains("children"))
      for (const json& c : n["children"]) visit(c.get<size_t>(), w, depth + 1);
  };
  for (const json& r : doc["scenes"][doc.value("scene", 0)]["nodes"]) visit(r.get<size_t>(), rtp::Mat4d::identity(), 1);
  return out;
}

uint64_t mesh_triangles(const json& doc, size_t mesh) {
  uint64_t t = 0;
  for (const json& p : doc["meshes"][mesh]["primitives"])
    t += doc["accessors"][p["indices"].get<size_t>()]["count"].get<uint64_t>() / 3;
  return t;
}

class Generator : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::path(::testing::TempDir()) / ("rtp_gen_" + std::string(info->name()) + "_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    ASSERT_TRUE(fs::exists(kTool)) << kTool << " is missing: build the rtpack-make-scene target first";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // Runs the tool from the source directory (so the default sample meshes resolve); returns its exit
  // code. stdout goes to dir_/stdout.txt.
  int run(const std::string& args) {
    const std::string cmd = "cd " + quote(kSource) + " && " + quote(kTool) + " " + args + " >" +
                            quote((dir_ / "stdout.txt").string()) + " 2>" + quote((dir_ / "stderr.txt").string());
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::string stdout_text() {
    const std::vector<uint8_t> b = read_bytes(dir_ / "stdout.txt");
    return {b.begin(), b.end()};
  }
  fs::path out(const std::string& name) const { return dir_ / name; }
  fs::path dir_;
};

TEST_F(Generator, SameArgumentsSameBytes) {
  const std::vector<std::pair<std::string, std::string>> cases = {{"gallery", "gallery"},
                                                                  {"forest --count 2000 --seed 7 --refine 0", "forest"},
                                                                  {"far", "far"},
                                                                  {"far --base forest --count 500 --refine 0", "far_forest"}};
  for (const auto& [args, name] : cases) {
    ASSERT_EQ(run(args + " -o " + quote(out(name + "_a.glb").string())), 0) << args;
    ASSERT_EQ(run(args + " -o " + quote(out(name + "_b.glb").string())), 0) << args;
    const auto a = read_bytes(out(name + "_a.glb")), b = read_bytes(out(name + "_b.glb"));
    EXPECT_GT(a.size(), 1000u) << args;
    EXPECT_TRUE(a == b) << args << ": two runs differ";
    EXPECT_FALSE(fs::exists(out(name + "_a.glb.tmp")));
  }
  ASSERT_EQ(run("forest --count 2000 --seed 8 --refine 0 -o " + quote(out("seed8.glb").string())), 0);
  EXPECT_FALSE(read_bytes(out("seed8.glb")) == read_bytes(out("forest_a.glb"))) << "the seed has no effect";
}

TEST_F(Generator, GalleryStructure) {
  ASSERT_EQ(run("gallery -o " + quote(out("g.glb").string())), 0);
  EXPECT_NE(stdout_text().find("instances=12 "), std::string::npos) << stdout_text();
  const Glb g = parse_glb(out("g.glb"));
  const json& doc = g.doc;
  ASSERT_EQ(doc["meshes"].size(), 5u);  // Suzanne, 3 Lantern parts, BoomBox
  std::map<size_t, int> uses;
  int mirrored = 0, matrix_nodes = 0, trs_nodes = 0, max_depth = 0, mesh_nodes = 0;
  rtp::Vec3d content;
  for (const NodeWorld& nw : world_nodes(doc)) {
    const json& n = doc["nodes"][nw.node];
    (n.contains("matrix") ? matrix_nodes : trs_nodes) += 1;
    if (!n.contains("mesh")) continue;
    ++mesh_nodes;
    uses[n["mesh"].get<size_t>()] += 1;
    max_depth = std::max(max_depth, nw.depth);
    if (nw.world.det3() < 0) ++mirrored;
    content = content + rtp::Vec3d{nw.world(0, 3), nw.world(1, 3), nw.world(2, 3)};
  }
  EXPECT_EQ(mesh_nodes, 12);
  EXPECT_EQ(mirrored, 1);
  EXPECT_GE(max_depth, 3);
  EXPECT_GT(matrix_nodes, 0);
  EXPECT_GT(trs_nodes, 0);
  ASSERT_EQ(uses.size(), 5u);
  for (const auto& [mesh, n] : uses) EXPECT_GE(n, 2) << "mesh " << mesh << " is not instanced";
  content = content * (1.0 / mesh_nodes);
  // POSITION accessors carry min/max, indices are uint32 and in range.
  for (const json& m : doc["meshes"]) {
    ASSERT_EQ(m["primitives"].size(), 1u);
    const json& pos = doc["accessors"][m["primitives"][0]["attributes"]["POSITION"].get<size_t>()];
    EXPECT_EQ(pos["componentType"], 5126);
    EXPECT_TRUE(pos.contains("min") && pos.contains("max"));
    const json& idx = doc["accessors"][m["primitives"][0]["indices"].get<size_t>()];
    EXPECT_EQ(idx["componentType"], 5125);
    const json& view = doc["bufferViews"][idx["bufferView"].get<size_t>()];
    uint32_t max_index = 0;
    for (size_t i = 0; i < idx["count"].get<size_t>(); ++i)
      max_index = std::max(max_index, le32(g.bin, view["byteOffset"].get<size_t>() + 4 * i));
    EXPECT_LT(max_index, pos["count"].get<uint32_t>());
  }
  // The perspective camera looks at the content: its -Z axis points at the mean instance position.
  int perspective = 0;
  for (const NodeWorld& nw : world_nodes(doc)) {
    const json& n = doc["nodes"][nw.node];
    if (!n.contains("camera")) continue;
    const json& cam = doc["cameras"][n["camera"].get<size_t>()];
    if (cam["type"] != "perspective") continue;
    ++perspective;
    const rtp::Vec3d eye{nw.world(0, 3), nw.world(1, 3), nw.world(2, 3)};
    const rtp::Vec3d fwd{-nw.world(0, 2), -nw.world(1, 2), -nw.world(2, 2)};
    const rtp::Vec3d to = content - eye;
    const double cos_angle = rtp::dot(fwd, to) / (rtp::length(fwd) * rtp::length(to));
    EXPECT_GT(cos_angle, std::cos(cam["perspective"]["yfov"].get<double>() / 4));
  }
  EXPECT_EQ(perspective, 1);
}

TEST_F(Generator, ForestStructure) {
  const int count = 2503;  // not a multiple of the mesh count
  ASSERT_EQ(run("forest --count " + std::to_string(count) + " --refine 0 -o " + quote(out("f.glb").string())), 0);
  const Glb g = parse_glb(out("f.glb"));
  const json& doc = g.doc;
  ASSERT_TRUE(doc.contains("extensionsUsed"));
  EXPECT_NE(std::find(doc["extensionsUsed"].begin(), doc["extensionsUsed"].end(), "EXT_mesh_gpu_instancing"),
            doc["extensionsUsed"].end());
  uint64_t instances = 0, instanced = 0;
  int short_rotations = 0, cameras = 0;
  for (const json& n : doc["nodes"]) {
    if (n.contains("camera")) ++cameras;
    if (!n.contains("mesh")) continue;
    ASSERT_TRUE(n.contains("extensions")) << n.dump();
    const json& attr = n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
    const json& t = doc["accessors"][attr["TRANSLATION"].get<size_t>()];
    const json& r = doc["accessors"][attr["ROTATION"].get<size_t>()];
    const json& s = doc["accessors"][attr["SCALE"].get<size_t>()];
    const uint64_t k = t["count"].get<uint64_t>();
    EXPECT_EQ(r["count"].get<uint64_t>(), k);
    EXPECT_EQ(s["count"].get<uint64_t>(), k);
    EXPECT_EQ(t["type"], "VEC3");
    EXPECT_EQ(r["type"], "VEC4");
    EXPECT_EQ(s["componentType"], 5126);
    // Every quaternion decodes to unit length; every scale is uniform in [0.5, 1.5].
    const size_t r_at = doc["bufferViews"][r["bufferView"].get<size_t>()]["byteOffset"].get<size_t>();
    const size_t s_at = doc["bufferViews"][s["bufferView"].get<size_t>()]["byteOffset"].get<size_t>();
    const bool is_short = r["componentType"] == 5122;
    if (is_short) {
      ++short_rotations;
      EXPECT_EQ(r.value("normalized", false), true);
    } else {
      EXPECT_EQ(r["componentType"], 5126);
    }
    for (uint64_t i = 0; i < k; ++i) {
      double len2 = 0;
      for (size_t c = 0; c < 4; ++c) {
        double v;
        if (is_short) {
          const size_t at = r_at + 8 * i + 2 * c;
          v = std::max(double(int16_t(uint16_t(g.bin[at] | g.bin[at + 1] << 8))) / 32767.0, -1.0);
        } else {
          float f;
          std::memcpy(&f, &g.bin[r_at + 16 * i + 4 * c], 4);
          v = f;
        }
        len2 += v * v;
      }
      EXPECT_NEAR(len2, 1.0, 1e-3);
      std::array<float, 3> sc;
      std::memcpy(sc.data(), &g.bin[s_at + 12 * i], 12);
      EXPECT_GE(sc[0], 0.5f);
      EXPECT_LE(sc[0], 1.5f);
      EXPECT_EQ(sc[0], sc[1]);
      EXPECT_EQ(sc[0], sc[2]);
    }
    instances += k;
    instanced += k * mesh_triangles(doc, n["mesh"].get<size_t>());
  }
  EXPECT_EQ(instances, uint64_t(count));
  EXPECT_EQ(short_rotations, 1);
  EXPECT_GE(cameras, 1);
  EXPECT_NE(stdout_text().find("instanced_triangles=" + std::to_string(instanced) + " "), std::string::npos) << stdout_text();
}

TEST_F(Generator, RefineMultipliesTrianglesByFour) {
  ASSERT_EQ(run("forest --count 10 --refine 0 -o " + quote(out("r0.glb").string())), 0);
  ASSERT_EQ(run("forest --count 10 --refine 2 -o " + quote(out("r2.glb").string())), 0);
  const json a = parse_glb(out("r0.glb")).doc, b = parse_glb(out("r2.glb")).doc;
  ASSERT_EQ(a["meshes"].size(), b["meshes"].size());
  for (size_t m = 0; m < a["meshes"].size(); ++m) EXPECT_EQ(mesh_triangles(b, m), 16 * mesh_triangles(a, m));
}

TEST_F(Generator, FarIsGalleryUnderAFarRoot) {
  ASSERT_EQ(run("gallery -o " + quote(out("g.glb").string())), 0);
  ASSERT_EQ(run("far -o " + quote(out("far.glb").string())), 0);
  const json g = parse_glb(out("g.glb")).doc, f = parse_glb(out("far.glb")).doc;
  EXPECT_EQ(g["meshes"], f["meshes"]);
  EXPECT_EQ(g["nodes"].size(), f["nodes"].size());
  const json& root = f["nodes"][f["scenes"][0]["nodes"][0].get<size_t>()];
  EXPECT_EQ(root["translation"], json::array({3e6, 1.5e6, -3e6}));
  for (const NodeWorld& nw : world_nodes(f))
    if (f["nodes"][nw.node].contains("mesh")) {
      EXPECT_GT(nw.world(0, 3), 2.9e6);
    }
}

TEST_F(Generator, ErrorsExitCodesAndNoPartialOutput) {
  EXPECT_EQ(run("meadow -o " + quote(out("x.glb").string())), 1);
  EXPECT_EQ(run("gallery"), 1);
  EXPECT_EQ(run("gallery --count 0 -o " + quote(out("x.glb").string())), 1);
  EXPECT_EQ(run("gallery --count 3 -o " + quote(out("x.glb").string())), 1);  // fewer nodes than meshes
  EXPECT_EQ(run("gallery --base forest -o " + quote(out("x.glb").string())), 1);
  EXPECT_EQ(run("gallery --mesh " + quote(out("missing.gltf").string()) + " -o " + quote(out("x.glb").string())), 2);
  EXPECT_FALSE(fs::exists(out("x.glb")));
  EXPECT_EQ(run("gallery -o " + quote(out("no/such/dir/x.glb").string())), 4);
  EXPECT_FALSE(fs::exists(out("no")));
  // A failing run leaves an existing output untouched.
  { std::ofstream(out("keep.glb")) << "old"; }
  EXPECT_EQ(run("gallery --mesh " + quote(out("missing.gltf").string()) + " -o " + quote(out("keep.glb").string())), 2);
  EXPECT_EQ(read_bytes(out("keep.glb")).size(), 3u);
  for (const auto& e : fs::directory_iterator(dir_)) EXPECT_NE(e.path().extension(), ".tmp") << e.path();
}

// ---- through the importer -------------------------------------------------------------------------

TEST_F(Generator, ImportGallery) {
  ASSERT_EQ(run("gallery -o " + quote(out("g.glb").string())), 0);
  const json doc = parse_glb(out("g.glb")).doc;
  const rtp::Scene scene = rtp::import_gltf(out("g.glb").string());
  ASSERT_EQ(scene.meshes.size(), doc["meshes"].size());
  EXPECT_EQ(scene.instances.size(), 12u);
  int mirrored = 0;
  uint64_t instanced = 0;
  for (const rtp::Instance& inst : scene.instances) {
    mirrored += inst.mirrored ? 1 : 0;
    EXPECT_EQ(inst.mirrored, inst.transform.det3() < 0);
    EXPECT_EQ(inst.gpu_instance, rtp::kNoIndex);
    instanced += mesh_triangles(doc, inst.mesh);
  }
  EXPECT_EQ(mirrored, 1);
  for (size_t m = 0; m < scene.meshes.size(); ++m) EXPECT_EQ(scene.meshes[m].triangle_count(), mesh_triangles(doc, m));
  EXPECT_EQ(scene.instanced_triangles(), instanced);
  EXPECT_EQ(scene.cameras.size(), 2u);
}

TEST_F(Generator, ImportForest) {
  const uint64_t count = 3001;
  ASSERT_EQ(run("forest --count " + std::to_string(count) + " --refine 1 -o " + quote(out("f.glb").string())), 0);
  const json doc = parse_glb(out("f.glb")).doc;
  const rtp::Scene scene = rtp::import_gltf(out("f.glb").string());
  ASSERT_EQ(scene.instances.size(), count);
  uint64_t instanced = 0;
  std::set<std::pair<uint32_t, uint32_t>> seen;
  for (const rtp::Instance& inst : scene.instances) {
    ASSERT_LT(inst.mesh, scene.meshes.size());
    instanced += scene.meshes[inst.mesh].triangle_count();
    EXPECT_FALSE(inst.mirrored);
    EXPECT_NE(inst.gpu_instance, rtp::kNoIndex);
    seen.insert({inst.node, inst.gpu_instance});
    // Uniform scale norm * [0.5, 1.5]: the world size of each instance is 0.5..1.5 (meshes are normalized).
    const double s = inst.transform.max_scale();
    const rtp::Aabb b = scene.meshes[inst.mesh].local_bounds();
    const rtp::Vec3d e = b.extent();
    const double size = s * std::max({e.x, e.y, e.z});
    EXPECT_GT(size, 0.499);
    EXPECT_LT(size, 1.501);
  }
  EXPECT_EQ(seen.size(), count);
  uint64_t expected = 0;
  for (const json& n : doc["nodes"])
    if (n.contains("mesh"))
      expected += doc["accessors"][n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]["TRANSLATION"].get<size_t>()]["count"]
                      .get<uint64_t>() *
                  mesh_triangles(doc, n["mesh"].get<size_t>());
  EXPECT_EQ(instanced, expected);
  EXPECT_EQ(scene.instanced_triangles(), expected);
  EXPECT_GE(scene.cameras.size(), 1u);
}

// forest --unique: every instance its own mesh (unique geometry for out-of-core traffic, issue 9), each a
// perturbed copy of its source placed like the instanced forest: same instance count, triangles all
// unique, no two copies with the same vertices, sizes as the instanced forest's, the same bytes twice.
TEST_F(Generator, UniqueForestHasNoSharedMesh) {
  const uint64_t count = 23;
  ASSERT_EQ(run("forest --unique --count " + std::to_string(count) + " -o " + quote(out("u.glb").string())), 0);
  ASSERT_EQ(run("forest --unique --count " + std::to_string(count) + " -o " + quote(out("u2.glb").string())), 0);
  const std::string said = stdout_text();
  EXPECT_TRUE(read_bytes(out("u.glb")) == read_bytes(out("u2.glb")));
  ASSERT_EQ(run("forest --count " + std::to_string(count) + " -o " + quote(out("i.glb").string())), 0);
  const rtp::Scene u = rtp::import_gltf(out("u.glb").string()), inst = rtp::import_gltf(out("i.glb").string());
  ASSERT_EQ(u.instances.size(), count);
  EXPECT_EQ(u.meshes.size(), count);
  EXPECT_EQ(u.unique_triangles(), u.instanced_triangles());
  EXPECT_EQ(u.instanced_triangles(), inst.instanced_triangles());
  EXPECT_NE(said.find("unique_triangles=" + std::to_string(inst.instanced_triangles())), std::string::npos) << said;
  std::set<uint32_t> meshes;
  for (const rtp::Instance& i : u.instances) meshes.insert(i.mesh);
  EXPECT_EQ(meshes.size(), count);
  // Copies 0 and 5 come from the same source (5 sources): same triangles, different vertices.
  const rtp::Mesh& a = u.meshes[u.instances[0].mesh];
  const rtp::Mesh& b = u.meshes[u.instances[5].mesh];
  ASSERT_EQ(a.triangle_count(), b.triangle_count());
  EXPECT_NE(a.positions[0].x, b.positions[0].x);
  for (const rtp::Instance& i : u.instances) {
    const rtp::Vec3d e = u.meshes[i.mesh].local_bounds().extent();
    const double size = i.transform.max_scale() * std::max({e.x, e.y, e.z});
    EXPECT_GT(size, 0.49);
    EXPECT_LT(size, 1.51);
  }
  EXPECT_EQ(run("gallery --unique -o " + quote(out("g.glb").string())), 1);  // forest only
}

TEST_F(Generator, ImportFar) {
  ASSERT_EQ(run("far -o " + quote(out("far.glb").string())), 0);
  const rtp::Scene scene = rtp::import_gltf(out("far.glb").string());
  EXPECT_EQ(scene.instances.size(), 12u);
  for (const rtp::Instance& inst : scene.instances) {
    EXPECT_NEAR(inst.transform(0, 3), 3e6, 100);
    EXPECT_NEAR(inst.transform(1, 3), 1.5e6, 100);
    EXPECT_NEAR(inst.transform(2, 3), -3e6, 100);
  }
}

}  // namespace RTP_UNITY_ID
}  // namespace
