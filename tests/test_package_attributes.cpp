// Vertex attributes (rtpack-convert --attributes normal,uv): imported from every encoding of a real
// file, carried corner by corner into separate per-chunk streams, interpolated at each traced hit ray
// by ray against the source Scene, absent unless asked for, and every tampering named by --verify.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "cluster/cluster.h"
#include "formats/chunk.h"
#include "gltf_builder.h"
#include "mesh/prepare.h"
#include "oracle/rays.h"
#include "reader/attribute_lookup.h"
#include "layout/chunk_io.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "package/write_package.h"
#include "package_patch.h"
#include "scene/import.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

namespace fs = std::filesystem;

const std::string kLantern = "samples/khronos/Lantern/";

Scene load(const std::string& path, bool attributes = true, bool prepare = true) {
  ImportOptions o;
  o.normals = o.uvs = attributes;
  Scene s = import_gltf(path[0] == '/' ? path : (source_dir() / path).string(), o);
  if (prepare) prepare_scene(s, {});
  return s;
}

std::string write(const Scene& s, const fs::path& p, uint64_t target, int zstd = 9, int w = 8) {
  ClusterOptions co;
  co.chunk_target = target;
  ConvertOptions cv;
  cv.width = w;
  cv.leaf_width = w == 16 ? 8 : w;
  cv.zstd_level = zstd;
  write_package(s, plan_batching_points(s, co), p.string(), cv);
  return p.string();
}

struct ToolRun {
  int code;
  std::string out, err;
};
ToolRun run(const std::string& tool, const std::string& args, const fs::path& dir) {
  const std::string cmd =
      std::string(RTP_BINARY_DIR) + "/" + tool + " " + args + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "out"), slurp(dir / "err")};
}

// A scene whose instanced mesh (3 instances, one mirrored, so it goes to a mesh segment) has normals
// and uvs in one primitive and none in the other, plus a unique mesh with uvs only.
std::string attribute_scene(const fs::path& dir) {
  GltfBuilder b;
  std::vector<float> pos, nrm, uv;
  std::vector<uint16_t> idx;
  const int n = 12;  // a bumpy n x n grid
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      const float fx = float(x) / n, fy = float(y) / n, z = 0.1f * std::sin(6 * fx) * std::cos(5 * fy);
      pos.insert(pos.end(), {fx, fy, z});
      const float gx = -0.6f * std::cos(6 * fx) * std::cos(5 * fy), gy = 0.5f * std::sin(6 * fx) * std::sin(5 * fy);
      const float l = std::sqrt(gx * gx + gy * gy + 1);
      nrm.insert(nrm.end(), {gx / l, gy / l, 1 / l});
      uv.insert(uv.end(), {fx * 2, 1 - fy});
    }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const uint16_t a = uint16_t(y * (n + 1) + x), c = uint16_t(a + n + 1);
      idx.insert(idx.end(), {a, uint16_t(a + 1), c, uint16_t(a + 1), uint16_t(c + 1), c});
    }
  const int p = b.add_positions(pos), ni = b.add_accessor(b.add_view(nrm), 5126, "VEC3", nrm.size() / 3),
            ti = b.add_accessor(b.add_view(uv), 5126, "VEC2", uv.size() / 2), ii = b.add_indices(idx);
  const int p2 = b.add_positions({0, 0, 1, 1, 0, 1, 0, 1, 1.5f}), i2 = b.add_indices(std::vector<uint16_t>{0, 1, 2});
  b.j["meshes"].push_back({{"primitives",
                            {{{"attributes", {{"POSITION", p}, {"NORMAL", ni}, {"TEXCOORD_0", ti}}}, {"indices", ii}},
                             {{"attributes", {{"POSITION", p2}}}, {"indices", i2}}}}});
  b.j["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", p}, {"TEXCOORD_0", ti}}}, {"indices", ii}}}}});
  b.set_scene({b.add_node({{"mesh", 0}}), b.add_node({{"mesh", 0}, {"translation", {2, 0, 0}}}),
               b.add_node({{"mesh", 0}, {"scale", {-1, 2, 1}}, {"translation", {-1, 0, 0}}}),
               b.add_node({{"mesh", 1}, {"translation", {0, 2, 0}}, {"rotation", {0, 0, 0.3826834f, 0.9238795f}}})});
  return b.write_glb(dir / "attributes.glb");
}

