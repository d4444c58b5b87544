// The importer on real files and on fabricated files for every supported glTF feature.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>

#include <tbb/task_arena.h>

#include "gltf_builder.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;
using Tri = std::array<Vec3d, 3>;

std::vector<Tri> world_triangles(const Scene& s) {
  std::vector<Tri> out;
  for (const Instance& in : s.instances) {
    const Mesh& m = s.meshes[in.mesh];
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      Tri tri;
      for (int k = 0; k < 3; ++k) tri[size_t(k)] = in.transform.apply(to_d(m.positions[m.indices[3 * t + size_t(k)]]));
      out.push_back(tri);
    }
  }
  return out;
}

double dist_inf(const Vec3d& a, const Vec3d& b) {
  return std::max({std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
}

// Every triangle of `a` has its own partner in `b` with all three vertices (same winding, any starting
// vertex) within `tol`; returns the number of triangles without a partner.
size_t unmatched(const std::vector<Tri>& a, const std::vector<Tri>& b, double tol) {
  const double cell = tol > 0 ? 4 * tol : 1e-4;  // a centroid moves by at most tol
  auto key = [&](const Tri& t) {
    const Vec3d c = (t[0] + t[1] + t[2]) * (1.0 / 3.0);
    return std::array<int64_t, 3>{int64_t(std::floor(c.x / cell)), int64_t(std::floor(c.y / cell)),
                                  int64_t(std::floor(c.z / cell))};
  };
  std::map<std::array<int64_t, 3>, std::vector<size_t>> grid;
  for (size_t i = 0; i < b.size(); ++i) grid[key(b[i])].push_back(i);
  std::vector<bool> used(b.size(), false);
  size_t missing = 0;
  for (const Tri& t : a) {
    const auto k = key(t);
    bool found = false;
    double best_d = std::numeric_limits<double>::infinity();
    size_t best = 0;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (size_t j : it->second) {
            if (used[j]) continue;
            for (int r = 0; r < 3; ++r) {
              const double d = std::max({dist_inf(t[0], b[j][size_t(r)]), dist_inf(t[1], b[j][size_t((r + 1) % 3)]),
                                         dist_inf(t[2], b[j][size_t((r + 2) % 3)])});
              if (d < best_d) {
                best_d = d;
                best = j;
              }
            }
          }
        }
    if (best_d <= tol) {
      used[best] = true;
      found = true;
    }
    missing += !found;
  }
  return missing;
}

// Quantization step of a `bits`-bit grid over the scene's largest extent.
double step(const Scene& s, int bits) {
  const Vec3d e = s.bounds.extent();
  return std::max({e.x, e.y, e.z}) / double((1 << bits) - 1);
}

// A .glb's BIN chunk reaches tinygltf by an internal buffer name (lib/scene/load.cpp, no copies); a
// second buffer whose file has exactly that name must still be read from its file, and the BIN chunk
// (longer than its byteLength by the chunk padding) still be buffer 0.
TEST(ImportGlb, BinChunkAndABufferFileNamedLikeItsInternalNameBothLoad) {
  const fs::path dir = temp_dir("glb_bin_name");
  GltfBuilder b = one_triangle();  // buffer 0: (0,0,0) (1,0,0) (0,1,0), 42 bytes, chunk padded to 44
  const std::vector<float> far_tri = {5, 5, 5, 7, 5, 5, 5, 7, 5};
  std::ofstream(dir / "rtpack-glb-bin-chunk", std::ios::binary)
      .write(reinterpret_cast<const char*>(far_tri.data()), std::streamsize(far_tri.size() * sizeof(float)));
  b.j["bufferViews"].push_back({{"buffer", 1}, {"byteOffset", 0}, {"byteLength", 36}});
  b.j["accessors"].push_back(
      {{"bufferView", int(b.j["bufferViews"].size()) - 1}, {"componentType", 5126}, {"type", "VEC3"}, {"count", 3}});
  b.j["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", int(b.j["accessors"].size()) - 1}}}}}}});
  b.set_scene({0, b.add_node({{"mesh", 1}})});
  std::string glb = b.glb_bytes();  // its JSON lists buffer 0 only: add buffer 1, re-assemble
  nlohmann::json d = b.j;
  d["buffers"] = {{{"byteLength", b.bin.size()}}, {{"byteLength", 36}, {"uri", "rtpack-glb-bin-chunk"}}};
  std::string js = d.dump();
  while (js.size() % 4) js.push_back(' ');
  std::vector<uint8_t> bin = b.bin;
  while (bin.size() % 4) bin.push_back(0);
  ASSERT_GT(bin.size(), b.bin.size()) << "the test wants a BIN chunk longer than its buffer";
  glb.clear();
  auto put = [&](uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
  put(0x46546C67), put(2), put(uint32_t(12 + 8 + js.size() + 8 + bin.size()));
  put(uint32_t(js.size())), put(0x4E4F534A);
  glb += js;
  put(uint32_t(bin.size())), put(0x004E4942);
  glb.append(reinterpret_cast<const char*>(bin.data()), bin.size());
  std::ofstream(dir / "two.glb", std::ios::binary) << glb;

  const Scene s = import_gltf((dir / "two.glb").string(), {});
  const std::vector<Tri> got = world_triangles(s);
  const std::vector<Tri> want = {Tri{Vec3d{0, 0, 0}, Vec3d{1, 0, 0}, Vec3d{0, 1, 0}},
                                 Tri{Vec3d{5, 5, 5}, Vec3d{7, 5, 5}, Vec3d{5, 7, 5}}};
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(unmatched(want, got, 0.0), 0u) << "a buffer was read from the wrong place";
  EXPECT_EQ(s.input.buffer_files, 1u);
  fs::remove_all(dir);
}

