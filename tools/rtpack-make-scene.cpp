// rtpack-make-scene: deterministic generator of test scenes (.glb) built from real sample meshes.
//
//   rtpack-make-scene gallery -o gallery.glb [--count 12] [--spacing 2]
//   rtpack-make-scene forest  -o forest.glb  [--count 3000] [--seed 1] [--refine 1] [--unique] [--ground-camera]
//   rtpack-make-scene far     -o far.glb     [--base gallery|forest]
//
// Source meshes: every triangle rtp::Mesh that rtp::import_gltf returns for each --mesh file (default:
// the Suzanne, Lantern and BoomBox samples = 5 meshes, 15366 triangles), written as-is (local positions,
// uint32 indices) as one glTF mesh with one primitive each. Nodes carry a uniform scale `norm` that
// brings each mesh's largest local extent to 1, so meshes of very different sizes sit on one grid.
//
// gallery  node instancing: --count mesh nodes (item i uses mesh i % M), hierarchy
//          root > platform (TRS: yaw + uniform scale 1.5) > row (TRS, or matrix with a 180 degree yaw)
//          > item (TRS for even i, matrix for odd i), exactly one mirrored item (i = min(2, count-1),
//          scale x negative), a perspective and an orthographic camera (children of root).
// forest   EXT_mesh_gpu_instancing: one node per mesh (node scale = norm), --count instances in total
//          (mesh m gets instances k with k % M == m) on a jittered grid with random yaw and scale
//          0.5..1.5 from std::mt19937_64(--seed). TRANSLATION/SCALE are float VEC3, ROTATION float VEC4
//          except on the second mesh's node where it is normalized SHORT. One perspective camera.
// far      gallery (or --base forest) with the root translated to (3e6, 1.5e6, -3e6).
//
// --refine L splits every source triangle 1-to-4 at its edge midpoints, L times (edges shared by index
// share the midpoint vertex). Default 1 for forest content, 0 otherwise: with the default meshes
// 15366 -> 61464 triangles, so `forest --count 1000000` gives 1e6/5 * 61464 = 1.23e10 instanced
// triangles.
//
// The output is a pure function of the arguments and the source meshes (same arguments = same bytes).
// It is written to OUT.tmp and renamed, so no partial file is ever left at OUT.
// Exit codes (core/error.h): 1 usage, 2 input unreadable, 3 input invalid, 4 output unwritable.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/input_file.h"
#include "core/utf8.h"
#include "core/output_file.h"
#include "core/math.h"
#include "scene/import.h"
#include "make_scene_sources.h"
#include "cli_checks.h"
#include "tool_version.h"

namespace {

using nlohmann::json;
using rtp::Error;
using rtp::ExitCode;
using rtp::tools::compute_bounds;
using rtp::tools::load_sources;
using rtp::tools::refine_once;
using rtp::tools::resolve_default;
using rtp::tools::SourceMesh;
namespace fs = std::filesystem;

constexpr double kPi = 3.14159265358979323846;
constexpr int kFloat = 5126, kUnsignedInt = 5125, kShort = 5122;
constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
constexpr const char* kInstancing = "EXT_mesh_gpu_instancing";
constexpr std::array<double, 3> kFarOffset = {3e6, 1.5e6, -3e6};
constexpr uint64_t kMaxUniqueTriangles = uint64_t(1) << 27;  // after --refine: 1.5 GiB of indices
const std::vector<std::string> kDefaultMeshes = {
    "samples/khronos/Suzanne/glTF/Suzanne.gltf",
    "samples/khronos/Lantern/glTF/Lantern.gltf",
    "samples/khronos/BoomBox/glTF/BoomBox.gltf",
};

using D3 = std::array<double, 3>;
using D4 = std::array<double, 4>;

struct Options {
  std::string kind, output, base = "gallery";
  int64_t count = -1;  // -1: 12 for gallery content, 3000 for forest content
  uint64_t seed = 1;
  double spacing = 2.0;
  int refine = -1;  // -1: 1 for forest content, 0 otherwise
  std::vector<std::string> meshes, allow_paths;
  bool unique = false;         // forest: every instance its own perturbed mesh (no GPU instancing)
  bool ground_camera = false;  // forest: a second camera at eye level, looking into the forest
  bool forest_content() const { return kind == "forest" || (kind == "far" && base == "forest"); }
};

struct Totals {
  uint64_t instances = 0, instanced_triangles = 0;
  uint64_t unique_triangles = 0;  // set by --unique only
};

// ---------------------------------------------------------------------------------------------------
// GLB writer: glTF JSON in nlohmann::json, one little-endian binary buffer.

class GlbBuilder {
 public:
  json doc;