// Every attribute entry of every attribute chunk, corner by corner, equals the Scene's attributes of
// the triangle it names (bit for bit). Returns the number of triangles checked per scene mesh.
void check_every_corner(const Scene& s, const std::string& path, std::map<uint32_t, uint64_t>& seen) {
  PackageReader r(path);
  for (size_t i = 0; i < r.toc().size(); ++i) {
    const uint32_t kind = r.toc()[i].kind;
    if (kind != uint32_t(fmt::ChunkKind::kSegmentAttributes) && kind != uint32_t(fmt::ChunkKind::kPointAttributes)) continue;
    const AlignedBytes b = r.read(i);
    ChunkView v(b.data(), b.size(), kind, "attributes");
    const auto entries = v.copy<fmt::AttributeEntry>(fmt::SectionType::kAttrEntries);
    const auto tris = v.copy<std::array<uint32_t, 3>>(fmt::SectionType::kAttrTriangles);
    const auto nrm = v.copy<Vec3f>(fmt::SectionType::kAttrNormals, false);
    const auto uv = v.copy<Vec2f>(fmt::SectionType::kAttrUvs, false);
    const auto ids = v.copy<uint32_t>(fmt::SectionType::kAttrTriIds, false);
    for (const fmt::AttributeEntry& e : entries) {
      if (e.triangle_count == 0) continue;
      EXPECT_LT(e.mesh, s.meshes.size());
      const Mesh& m = s.meshes[e.mesh];
      EXPECT_EQ(e.normal_first != fmt::kNoAttribute, !m.normals.empty()) << "mesh " << e.mesh;
      EXPECT_EQ(e.uv_first != fmt::kNoAttribute, !m.uvs.empty()) << "mesh " << e.mesh;
      const bool piece = kind == uint32_t(fmt::ChunkKind::kPointAttributes);
      EXPECT_EQ(e.tri_id_first != fmt::kNoAttribute, piece);
      for (uint32_t t = 0; t < e.triangle_count; ++t) {
        const uint32_t prim = piece ? ids.at(e.tri_id_first + t) : t;
        ASSERT_LT(prim, m.triangle_count());
        ++seen[e.mesh];
        for (int k = 0; k < 3; ++k) {
          const uint32_t sv = m.indices[3 * prim + size_t(k)], pv = tris.at(e.triangle_first + t)[size_t(k)];
          ASSERT_LT(pv, e.vertex_count);
          if (!m.normals.empty()) {
            ASSERT_EQ(nrm.at(e.normal_first + pv), m.normals[sv]) << "mesh " << e.mesh << " tri " << prim;
          }
          if (!m.uvs.empty()) {
            ASSERT_EQ(uv.at(e.uv_first + pv), m.uvs[sv]) << "mesh " << e.mesh << " tri " << prim;
          }
        }
      }
    }
  }
}