TEST(ImportReal, LanternFloatQuantizedDracoAgree) {
  const fs::path dir = source_dir() / "samples/khronos/Lantern";
  const Scene f = import_gltf((dir / "glTF/Lantern.gltf").string());
  const Scene q = import_gltf((dir / "glTF-Quantized/Lantern.gltf").string());
  const Scene d = import_gltf((dir / "glTF-Draco/Lantern.gltf").string());
  ASSERT_EQ(f.instanced_triangles(), 5394u);
  ASSERT_EQ(q.instanced_triangles(), f.instanced_triangles());
  ASSERT_EQ(d.instanced_triangles(), f.instanced_triangles());
  const auto tf = world_triangles(f);
  // The quantized file stores 14-bit positions (uint16 up to 16383 under one node scale); the Draco
  // file was encoded with 11 position bits (its accessor bounds differ from the float file's by up to
  // one 11-bit step). Each must match the float file within its own quantization step.
  const double tol = step(f, 14);
  EXPECT_EQ(unmatched(tf, world_triangles(q), tol), 0u);
  EXPECT_EQ(unmatched(tf, world_triangles(d), step(f, 11)), 0u);
  EXPECT_GT(unmatched(tf, world_triangles(d), tol), 800u);  // Draco really is coarser than 14 bits
  // The test has teeth: a shift of 3 steps must be caught.
  auto shifted = world_triangles(q);
  for (auto& t : shifted) t[1].y += 3 * tol;
  EXPECT_EQ(unmatched(tf, shifted, tol), tf.size());
}

TEST(ImportReal, FlightHelmetFloatAndMeshoptAgree) {
  const fs::path dir = source_dir() / "samples/khronos/FlightHelmet";
  const Scene f = import_gltf((dir / "glTF/FlightHelmet.gltf").string());
  const Scene m = import_gltf((dir / "FlightHelmet-meshopt.glb").string());
  ASSERT_EQ(f.instanced_triangles(), 94722u);
  ASSERT_EQ(m.instanced_triangles(), f.instanced_triangles());
  // meshopt's vertex codec is lossless for float positions: exact equality.
  EXPECT_EQ(unmatched(world_triangles(f), world_triangles(m), 0.0), 0u);
}

// Independent recomputation of node world transforms from the raw JSON (simple recursion, doubles).
void walk_json(const nlohmann::json& nodes, int n, const std::array<double, 16>& parent,
               std::vector<std::pair<int, std::array<double, 16>>>& out) {
  const nlohmann::json& node = nodes[size_t(n)];
  std::array<double, 16> local{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // column-major
  if (node.contains("matrix")) {
    for (int i = 0; i < 16; ++i) local[size_t(i)] = node["matrix"][size_t(i)].get<double>();
  } else {
    const auto t = node.value("translation", std::vector<double>{0, 0, 0});
    const auto q = node.value("rotation", std::vector<double>{0, 0, 0, 1});
    const auto s = node.value("scale", std::vector<double>{1, 1, 1});
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                         2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                         2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};  // column-major
    for (int c = 0; c < 3; ++c)
      for (int rr = 0; rr < 3; ++rr) local[4 * size_t(c) + size_t(rr)] = r[c * 3 + rr] * s[size_t(c)];
    for (int rr = 0; rr < 3; ++rr) local[12 + size_t(rr)] = t[size_t(rr)];
  }
  std::array<double, 16> g{};
  for (int c = 0; c < 4; ++c)
    for (int rr = 0; rr < 4; ++rr)
      for (int k = 0; k < 4; ++k)
        g[4 * size_t(c) + size_t(rr)] += parent[4 * size_t(k) + size_t(rr)] * local[4 * size_t(c) + size_t(k)];
  if (node.contains("mesh")) out.push_back({n, g});
  for (const auto& c : node.value("children", std::vector<int>{})) walk_json(nodes, c, g, out);
}