  GlbBuilder() {
    doc["asset"] = {{"version", "2.0"}, {"generator", "rtpack-make-scene"}};
    for (const char* key : {"accessors", "bufferViews", "meshes", "nodes", "cameras"}) doc[key] = json::array();
  }
  void reserve(size_t bytes) { bin_.reserve(bytes); }
  void put_f32(float v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    put_u32(u);
  }
  void put_u32(uint32_t v) {
    for (int i = 0; i < 4; ++i) bin_.push_back(uint8_t(v >> (8 * i)));
  }
  void put_i16(int16_t v) {
    const uint16_t u = uint16_t(v);
    bin_.push_back(uint8_t(u));
    bin_.push_back(uint8_t(u >> 8));
  }
  // Starts a buffer view (4-byte aligned) and returns its offset.
  size_t begin_view() {
    while (bin_.size() % 4) bin_.push_back(0);
    return bin_.size();
  }
  // Ends the view started at `begin`, adds one accessor over it, returns the accessor index.
  int end_accessor(size_t begin, int target, int component, size_t count, const char* type, bool normalized = false) {
    json view = {{"buffer", 0}, {"byteOffset", begin}, {"byteLength", bin_.size() - begin}};
    if (target) view["target"] = target;
    doc["bufferViews"].push_back(std::move(view));
    json acc = {{"bufferView", doc["bufferViews"].size() - 1}, {"componentType", component}, {"count", count}, {"type", type}};
    if (normalized) acc["normalized"] = true;
    doc["accessors"].push_back(std::move(acc));
    return int(doc["accessors"].size() - 1);
  }
  int add_node(json node, int parent) {
    doc["nodes"].push_back(std::move(node));
    const int index = int(doc["nodes"].size() - 1);
    if (parent >= 0) doc["nodes"][size_t(parent)]["children"].push_back(index);
    return index;
  }
  size_t node_count() const { return doc["nodes"].size(); }

  // Writes the .glb to `path` + ".tmp", then renames it to `path`.
  uint64_t write(const std::string& path) {
    begin_view();  // pad BIN to 4 bytes; buffer.byteLength == BIN chunk length
    doc["buffers"] = json::array({json{{"byteLength", bin_.size()}}});
    if (doc["cameras"].empty()) doc.erase("cameras");
    std::string text = doc.dump();
    while (text.size() % 4) text.push_back(' ');
    const uint64_t total = 12 + 8 + text.size() + 8 + bin_.size();
    if (total > 0xffffffffull)
      throw Error(ExitCode::kUsage, "output would exceed the 4 GiB .glb limit; lower --count or --refine");
    std::string header;
    auto u32 = [&header](uint64_t v) {
      for (int i = 0; i < 4; ++i) header.push_back(char(uint8_t(v >> (8 * i))));
    };
    u32(0x46546C67);  // "glTF"
    u32(2);
    u32(total);
    u32(text.size());
    u32(0x4E4F534A);  // "JSON"
    // One unnamed output file linked into place when whole (core/output_file.h): no temporary name.
    rtp::OutputFile f(path);
    uint64_t off = 0;
    auto put = [&](const void* d, size_t n) {
      f.write_at(off, d, n);
      off += n;
    };
    put(header.data(), header.size());
    put(text.data(), text.size());
    header.clear();
    u32(bin_.size());
    u32(0x004E4942);  // "BIN\0"
    put(header.data(), header.size());
    put(bin_.data(), bin_.size());
    f.set_size(off);
    f.commit();
    return total;
  }