// Rays through the package in core; each hit's shading against the Scene in double: the corner
// attributes of (instance, prim) interpolated with (u, v), normals by the inverse transpose of the
// instance's local->world (inverted here in double, independently of the stored world->local).
void check_shading_ray_by_ray(const Scene& s, const std::string& path, bool normals, bool uvs, uint64_t& checked) {
  PackageReader r(path);
  const auto tracer = load_package_in_core(r);
  const AttributeLookup lookup(r);
  EXPECT_EQ(lookup.has_normals(), normals);
  EXPECT_EQ(lookup.has_uvs(), uvs);
  checked = 0;
  for (RayKind kind : {RayKind::kPrimary, RayKind::kRandom}) {
    const auto rays = generate_rays(s, kind, 4000, {});
    std::vector<fmt::Hit> hits(rays.size());
    tracer->closest(rays.data(), hits.data(), rays.size(), {});
    for (size_t i = 0; i < rays.size(); ++i) {
      const fmt::Shading got = lookup.shade(hits[i]);
      if (hits[i].instance == fmt::Hit::kNone) {
        for (float x : {got.normal[0], got.normal[1], got.normal[2], got.uv[0], got.uv[1]}) ASSERT_EQ(x, 0.0f);
        continue;
      }
      const Instance& in = s.instances.at(hits[i].instance);
      const Mesh& m = s.meshes[in.mesh];
      const double w[3] = {1.0 - hits[i].u - hits[i].v, hits[i].u, hits[i].v};
      double n[3] = {0, 0, 0}, t[2] = {0, 0};
      for (int k = 0; k < 3; ++k) {
        const uint32_t vi = m.indices[3 * size_t(hits[i].prim) + size_t(k)];
        if (!m.normals.empty())
          for (int a = 0; a < 3; ++a) n[a] += w[k] * m.normals[vi][a];
        if (!m.uvs.empty()) t[0] += w[k] * m.uvs[vi].x, t[1] += w[k] * m.uvs[vi].y;
      }
      // Inverse transpose by cofactors of the 3x3 part (sign and scale drop out in the normalization).
      const auto& M = in.transform.m;
      auto e = [&](int r_, int c_) { return double(M[4 * size_t(r_) + size_t(c_)]); };
      double cof[3][3];
      for (int r_ = 0; r_ < 3; ++r_)
        for (int c_ = 0; c_ < 3; ++c_)
          cof[r_][c_] = e((r_ + 1) % 3, (c_ + 1) % 3) * e((r_ + 2) % 3, (c_ + 2) % 3) -
                        e((r_ + 1) % 3, (c_ + 2) % 3) * e((r_ + 2) % 3, (c_ + 1) % 3);
      const double det = e(0, 0) * cof[0][0] + e(0, 1) * cof[0][1] + e(0, 2) * cof[0][2];
      double wn[3], len = 0;
      for (int a = 0; a < 3; ++a) {
        wn[a] = (cof[a][0] * n[0] + cof[a][1] * n[1] + cof[a][2] * n[2]) / det;
        len += wn[a] * wn[a];
      }
      len = std::sqrt(len);
      for (int a = 0; a < 3; ++a) {
        const double want = normals && !m.normals.empty() && len > 0 ? wn[a] / len : 0.0;
        ASSERT_NEAR(got.normal[a], want, 2e-5) << "ray " << i << " instance " << hits[i].instance << " prim " << hits[i].prim;
      }
      for (int a = 0; a < 2; ++a) {
        const double want = uvs && !m.uvs.empty() ? t[a] : 0.0;
        ASSERT_NEAR(got.uv[a], want, 1e-6 * (1 + std::abs(want))) << "ray " << i;
      }
      ++checked;
    }
  }
}

class Attributes : public ::testing::Test {
 protected:
  fs::path dir = temp_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  void TearDown() override { fs::remove_all(dir); }
};