nlohmann::json glb_json(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::string s((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  uint32_t len;
  std::memcpy(&len, s.data() + 12, 4);
  return nlohmann::json::parse(s.substr(20, len));
}

TEST(ImportReal, GalleryInstancesMirrorAndBounds) {
  const fs::path p = shared_assets() / "scenes/gallery.glb";
  RTP_NEED_SHARED(p);
  const Scene s = import_gltf(p.string());
  const nlohmann::json j = glb_json(p);
  std::vector<std::pair<int, std::array<double, 16>>> expect;
  for (int root : j["scenes"][j.value("scene", 0)]["nodes"])
    walk_json(j["nodes"], root, {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}, expect);
  ASSERT_EQ(s.instances.size(), expect.size());
  size_t mirrored = 0;
  for (size_t i = 0; i < expect.size(); ++i) {
    const auto& [node, g] = expect[i];
    const Instance& in = s.instances[i];
    EXPECT_EQ(int(in.node), node);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        EXPECT_NEAR(in.transform(r, c), g[size_t(c * 4 + r)], 1e-5 * (1 + std::abs(g[size_t(c * 4 + r)])));
    const double det =
        g[0] * (g[5] * g[10] - g[9] * g[6]) - g[4] * (g[1] * g[10] - g[9] * g[2]) + g[8] * (g[1] * g[6] - g[5] * g[2]);
    EXPECT_EQ(in.mirrored, det < 0) << "instance " << i;
    mirrored += in.mirrored;
    EXPECT_EQ(s.meshes[in.mesh].primitives[0].gltf_mesh, j["nodes"][size_t(node)]["mesh"].get<uint32_t>());
  }
  EXPECT_GE(mirrored, 1u);
  // Meshes are shared, not copied: one Mesh per glTF mesh used.
  std::set<int> used;
  for (const auto& [node, g] : expect) used.insert(j["nodes"][size_t(node)]["mesh"].get<int>());
  EXPECT_EQ(s.meshes.size(), used.size());
  // Bounds equal a brute-force transform of every vertex of every instance.
  Aabb brute;
  for (const auto& t : world_triangles(s))
    for (const auto& v : t) brute.grow(v);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s.bounds.lo[k], brute.lo[k]);
    EXPECT_EQ(s.bounds.hi[k], brute.hi[k]);
  }
  ASSERT_EQ(s.cameras.size(), 1u);
}