 private:
  std::vector<uint8_t> bin_;
};

int add_mesh(GlbBuilder& g, const SourceMesh& m) {
  size_t begin = g.begin_view();
  for (const rtp::Vec3f& p : m.positions) {
    g.put_f32(p.x);
    g.put_f32(p.y);
    g.put_f32(p.z);
  }
  const int pos = g.end_accessor(begin, kArrayBuffer, kFloat, m.positions.size(), "VEC3");
  g.doc["accessors"][size_t(pos)]["min"] = {m.lo.x, m.lo.y, m.lo.z};
  g.doc["accessors"][size_t(pos)]["max"] = {m.hi.x, m.hi.y, m.hi.z};
  begin = g.begin_view();
  for (uint32_t v : m.indices) g.put_u32(v);
  const int idx = g.end_accessor(begin, kElementArrayBuffer, kUnsignedInt, m.indices.size(), "SCALAR");
  json prim = {{"attributes", {{"POSITION", pos}}}, {"indices", idx}, {"mode", 4}};
  g.doc["meshes"].push_back({{"name", m.name}, {"primitives", json::array({prim})}});
  return idx;
}

// ---------------------------------------------------------------------------------------------------
// Nodes and cameras

D4 yaw_quat(double radians) { return {0, std::sin(radians / 2), 0, std::cos(radians / 2)}; }
D4 pitch_quat(double radians) { return {std::sin(radians / 2), 0, 0, std::cos(radians / 2)}; }

json trs_node(const std::string& name, const D3& t, const D4& q, const D3& s) {
  return {{"name", name}, {"translation", t}, {"rotation", q}, {"scale", s}};
}

// The same transform as trs_node, stored as a column-major `matrix`.
json matrix_node(const std::string& name, const D3& t, const D4& q, const D3& s) {
  const rtp::Mat4d m = rtp::Mat4d::from_trs(t.data(), q.data(), s.data());
  std::array<double, 16> cm{};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) cm[4 * size_t(c) + size_t(r)] = m(r, c);
  return {{"name", name}, {"matrix", cm}};
}

// A perspective camera looking down at `center` (25 degrees pitch, from +Z) so that the sphere of
// `radius` fits the vertical field of view; optionally an orthographic camera looking straight down.
void add_cameras(GlbBuilder& g, int parent, const rtp::Vec3d& center, double radius, bool ortho) {
  const double yfov = 0.8, pitch = 25.0 * kPi / 180.0;
  const double dist = radius / std::sin(yfov / 2);
  g.doc["cameras"].push_back(
      {{"name", "perspective"},
       {"type", "perspective"},
       {"perspective", {{"yfov", yfov}, {"aspectRatio", 1.5}, {"znear", dist * 1e-3}, {"zfar", dist * 4}}}});
  const D3 eye = {center.x, center.y + dist * std::sin(pitch), center.z + dist * std::cos(pitch)};
  json cam = {{"name", "camera_perspective"},
              {"camera", g.doc["cameras"].size() - 1},
              {"translation", eye},
              {"rotation", pitch_quat(-pitch)}};
  g.add_node(std::move(cam), parent);
  if (!ortho) return;
  g.doc["cameras"].push_back(
      {{"name", "top"},
       {"type", "orthographic"},
       {"orthographic", {{"xmag", radius}, {"ymag", radius}, {"znear", radius * 1e-3}, {"zfar", radius * 4}}}});
  const D3 top = {center.x, center.y + 2 * radius, center.z};
  json node = {
      {"name", "camera_top"}, {"camera", g.doc["cameras"].size() - 1}, {"translation", top}, {"rotation", pitch_quat(-kPi / 2)}};
  g.add_node(std::move(node), parent);
}

// forest --ground-camera: a perspective camera at eye height (0.6 of a normalized mesh) a row outside the
// grid's +z edge, looking along -z 4 degrees down, so that trees hide trees behind them (the occlusion
// the path workload of issue 54 needs; the camera from above sees mostly the gaps between trees).
void add_ground_camera(GlbBuilder& g, int parent, double side, double spacing) {
  const double yfov = 0.8, pitch = 4.0 * kPi / 180.0;
  g.doc["cameras"].push_back({{"name", "ground"},
                              {"type", "perspective"},
                              {"perspective", {{"yfov", yfov}, {"aspectRatio", 1.0}, {"znear", 1e-2}, {"zfar", 4 * side + 10}}}});
  json cam = {{"name", "camera_ground"},
              {"camera", g.doc["cameras"].size() - 1},
              {"translation", D3{0, 0.6, side / 2 + spacing}},
              {"rotation", pitch_quat(-pitch)}};
  g.add_node(std::move(cam), parent);
}