// Every triangle corner of a scene in world space: position, unit normal (inverse transpose of the
// instance transform, by cofactors in double), uv.
struct Corner {
  double p[3], n[3], uv[2];
};
std::vector<std::array<Corner, 3>> world_corners(const Scene& s) {
  std::vector<std::array<Corner, 3>> out;
  for (const Instance& in : s.instances) {
    const Mesh& m = s.meshes[in.mesh];
    const auto& M = in.transform.m;
    auto e = [&](int r, int c) { return double(M[4 * size_t(r) + size_t(c)]); };
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      std::array<Corner, 3> tri{};
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = m.indices[3 * t + size_t(k)];
        Corner& c = tri[size_t(k)];
        double len = 0;
        for (int r = 0; r < 3; ++r) {
          c.p[r] = e(r, 0) * m.positions[v].x + e(r, 1) * m.positions[v].y + e(r, 2) * m.positions[v].z + e(r, 3);
          double cof[3];
          for (int j = 0; j < 3; ++j)
            cof[j] = e((r + 1) % 3, (j + 1) % 3) * e((r + 2) % 3, (j + 2) % 3) -
                     e((r + 1) % 3, (j + 2) % 3) * e((r + 2) % 3, (j + 1) % 3);
          c.n[r] = cof[0] * m.normals[v].x + cof[1] * m.normals[v].y + cof[2] * m.normals[v].z;
          len += c.n[r] * c.n[r];
        }
        for (double& x : c.n) x /= std::sqrt(len);
        c.uv[0] = m.uvs[v].x, c.uv[1] = m.uvs[v].y;
      }
      out.push_back(tri);
    }
  }
  return out;
}

// The same model stored three ways: float, KHR_mesh_quantization (int8 normals, integer uvs that
// only mean something through the material's KHR_texture_transform, meshes merged) and Draco. Each
// triangle is found in the float file by position (within the encoding's position step), then
// corner by corner the normals and uvs must agree within the encoding's quantization.
TEST_F(Attributes, ImportAgreesAcrossEncodingsOfARealFile) {
  const auto f = world_corners(load(kLantern + "glTF/Lantern.gltf", true, false));
  struct Enc {
    const char* path;
    double pos_tol, max_deg, max_uv;
  };
  // Quantized: 14-bit positions, int8 normals (≤ 1/127 per component), uv step 2.4e-4 (its texture
  // transform's scale). Draco: 11-bit positions, the file's normal and uv bits (measured ≤ 3°, 1e-3).
  for (const Enc& enc :
       {Enc{"glTF-Quantized/Lantern.gltf", 2.5e-3, 1.0, 2.5e-4}, Enc{"glTF-Draco/Lantern.gltf", 2e-2, 3.0, 1e-3}}) {
    SCOPED_TRACE(enc.path);
    auto g = world_corners(load(kLantern + enc.path, true, false));  // as imported: no triangle dropped
    ASSERT_EQ(g.size(), f.size());
    auto cx = [](const std::array<Corner, 3>& t) { return t[0].p[0] + t[1].p[0] + t[2].p[0]; };
    std::sort(g.begin(), g.end(), [&](const auto& a, const auto& b) { return cx(a) < cx(b); });
    double worst_deg = 0, worst_uv = 0;
    size_t unmatched = 0;
    for (const auto& t : f) {
      // Candidates: centroid x within 3 position steps; the match is the one whose corners all lie
      // within the step of t's corners (in some rotation of the corner order).
      auto lo = std::lower_bound(g.begin(), g.end(), cx(t) - 3 * enc.pos_tol, [&](const auto& a, double x) { return cx(a) < x; });
      double best = INFINITY;
      const std::array<Corner, 3>* match = nullptr;
      int match_rot = 0;
      for (auto it = lo; it != g.end() && cx(*it) <= cx(t) + 3 * enc.pos_tol; ++it)
        for (int rot = 0; rot < 3; ++rot) {
          double err = 0;  // the largest corner coordinate difference
          for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a) err = std::max(err, std::abs(t[size_t(k)].p[a] - (*it)[size_t((k + rot) % 3)].p[a]));
          if (err < best) best = err, match = &*it, match_rot = rot;
        }
      const bool found = match && best <= enc.pos_tol;
      for (int k = 0; found && k < 3; ++k) {
        const Corner &x = t[size_t(k)], &y = (*match)[size_t((k + match_rot) % 3)];
        const double dot = x.n[0] * y.n[0] + x.n[1] * y.n[1] + x.n[2] * y.n[2];
        worst_deg = std::max(worst_deg, std::acos(std::min(1.0, dot)) * 180 / M_PI);
        worst_uv = std::max({worst_uv, std::abs(x.uv[0] - y.uv[0]), std::abs(x.uv[1] - y.uv[1])});
      }
      unmatched += !found;
    }
    EXPECT_LT(unmatched, f.size() / 200) << "triangles not found by position";
    EXPECT_LT(worst_deg, enc.max_deg);
    EXPECT_LT(worst_uv, enc.max_uv);
    EXPECT_GT(worst_uv, 0.0) << "a lossy encoding cannot agree exactly: the comparison is not looking";
  }
  // Without --attributes nothing is loaded.
  for (const Mesh& m : load(kLantern + "glTF/Lantern.gltf", false).meshes) EXPECT_TRUE(m.normals.empty() && m.uvs.empty());
}