// compute_world_bounds skips the instances whose root-box bound cannot raise a face already found:
// on thousands of rotated, scaled and mirrored instances (ties included: copies of one placement, and
// instances of a mesh without vertices, meshes of 1 to 4 instances, scanned without a tree, and a mesh
// searched often enough to get one)
// it must still equal the brute force exactly, for 1 and 2 threads.
TEST(WorldBounds, ManyInstancesEqualBruteForceForAnyThreadCount) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Scene s;
  for (int m = 0; m < 3; ++m) {
    Mesh mesh;
    for (int v = 0; v < 400; ++v) mesh.positions.push_back({u(rng), u(rng) * (m + 1.f), u(rng) * 0.5f});
    for (uint32_t t = 0; t + 2 < 400; t += 3) mesh.indices.insert(mesh.indices.end(), {t, t + 1, t + 2});
    s.meshes.push_back(mesh);
  }
  s.meshes.push_back(Mesh{});  // no vertices: contributes nothing
  for (int i = 0; i < 6000; ++i) {
    Instance in;
    in.mesh = uint32_t(i % 4);
    const double a = u(rng) * 3.2, b = u(rng) * 3.2, sc = 0.5 + u(rng) * 0.4;
    const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b);
    const double r[3][3] = {{ca * cb, -sa, ca * sb}, {sa * cb, ca, sa * sb}, {-sb, 0, cb}};
    const double mirror = i % 5 == 0 ? -1.0 : 1.0;
    for (int row = 0; row < 3; ++row) {
      for (int c = 0; c < 3; ++c) in.transform(row, c) = float(r[row][c] * sc * (c == 0 ? mirror : 1.0));
      in.transform(row, 3) = u(rng) * 20.f;
    }
    s.instances.push_back(in);
    if (i % 100 == 0) s.instances.push_back(in);  // the same placement twice
  }
  // Meshes with 1..4 instances (scanned, never given a tree), placed to reach the scene's faces.
  for (int m = 0; m < 4; ++m) {
    Mesh mesh;
    for (int v = 0; v < 300; ++v) mesh.positions.push_back({u(rng) * 3.f, u(rng), u(rng) * 2.f});
    for (uint32_t t = 0; t + 2 < 300; t += 3) mesh.indices.insert(mesh.indices.end(), {t, t + 1, t + 2});
    s.meshes.push_back(mesh);
    for (int k = 0; k <= m; ++k) {
      Instance in;
      in.mesh = uint32_t(s.meshes.size() - 1);
      const double a = u(rng) * 3.2, ca = std::cos(a), sa = std::sin(a);
      in.transform(0, 0) = float(ca), in.transform(0, 1) = float(-sa), in.transform(1, 0) = float(sa);
      in.transform(1, 1) = float(ca), in.transform(2, 2) = k % 2 ? -1.f : 1.f;
      for (int row = 0; row < 3; ++row) in.transform(row, 3) = float((m + 1) * (row == m % 3 ? 7 : -6));
      s.instances.push_back(in);
    }
  }
  // A sphere's points, 300 instances at one place on the +x/+y corner, each turned about z: every box
  // bound (|cos| + |sin| > 1) beats the exact face (1 + translation), so each instance is searched and
  // the mesh gets its tree.
  {
    Mesh mesh;
    for (int v = 0; v < 600; ++v) {
      const Vec3d d{u(rng), u(rng), u(rng)};
      const double len = std::sqrt(dot(d, d)) + 1e-3;
      mesh.positions.push_back({float(d.x / len), float(d.y / len), float(d.z / len)});
    }
    for (uint32_t t = 0; t + 2 < 600; t += 3) mesh.indices.insert(mesh.indices.end(), {t, t + 1, t + 2});
    s.meshes.push_back(mesh);
    for (int k = 0; k < 300; ++k) {
      Instance in;
      in.mesh = uint32_t(s.meshes.size() - 1);
      const double a = 0.1 + 0.005 * k, ca = std::cos(a), sa = std::sin(a);
      in.transform(0, 0) = float(ca), in.transform(0, 1) = float(-sa), in.transform(1, 0) = float(sa);
      in.transform(1, 1) = float(ca);
      in.transform(0, 3) = 45.f, in.transform(1, 3) = 45.f;
      s.instances.push_back(in);
    }
  }
  Aabb brute;
  for (const Instance& in : s.instances)
    for (uint32_t v : s.meshes[in.mesh].indices) brute.grow(in.transform.apply(to_d(s.meshes[in.mesh].positions[v])));
  for (int threads : {1, 2}) {
    Aabb got;
    tbb::task_arena(threads).execute([&] { got = compute_world_bounds(s); });
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(got.lo[k], brute.lo[k]) << "axis " << k << ", " << threads << " threads";
      EXPECT_EQ(got.hi[k], brute.hi[k]) << "axis " << k << ", " << threads << " threads";
    }
  }
  s.instances.resize(0);
  EXPECT_TRUE(compute_world_bounds(s).empty());
}

TEST(ImportReal, Forest2kInstancedTriangleCount) {
  const fs::path p = shared_assets() / "scenes/forest-2k.glb";
  RTP_NEED_SHARED(p);
  const Scene s = import_gltf(p.string());
  const nlohmann::json j = glb_json(p);
  // Σ over instancing nodes of (instance count × triangles of the node's mesh), from the raw JSON.
  uint64_t expected = 0, instances = 0;
  for (const auto& n : j["nodes"]) {
    if (!n.contains("mesh")) continue;
    uint64_t tris = 0;
    for (const auto& pr : j["meshes"][n["mesh"].get<size_t>()]["primitives"])
      tris += j["accessors"][pr["indices"].get<size_t>()]["count"].get<uint64_t>() / 3;
    uint64_t count = 1;
    if (n.contains("extensions") && n["extensions"].contains("EXT_mesh_gpu_instancing"))
      for (const auto& [k, a] : n["extensions"]["EXT_mesh_gpu_instancing"]["attributes"].items())
        count = j["accessors"][a.get<size_t>()]["count"].get<uint64_t>();
    expected += count * tris;
    instances += count;
  }
  EXPECT_EQ(s.instances.size(), instances);
  EXPECT_EQ(s.instanced_triangles(), expected);
  EXPECT_GT(s.instanced_triangles(), 100 * s.unique_triangles() / 10);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