Totals build_gallery(GlbBuilder& g, const std::vector<SourceMesh>& meshes, const Options& o, int root) {
  const size_t count = size_t(o.count), per_row = 4, rows = (count + per_row - 1) / per_row;
  const size_t mirrored = std::min<size_t>(2, count - 1);
  const D3 platform_t = {0, 0.25, 0}, platform_s = {1.5, 1.5, 1.5};
  const D4 platform_q = yaw_quat(20.0 * kPi / 180.0);
  const int platform = g.add_node(trs_node("platform", platform_t, platform_q, platform_s), root);
  Totals totals;
  int row = -1;
  for (size_t i = 0; i < count; ++i) {
    const size_t r = i / per_row, p = i % per_row;
    if (p == 0) {
      const D3 t = {0, 0, -double(r) * o.spacing};
      const std::string name = "row_" + std::to_string(r);
      row = g.add_node(r % 2 ? matrix_node(name, t, yaw_quat(kPi), {1, 1, 1}) : trs_node(name, t, {0, 0, 0, 1}, {1, 1, 1}),
                       platform);
    }
    const size_t mi = i % meshes.size();
    const SourceMesh& m = meshes[mi];
    const double s = m.norm;
    const D3 t = {(double(p) - (per_row - 1) / 2.0) * o.spacing, -double(m.lo.y) * s, 0};
    const D4 q = yaw_quat(double((i * 47) % 360) * kPi / 180.0);
    const D3 scale = {i == mirrored ? -s : s, s, s};
    const std::string name = "item_" + std::to_string(i) + (i == mirrored ? "_mirrored" : "");
    json node = i % 2 ? matrix_node(name, t, q, scale) : trs_node(name, t, q, scale);
    node["mesh"] = mi;
    g.add_node(std::move(node), row);
    totals.instances += 1;
    totals.instanced_triangles += m.triangles();
  }
  // Content bounding sphere in platform space, then mapped into root space for the cameras.
  const double w = (per_row - 1) * o.spacing + 1, d = (double(rows) - 1) * o.spacing + 1;
  const rtp::Vec3d c_platform = {0, 0.5, -(double(rows) - 1) * o.spacing / 2};
  const rtp::Affine3x4 pm = rtp::Affine3x4::from(rtp::Mat4d::from_trs(platform_t.data(), platform_q.data(), platform_s.data()));
  const double radius = platform_s[0] * 0.5 * std::sqrt(w * w + d * d + 1.0);
  add_cameras(g, root, pm.apply(c_platform), radius, true);
  return totals;
}

// Uniform double in [0, 1) from the top 53 bits: same sequence on every platform.
double uniform(std::mt19937_64& rng) { return double(rng() >> 11) * 0x1.0p-53; }

int16_t snorm16(double v) { return int16_t(std::lround(std::clamp(v, -1.0, 1.0) * 32767.0)); }