TEST_F(Attributes, EveryCornerOfEveryChunkMatchesTheScene) {
  const std::string glb = attribute_scene(dir);
  struct Case {
    std::string path;
    uint64_t target;
  };
  for (const Case& c :
       {Case{glb, 0}, Case{"samples/khronos/BoomBox/glTF/BoomBox.gltf", 700},
        Case{"samples/khronos/FlightHelmet/FlightHelmet-meshopt.glb", 5000}, Case{kLantern + "glTF-Quantized/Lantern.gltf", 0}}) {
    SCOPED_TRACE(c.path);
    const Scene s = load(c.path);
    for (int w : {4, 8, 16}) {
      const std::string p = write(s, dir / ("a" + std::to_string(w) + ".rtp"), c.target, 9, w);
      std::map<uint32_t, uint64_t> seen;
      check_every_corner(s, p, seen);
      for (size_t m = 0; m < s.meshes.size(); ++m) {
        const bool any = !s.meshes[m].normals.empty() || !s.meshes[m].uvs.empty();
        EXPECT_EQ(seen.count(uint32_t(m)) ? seen.at(uint32_t(m)) : 0, any ? s.meshes[m].triangle_count() : 0) << "mesh " << m;
      }
      const fmt::Header h = PackageReader(p).header();
      EXPECT_EQ(h.flags, fmt::kFlagNormals | fmt::kFlagUvs | fmt::kFlagDag);
      const ToolRun v = run("rtpack-inspect", p + " --verify", dir);
      EXPECT_EQ(v.code, 0) << v.out << v.err;
    }
  }
  // The synthetic scene exercises both chunk kinds: a segment (instanced mesh) and pieces.
  const Scene s = load(glb);
  PackageReader r(write(s, dir / "k.rtp", 0));
  EXPECT_GE(r.find(fmt::ChunkKind::kSegmentAttributes, 0), 0);
  EXPECT_GE(r.find(fmt::ChunkKind::kPointAttributes, 0), 0);
}

TEST_F(Attributes, ShadingAtEveryHitMatchesTheSceneRayByRay) {
  const std::string glb = attribute_scene(dir);
  uint64_t n = 0;
  const Scene s = load(glb);
  check_shading_ray_by_ray(s, write(s, dir / "a.rtp", 0), true, true, n);
  EXPECT_GT(n, 800u);
  const Scene boom = load("samples/khronos/BoomBox/glTF/BoomBox.gltf");
  check_shading_ray_by_ray(boom, write(boom, dir / "b.rtp", 700), true, true, n);
  EXPECT_GT(n, 1000u);
  // Stored without attributes: the lookup answers zeros.
  const Scene plain = load(glb, false);
  check_shading_ray_by_ray(plain, write(plain, dir / "c.rtp", 0), false, false, n);
  EXPECT_GT(n, 800u);
}

TEST_F(Attributes, NothingStoredUnlessAskedFor) {
  const std::string glb = attribute_scene(dir);
  const ToolRun a = run("rtpack-convert", glb + " -o " + (dir / "plain.rtp").string() + " -q", dir);
  ASSERT_EQ(a.code, 0) << a.err;
  const ToolRun b = run("rtpack-convert", glb + " -o " + (dir / "uv.rtp").string() + " --attributes uv -q", dir);
  ASSERT_EQ(b.code, 0) << b.err;
  PackageReader plain((dir / "plain.rtp").string()), uv((dir / "uv.rtp").string());
  EXPECT_EQ(plain.header().flags, fmt::kFlagDag);  // culling DAGs are on by default (2.0)
  EXPECT_EQ(uv.header().flags, fmt::kFlagUvs | fmt::kFlagDag);
  for (const auto& e : plain.toc()) EXPECT_TRUE(e.kind != 18 && e.kind != 19) << chunk_kind_name(e.kind);
  // Geometry chunks are byte-identical with and without attributes: the streams are separate.
  uint64_t geometry = 0;
  for (const auto& e : plain.toc())
    if (e.kind == 16 || e.kind == 17) {
      const int64_t j = uv.find(fmt::ChunkKind(e.kind), e.id);
      ASSERT_GE(j, 0);
      EXPECT_EQ(plain.read(size_t(&e - plain.toc().data())), uv.read(size_t(j)));
      ++geometry;
    }
  EXPECT_GE(geometry, 2u);
  // A file without any normal: a warning, and nothing stored.
  const ToolRun c = run(
      "rtpack-convert",
      (source_dir() / "samples/generated/gallery.glb").string() + " -o " + (dir / "g.rtp").string() + " --attributes normal,uv",
      dir);
  EXPECT_EQ(c.code, 0);
  EXPECT_NE(c.err.find("--attributes: no mesh has NORMAL; none stored"), std::string::npos) << c.err;
  EXPECT_EQ(PackageReader((dir / "g.rtp").string()).header().flags, fmt::kFlagDag);
  const ToolRun bad = run("rtpack-convert", glb + " -o " + (dir / "x.rtp").string() + " --attributes tangent", dir);
  EXPECT_EQ(bad.code, 1);
  EXPECT_FALSE(fs::exists(dir / "x.rtp"));
}

TEST_F(Attributes, TraceToolWritesShadingAndRefusesItWithAny) {
  const std::string glb = attribute_scene(dir);
  const std::string p = (dir / "a.rtp").string(), rays = (dir / "r.bin").string();
  ASSERT_EQ(run("rtpack-convert", glb + " -o " + p + " --attributes normal,uv -q", dir).code, 0);
  const ToolRun t = run("rtpack-trace",
                        p + " --make-camera-rays 48x32 --rays " + rays + " --hits " + (dir / "h.bin").string() + " --shading " +
                            (dir / "s.bin").string(),
                        dir);
  ASSERT_EQ(t.code, 0) << t.err;
  const std::string hb = slurp(dir / "h.bin"), sb = slurp(dir / "s.bin");
  ASSERT_EQ(hb.size() / sizeof(fmt::Hit), 48u * 32u);
  ASSERT_EQ(sb.size() / sizeof(fmt::Shading), 48u * 32u);
  PackageReader r(p);
  const AttributeLookup lookup(r);
  uint64_t lit = 0;
  for (size_t i = 0; i < 48 * 32; ++i) {
    fmt::Hit h;
    fmt::Shading got;
    std::memcpy(&h, hb.data() + i * sizeof h, sizeof h);
    std::memcpy(&got, sb.data() + i * sizeof got, sizeof got);
    const fmt::Shading want = lookup.shade(h);
    ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << "ray " << i;
    lit += got.normal[0] != 0 || got.normal[1] != 0 || got.normal[2] != 0;
  }
  EXPECT_GT(lit, 30u);
  const ToolRun any =
      run("rtpack-trace",
          p + " --rays " + rays + " --hits " + (dir / "o.bin").string() + " --any --shading " + (dir / "s2.bin").string(), dir);
  EXPECT_EQ(any.code, 1);
  EXPECT_NE(any.err.find("--shading needs closest hits"), std::string::npos) << any.err;
  EXPECT_FALSE(fs::exists(dir / "s2.bin"));
}