// forest --unique: instance k becomes its own mesh, a copy of source k mod n whose every vertex is moved
// by a hash of (k, vertex) up to 0.1 % of the mesh size, sharing the source's index accessor; a TRS node
// places it as the instancing attributes would. Unique geometry, so out-of-core traffic is real (issue 9).
template <class Attributes>
Totals build_unique(GlbBuilder& g, const std::vector<SourceMesh>& meshes, const std::vector<Attributes>& attrs, const Options& o,
                    int root) {
  const uint64_t nm = meshes.size();
  Totals totals;
  std::vector<size_t> used(nm, 0);
  for (uint64_t k = 0; k < uint64_t(o.count); ++k) {
    const uint64_t mi = k % nm;
    const SourceMesh& m = meshes[mi];
    const size_t j = used[mi]++;
    const Attributes& a = attrs[mi];
    const double amp = 1e-3 * std::max({double(m.hi.x - m.lo.x), double(m.hi.y - m.lo.y), double(m.hi.z - m.lo.z)});
    const size_t begin = g.begin_view();
    rtp::Vec3f lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m.positions.size(); ++v) {
      uint64_t h = (k * 0x9E3779B97F4A7C15ull) ^ (v * 0xBF58476D1CE4E5B9ull);
      rtp::Vec3f p = m.positions[v];
      float* c[3] = {&p.x, &p.y, &p.z};
      for (int ax = 0; ax < 3; ++ax) {
        h = (h ^ (h >> 31)) * 0x94D049BB133111EBull + 0x632BE59BD9B4E019ull;
        *c[ax] += float(amp * (double(h >> 11) * 0x1.0p-53 - 0.5));
      }
      lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
      hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
      g.put_f32(p.x);
      g.put_f32(p.y);
      g.put_f32(p.z);
    }
    const int pos = g.end_accessor(begin, kArrayBuffer, kFloat, m.positions.size(), "VEC3");
    g.doc["accessors"][size_t(pos)]["min"] = {lo.x, lo.y, lo.z};
    g.doc["accessors"][size_t(pos)]["max"] = {hi.x, hi.y, hi.z};
    const json prim = {
        {"attributes", {{"POSITION", pos}}}, {"indices", g.doc["meshes"][mi]["primitives"][0]["indices"]}, {"mode", 4}};
    g.doc["meshes"].push_back({{"name", m.name + "_" + std::to_string(k)}, {"primitives", json::array({prim})}});
    const double n = m.norm, sc = a.s[3 * j];
    const D3 t{a.t[3 * j] * n, a.t[3 * j + 1] * n, a.t[3 * j + 2] * n};
    const D4 q{a.r[4 * j], a.r[4 * j + 1], a.r[4 * j + 2], a.r[4 * j + 3]};
    json node = trs_node("unique_" + std::to_string(k), t, q, {sc * n, sc * n, sc * n});
    node["mesh"] = g.doc["meshes"].size() - 1;
    g.add_node(std::move(node), root);
    ++totals.instances;
    totals.instanced_triangles += m.triangles();
    totals.unique_triangles += m.triangles();
  }
  return totals;
}

Totals build_forest(GlbBuilder& g, const std::vector<SourceMesh>& meshes, const Options& o, int root) {
  const uint64_t n = uint64_t(o.count), nm = meshes.size();
  uint64_t grid = uint64_t(std::sqrt(double(n)));
  while (grid * grid < n) ++grid;
  struct Attributes {
    std::vector<float> t, r, s;
  };
  std::vector<Attributes> attrs(nm);
  for (uint64_t m = 0; m < nm; ++m) {
    const uint64_t k = n / nm + (m < n % nm ? 1 : 0);
    attrs[m].t.reserve(k * 3);
    attrs[m].r.reserve(k * 4);
    attrs[m].s.reserve(k * 3);
  }
  std::mt19937_64 rng(o.seed);
  const double half = (double(grid) - 1) / 2;
  for (uint64_t k = 0; k < n; ++k) {
    const uint64_t mi = k % nm;
    const SourceMesh& m = meshes[mi];
    const double jx = (uniform(rng) - 0.5) * 0.5 * o.spacing, jz = (uniform(rng) - 0.5) * 0.5 * o.spacing;
    const double yaw = uniform(rng) * 2 * kPi, sc = 0.5 + uniform(rng);
    const uint64_t row = k / grid, column = k % grid;  // the instance's cell on the grid
    const double x = (double(column) - half) * o.spacing + jx, z = (double(row) - half) * o.spacing + jz;
    // The node scales by m.norm, so translations are divided by it; y puts the mesh on the ground.
    Attributes& a = attrs[mi];
    a.t.insert(a.t.end(), {float(x / m.norm), float(-double(m.lo.y) * sc), float(z / m.norm)});
    const D4 q = yaw_quat(yaw);
    a.r.insert(a.r.end(), {float(q[0]), float(q[1]), float(q[2]), float(q[3])});
    a.s.insert(a.s.end(), {float(sc), float(sc), float(sc)});
  }
  Totals totals;
  if (o.unique) {
    totals = build_unique(g, meshes, attrs, o, root);
    const double side = double(grid) * o.spacing;
    add_cameras(g, root, {0, 0.5, 0}, 0.5 * std::sqrt(2 * side * side + 1.0), false);
    if (o.ground_camera) add_ground_camera(g, root, side, o.spacing);
    return totals;
  }
  const uint64_t short_rotation_mesh = 1 % nm;
  for (uint64_t mi = 0; mi < nm; ++mi) {
    Attributes& a = attrs[mi];
    const size_t k = a.s.size() / 3;
    size_t begin = g.begin_view();
    for (float v : a.t) g.put_f32(v);
    const int t = g.end_accessor(begin, 0, kFloat, k, "VEC3");
    begin = g.begin_view();
    int r;
    if (mi == short_rotation_mesh) {
      for (float v : a.r) g.put_i16(snorm16(v));
      r = g.end_accessor(begin, 0, kShort, k, "VEC4", true);
    } else {
      for (float v : a.r) g.put_f32(v);
      r = g.end_accessor(begin, 0, kFloat, k, "VEC4");
    }
    begin = g.begin_view();
    for (float v : a.s) g.put_f32(v);
    const int s = g.end_accessor(begin, 0, kFloat, k, "VEC3");
    a = Attributes{};  // release early: peak memory stays ~2x the instance data
    const double norm = meshes[mi].norm;
    json node = {{"name", "forest_" + meshes[mi].name},
                 {"mesh", mi},
                 {"scale", D3{norm, norm, norm}},
                 {"extensions", {{kInstancing, {{"attributes", {{"TRANSLATION", t}, {"ROTATION", r}, {"SCALE", s}}}}}}}};
    g.add_node(std::move(node), root);
    totals.instances += k;
    totals.instanced_triangles += k * meshes[mi].triangles();
  }
  const double side = double(grid) * o.spacing;
  add_cameras(g, root, {0, 0.5, 0}, 0.5 * std::sqrt(2 * side * side + 1.0), false);
  if (o.ground_camera) add_ground_camera(g, root, side, o.spacing);
  g.doc["extensionsUsed"] = json::array({kInstancing});
  return totals;
}

// ---------------------------------------------------------------------------------------------------

int run(const Options& cli) {
  Options o = cli;
  const bool forest = o.forest_content();
  if (o.count < 0) o.count = forest ? 3000 : 12;
  if (o.refine < 0) o.refine = forest ? 1 : 0;
  std::vector<std::string> files = o.meshes;
  if (files.empty())
    for (const std::string& rel : kDefaultMeshes) files.push_back(resolve_default(rel));

  for (const std::string& f : files) rtp::check_not_same_file(f, o.output);
  rtp::check_output_path(o.output);  // before any work
  std::vector<SourceMesh> meshes = load_sources(files, o.allow_paths, o.output);
  if (uint64_t(o.count) < meshes.size())
    throw Error(ExitCode::kUsage, "--count " + std::to_string(o.count) + " is below the number of source meshes (" +
                                      std::to_string(meshes.size()) + "); every mesh needs an instance");
  uint64_t unique = 0, vertices = 0;
  for (const SourceMesh& m : meshes) unique += m.triangles() << (2 * o.refine);
  if (unique > kMaxUniqueTriangles)
    throw Error(ExitCode::kUsage, "--refine " + std::to_string(o.refine) + " would give " + std::to_string(unique) +
                                      " unique triangles (limit " + std::to_string(kMaxUniqueTriangles) + ")");
  if (o.unique) {  // every instance a copy: count * (mean source triangles)
    unique = 0;
    for (int64_t k = 0; k < o.count; ++k) unique += meshes[size_t(k) % meshes.size()].triangles() << (2 * o.refine);
    if (unique > kMaxUniqueTriangles)
      throw Error(ExitCode::kUsage, "--unique --count " + std::to_string(o.count) + " would give " + std::to_string(unique) +
                                        " unique triangles (limit " + std::to_string(kMaxUniqueTriangles) + ")");
  }
  for (SourceMesh& m : meshes) {
    for (int level = 0; level < o.refine; ++level) refine_once(m);
    compute_bounds(m);
    vertices += m.positions.size();
  }

  GlbBuilder g;
  g.reserve(size_t(vertices * 12 + unique * (o.unique ? 8 : 12) + (forest ? uint64_t(o.count) * 40 : 0) + 4096));
  json sources = json::array();
  for (const std::string& f : files) sources.push_back(rtp::utf8_display(fs::path(f).filename().string()));
  g.doc["asset"]["extras"] = {{"kind", o.kind},     {"base", o.kind == "far" ? o.base : o.kind},
                              {"count", o.count},   {"seed", o.seed},
                              {"refine", o.refine}, {"spacing", o.spacing},
                              {"unique", o.unique}, {"sources", sources}};
  for (const SourceMesh& m : meshes) add_mesh(g, m);
  const D3 offset = o.kind == "far" ? kFarOffset : D3{0, 0, 0};
  const int root = g.add_node(trs_node(o.kind + "_root", offset, {0, 0, 0, 1}, {1, 1, 1}), -1);
  g.doc["scenes"] = json::array({json{{"name", o.kind}, {"nodes", json::array({root})}}});
  g.doc["scene"] = 0;
  const Totals totals = forest ? build_forest(g, meshes, o, root) : build_gallery(g, meshes, o, root);
  const size_t nodes = g.node_count();
  const uint64_t bytes = g.write(o.output);
  std::cout << o.output << ": kind=" << o.kind << " nodes=" << nodes << " meshes=" << meshes.size()
            << " instances=" << totals.instances << " unique_triangles=" << (o.unique ? totals.unique_triangles : unique)
            << " instanced_triangles=" << totals.instanced_triangles << " bytes=" << bytes << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"rtpack-make-scene: deterministic test scenes (.glb) from the sample meshes"};
  rtp::tools::add_version_flag(app, "rtpack-make-scene");
  app.add_option("kind", o.kind, "gallery | forest | far")->required()->check(CLI::IsMember({"gallery", "forest", "far"}));
  app.add_option("-o,--output", o.output, "output .glb (appears only when complete)")->required();
  app.add_option("--count", o.count, "gallery: mesh nodes (default 12); forest: total instances (default 3000)")
      ->check(CLI::Range(int64_t(1), int64_t(100'000'000)));
  app.add_option("--seed", o.seed, "forest random seed (default 1)")->check(rtp::tools::unsigned_integer());
  CLI::Option* unique = app.add_flag("--unique", o.unique,
                                     "forest: every instance its own mesh, a copy of its source with every vertex moved by "
                                     "a per-copy hash (unique geometry, no GPU instancing)");
  CLI::Option* ground = app.add_flag("--ground-camera", o.ground_camera,
                                     "forest: a second camera (index 1) at eye level outside the grid, looking into the forest");
  app.add_option("--spacing", o.spacing, "grid spacing; meshes are normalized to size 1 (default 2)")
      ->check(rtp::tools::finite_range(1e-3, 1e5));
  app.add_option("--mesh", o.meshes, "source glTF file, repeatable (default: Suzanne, Lantern, BoomBox samples)")
      ->allow_extra_args(false);
  app.add_option("--allow-path", o.allow_paths, "also read --mesh files' external buffers from DIR (repeatable)");
  app.add_option("--refine", o.refine, "1-to-4 midpoint splits of every source triangle (default: forest 1, gallery 0)")
      ->check(CLI::Range(0, 8));
  CLI::Option* base =
      app.add_option("--base", o.base, "far only: gallery (default) or forest")->check(CLI::IsMember({"gallery", "forest"}));
  try {
    app.parse(argc, argv);
    if (base->count() > 0 && o.kind != "far") throw CLI::ValidationError("--base", "only applies to kind 'far'");
    if (unique->count() > 0 && o.kind != "forest") throw CLI::ValidationError("--unique", "only applies to kind 'forest'");
    if (ground->count() > 0 && o.kind != "forest") throw CLI::ValidationError("--ground-camera", "only applies to kind 'forest'");
  } catch (const CLI::ParseError& e) {
    return rtp::tools::parse_error_exit(app, e, "rtpack-make-scene", argc, argv);
  }
  try {
    return run(o);
  } catch (const Error& e) {
    std::cerr << "rtpack-make-scene: error: " << e.what() << "\n";
    return int(e.code());
  } catch (const std::exception& e) {
    std::cerr << "rtpack-make-scene: internal error: " << e.what() << "\n";
    return int(ExitCode::kInternal);
  }
}