// Tampered attribute chunks (re-sealed, so only the invariants can tell): each names its chunk.
TEST_F(Attributes, VerifyNamesEveryTamperedAttributeChunk) {
  const std::string glb = attribute_scene(dir);
  const Scene s = load(glb);
  struct Edit {
    const char* what;
    fmt::ChunkKind kind;
    std::function<void(uint8_t*)> f;
    const char* message;
  };
  const std::vector<Edit> edits = {
      {"index", fmt::ChunkKind::kSegmentAttributes,
       [](uint8_t* c) { section<uint32_t>(c, fmt::SectionType::kAttrTriangles)[4] = 1u << 20; }, "vertex indices out of range"},
      {"normal", fmt::ChunkKind::kSegmentAttributes,
       [](uint8_t* c) { section<float>(c, fmt::SectionType::kAttrNormals)[7] = std::nanf(""); }, "normals neither unit length"},
      {"uv", fmt::ChunkKind::kPointAttributes, [](uint8_t* c) { section<float>(c, fmt::SectionType::kAttrUvs)[3] = INFINITY; },
       "non-finite texture coordinates"},
      {"ids", fmt::ChunkKind::kPointAttributes,
       [](uint8_t* c) {
         std::swap(section<uint32_t>(c, fmt::SectionType::kAttrTriIds)[0],
                   section<uint32_t>(c, fmt::SectionType::kAttrTriIds)[1]);
       },
       "not strictly ascending"},
      {"mesh", fmt::ChunkKind::kSegmentAttributes,
       [](uint8_t* c) { section<fmt::AttributeEntry>(c, fmt::SectionType::kAttrEntries)[0].mesh = 1; },
       "the geometry entry's are"},
      {"range", fmt::ChunkKind::kPointAttributes,
       [](uint8_t* c) { section<fmt::AttributeEntry>(c, fmt::SectionType::kAttrEntries)[0].vertex_count += 1000; },
       "outside the section"},
  };
  for (const Edit& e : edits) {
    SCOPED_TRACE(e.what);
    const std::string p = write(s, dir / (std::string(e.what) + ".rtp"), 0, 0);
    ASSERT_EQ(run("rtpack-inspect", p + " --verify", dir).code, 0);
    PackageReader r(p);
    const int64_t i = r.find(e.kind, 0);
    ASSERT_GE(i, 0);
    const std::string label = chunk_label(r.toc()[size_t(i)], size_t(i));
    patch_chunk(p, size_t(i), [&](uint8_t* c, size_t) { e.f(c); });
    const ToolRun v = run("rtpack-inspect", p + " --verify", dir);
    EXPECT_EQ(v.code, 3) << v.out;
    EXPECT_NE(v.out.find(label), std::string::npos) << v.out;
    EXPECT_NE(v.out.find(e.message), std::string::npos) << v.out;
  }
  // A package whose attribute chunk was dropped from the mesh table's promise: verify says so.
  const std::string p = write(s, dir / "flags.rtp", 0, 0);
  PackageReader r(p);
  const int64_t mi = r.find(fmt::ChunkKind::kMeshes, 0);
  patch_chunk(p, size_t(mi),
              [](uint8_t* c, size_t) { section<fmt::MeshInfo>(c, fmt::SectionType::kMeshTable)[1].flags ^= fmt::kMeshNormals; });
  const ToolRun v = run("rtpack-inspect", p + " --verify", dir);
  EXPECT_EQ(v.code, 3);
  EXPECT_NE(v.out.find("attributes disagree with the mesh table's flags for mesh 1"), std::string::npos) << v.out;
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
