// TESTING.md item 7 (issue 11): the N closest hits of a ray equal the first N of the sorted all-hits
// list, ties ordered by (t, instance, primitive), no duplicates — for N in {1, 2, 8, 64}, every ISA,
// width and traversal order; node culling (Gribble 2016 §2.1) against the collect-everything baseline,
// bit for bit; N = 1 against the closest-hit tracer; through a package against in core; rtpack-trace
// --multi-hit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "core/error.h"
#include "gltf_builder.h"
#include "mesh/shapes.h"
#include "oracle/double_tests.h"
#include "oracle/rays.h"
#include "package/convert.h"
#include "reader/reader.h"
#include "tool_run.h"
#include "trace/out_of_core.h"
#include "trace/package_tracer.h"
#include "reader/ray_file.h"
#include "trace/trace.h"

namespace rtp::test {
namespace {
namespace RTP_UNITY_ID {  // unity builds: this file's own names (CMakeLists.txt)

constexpr uint32_t kNs[] = {1, 2, 8, 64};
constexpr int kLayers = 70;  // more than 64 surfaces along a vertical ray: N = 64 must cut the list

// The order written out once more here, independently of hit_order_less and the kernels' copy.
bool before(const fmt::Hit& a, const fmt::Hit& b) {
  return a.t != b.t ? a.t < b.t : (a.instance != b.instance ? a.instance < b.instance : a.prim < b.prim);
}

// Stacked grids (70 layers, one instance each), a grid whose triangles are all stored twice (ties by
// primitive), two instances of one sphere at the same place (ties by instance), and scaled, rotated,
// mirrored spheres elsewhere.
Scene layered_scene() {
  Scene s;
  s.meshes.push_back(make_grid(8, 8));
  Mesh twice = make_grid(8, 8);
  const size_t n = twice.indices.size();
  for (size_t k = 0; k < n; ++k) twice.indices.push_back(twice.indices[k]);
  twice.source.insert(twice.source.end(), twice.source.begin(), twice.source.end());
  s.meshes.push_back(twice);
  s.meshes.push_back(make_icosphere(2));
  auto place = [&](uint32_t mesh, double sx, double sy, double sz, double tx, double ty, double tz) {
    Instance in;
    in.mesh = mesh;
    in.transform(0, 0) = sx, in.transform(1, 1) = sy, in.transform(2, 2) = sz;
    in.transform(0, 3) = tx, in.transform(1, 3) = ty, in.transform(2, 3) = tz;
    in.mirrored = sx * sy * sz < 0;
    s.instances.push_back(in);
  };
  for (int k = 0; k < kLayers; ++k) place(0, 1, 1, 1, 0, 0, 0.25 * k);
  place(1, 1, 1, 1, 0, 0, 3.1);
  place(2, 1.5, 1.5, 1.5, 4, 4, 8);
  place(2, 1.5, 1.5, 1.5, 4, 4, 8);  // coincident with the previous one
  place(2, -1, 2, 0.5, 2, 6, 12);
  s.bounds = Aabb{};
  for (const Instance& in : s.instances)
    for (uint32_t v : s.meshes[in.mesh].indices) s.bounds.grow(in.transform.apply(to_d(s.meshes[in.mesh].positions[v])));
  return s;
}

// Mostly vertical rays through the stack (many hits), some with a shortened interval, and random ones.
std::vector<fmt::Ray> layered_rays(const Scene& s) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(0, 1);
  std::vector<fmt::Ray> rays;
  for (int i = 0; i < 1500; ++i) {
    const bool up = i % 2 == 0;
    fmt::Ray r{};
    r.org[0] = 8 * u(rng), r.org[1] = 8 * u(rng), r.org[2] = up ? -1.0f : 20.0f;
    float d[3] = {0.2f * (u(rng) - 0.5f), 0.2f * (u(rng) - 0.5f), up ? 1.0f : -1.0f};
    if (i % 7 == 0) d[0] = d[1] = 0;  // axis-parallel: hits the stored-twice grid's shared edges too
    const float len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int a = 0; a < 3; ++a) r.dir[a] = d[a] / len;
    r.tnear = i % 5 == 0 ? 2.0f * u(rng) : 0.0f;
    r.tfar = i % 3 == 0 ? 4.0f + 10.0f * u(rng) : INFINITY;
    rays.push_back(r);
  }
  RayGenOptions g;
  g.seed = 3;
  const auto random = generate_rays(s, RayKind::kRandom, 1500, g);
  rays.insert(rays.end(), random.begin(), random.end());
  return rays;
}

struct Multi {
  std::vector<fmt::Hit> hits;
  std::vector<uint32_t> counts;
};

// The properties of TESTING.md item 7 that hold for one answer on its own.
void expect_well_formed(const std::vector<fmt::Ray>& rays, const Multi& m, uint32_t N, const std::string& what) {
  for (size_t i = 0; i < rays.size(); ++i) {
    const fmt::Hit* h = m.hits.data() + i * N;
    ASSERT_LE(m.counts[i], N) << what << " ray " << i;
    for (uint32_t k = 0; k < m.counts[i]; ++k) {
      ASSERT_TRUE(h[k].t >= rays[i].tnear && h[k].t <= rays[i].tfar) << what << " ray " << i << " hit " << k;
      if (k > 0) {
        ASSERT_TRUE(before(h[k - 1], h[k])) << what << " ray " << i << ": hits " << k - 1 << ", " << k
                                            << " out of (t, instance, prim) order or a duplicate";
      }
    }
    for (uint32_t k = m.counts[i]; k < N; ++k)
      ASSERT_TRUE(h[k].t == INFINITY && h[k].instance == fmt::Hit::kNone) << what << " ray " << i << " entry " << k;
  }
}

template <int W>
void check_width(const Scene& scene, const std::vector<fmt::Ray>& rays) {
  const InCoreScene<W, W> bvh = InCoreScene<W, W>::build(scene);
  const size_t n = rays.size();
  std::vector<Multi> first_isa;  // per N: the scalar octant answer, which every other path must equal
  size_t truncated = 0, prim_ties = 0, instance_ties = 0;
  for (Isa isa : {Isa::kScalar, Isa::kAvx2, Isa::kAvx512}) {
    if (int(isa) > int(detect_isa())) continue;
    for (TraversalOrder order : {TraversalOrder::kOctantStack, TraversalOrder::kActiveList}) {
      const TraceOptions o{isa, order};
      std::vector<fmt::Hit> closest(n);
      trace_closest<W, W>(bvh.view(), rays.data(), closest.data(), n, o);
      std::vector<Multi> by_n;
      for (uint32_t N : kNs) {
        const std::string what =
            "W=" + std::to_string(W) + " " + isa_name(isa) + " " + order_name(order) + " N=" + std::to_string(N);
        Multi cull{std::vector<fmt::Hit>(n * N), std::vector<uint32_t>(n)};
        Multi all = cull;
        trace_multi<W, W>(bvh.view(), rays.data(), n, N, cull.hits.data(), cull.counts.data(), o);
        trace_multi<W, W>(bvh.view(), rays.data(), n, N, all.hits.data(), all.counts.data(), o, MultiHitMethod::kCollectAll);
        expect_well_formed(rays, cull, N, what);
        // Node culling returns exactly the first N of the sorted all-hits list.
        ASSERT_EQ(cull.counts, all.counts) << what;
        ASSERT_EQ(std::memcmp(cull.hits.data(), all.hits.data(), n * N * sizeof(fmt::Hit)), 0) << what;
        for (size_t i = 0; i < n; ++i) {
          if (N == 1) {  // the closest-hit tracer (checked against Embree elsewhere) is N = 1
            ASSERT_EQ(std::memcmp(&cull.hits[i], &closest[i], sizeof(fmt::Hit)), 0) << what << " ray " << i;
          }
          if (N == 64 && isa == Isa::kScalar && order == TraversalOrder::kOctantStack) {
            truncated += cull.counts[i] == 64 && rays[i].tfar == INFINITY && rays[i].tnear == 0;
            for (uint32_t k = 1; k < cull.counts[i]; ++k) {
              const fmt::Hit &a = cull.hits[i * N + k - 1], &b = cull.hits[i * N + k];
              prim_ties += a.t == b.t && a.instance == b.instance;
              instance_ties += a.t == b.t && a.instance != b.instance;
            }
          }
        }
        by_n.push_back(cull);
      }
      // A smaller N is a prefix of a larger one.
      for (size_t a = 0; a + 1 < by_n.size(); ++a)
        for (size_t i = 0; i < n; ++i) {
          const uint32_t na = kNs[a], nb = kNs[a + 1];
          ASSERT_EQ(by_n[a].counts[i], std::min(na, by_n[a + 1].counts[i])) << "ray " << i;
          ASSERT_EQ(std::memcmp(&by_n[a].hits[i * na], &by_n[a + 1].hits[i * nb], by_n[a].counts[i] * sizeof(fmt::Hit)), 0)
              << "ray " << i << ": N=" << na << " is not the prefix of N=" << nb;
        }
      if (first_isa.empty()) {
        first_isa = std::move(by_n);
      } else {
        for (size_t k = 0; k < by_n.size(); ++k)
          ASSERT_EQ(std::memcmp(first_isa[k].hits.data(), by_n[k].hits.data(), by_n[k].hits.size() * sizeof(fmt::Hit)), 0)
              << isa_name(isa) << " " << order_name(order) << " N=" << kNs[k] << " differs from scalar";
      }
    }
  }
  // The scene and rays exercise what the test is about.
  EXPECT_GT(truncated, 100u) << "rays with more than 64 hits";
  EXPECT_GT(prim_ties, 100u) << "equal t within one instance (the stored-twice grid)";
  EXPECT_GT(instance_ties, 10u) << "equal t across instances (the coincident spheres)";
  std::printf("[ multi-hit] W=%d: %zu rays, %zu cut at 64 hits, %zu ties by primitive, %zu ties by instance\n", W, n, truncated,
              prim_ties, instance_ties);
}

TEST(MultiHit, NClosestEqualTheSortedAllHitsPrefixOnEveryPath) {
  const Scene scene = layered_scene();
  const std::vector<fmt::Ray> rays = layered_rays(scene);
  check_width<4>(scene, rays);
  check_width<8>(scene, rays);
  check_width<16>(scene, rays);
}

// TESTING.md item 7 against a list no rtpack walk made: every triangle of every instance moved to world
// space in double and tested on its own (Moller-Trumbore in double, lib/oracle), no BVH and no float
// kernel; the test above compares node culling with rtpack's own collect-all walk, which shares both.
// Hit for hit with the N = 64 answer of every ISA: an rtpack hit is a reference hit of the same (instance,
// primitive) at the same t, or an edge tie (the triangle grown by 1e-4 about its centroid is hit); a
// reference hit that stays one when its triangle shrinks by 1e-4 and its t moves inside the interval, and
// that is nearer than rtpack's 64th hit, is in rtpack's list.
TEST(MultiHit, AgreesHitForHitWithADoubleBruteForceList) {
  const Scene scene = layered_scene();
  const std::vector<fmt::Ray> rays = layered_rays(scene);
  struct Tri {
    double v0[3], e1[3], e2[3];
  };
  std::vector<Tri> tris;
  std::vector<size_t> base;  // instance i's triangle p is tris[base[i] + p]
  for (const Instance& in : scene.instances) {
    base.push_back(tris.size());
    const Mesh& m = scene.meshes[in.mesh];
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      Vec3d p[3];
      for (int k = 0; k < 3; ++k) p[k] = in.transform.apply(to_d(m.positions[m.indices[3 * t + k]]));
      Tri tri;
      for (int a = 0; a < 3; ++a) tri.v0[a] = p[0][a], tri.e1[a] = p[1][a] - p[0][a], tri.e2[a] = p[2][a] - p[0][a];
      tris.push_back(tri);
    }
  }
  // The triangle scaled by `s` about its centroid, tested on [t0, t1].
  const auto hit = [](const Tri& tri, const fmt::Ray& r, double s, double t0, double t1, double* t) {
    double v0[3], e1[3], e2[3], o[3], d[3], u, v;
    for (int a = 0; a < 3; ++a) {
      const double c = tri.v0[a] + (tri.e1[a] + tri.e2[a]) / 3;
      v0[a] = c + (tri.v0[a] - c) * s, e1[a] = tri.e1[a] * s, e2[a] = tri.e2[a] * s;
      o[a] = r.org[a], d[a] = r.dir[a];
    }
    return oracle_detail::moller_trumbore(o, d, v0, e1, e2, t0, t1, t, &u, &v);
  };
  constexpr uint32_t N = 64;
  constexpr double kTol = 2e-4;  // 1e-5 of the scene's size (about 20)
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  const size_t n = rays.size();
  for (Isa isa : {Isa::kScalar, Isa::kAvx2, Isa::kAvx512}) {
    if (int(isa) > int(detect_isa())) continue;
    const TraceOptions o{isa, TraversalOrder::kOctantStack};
    Multi m{std::vector<fmt::Hit>(n * N), std::vector<uint32_t>(n)};
    trace_multi<8, 8>(bvh.view(), rays.data(), n, N, m.hits.data(), m.counts.data(), o);
    size_t compared = 0, ties = 0, cut = 0;
    for (size_t i = 0; i < n; ++i) {
      const fmt::Ray& r = rays[i];
      const fmt::Hit* h = m.hits.data() + i * N;
      std::vector<std::pair<size_t, double>> ref;  // (triangle, t) of every double hit
      for (size_t k = 0; k < tris.size(); ++k) {
        double t;
        if (hit(tris[k], r, 1.0, r.tnear, r.tfar, &t)) ref.push_back({k, t});
      }
      std::vector<size_t> mine(m.counts[i]);
      for (uint32_t k = 0; k < m.counts[i]; ++k) {
        ASSERT_LT(h[k].instance, base.size()) << isa_name(isa) << " ray " << i;
        mine[k] = base[h[k].instance] + h[k].prim;
        const auto it = std::find_if(ref.begin(), ref.end(), [&](const auto& e) { return e.first == mine[k]; });
        double t;
        if (it != ref.end()) {
          EXPECT_NEAR(h[k].t, it->second, kTol) << isa_name(isa) << " ray " << i << " hit " << k;
          ++compared;
        } else if (hit(tris[mine[k]], r, 1 + 1e-4, r.tnear - kTol, r.tfar + kTol, &t)) {
          ++ties;
        } else {
          ADD_FAILURE() << isa_name(isa) << " ray " << i << ": rtpack's hit " << k << " (instance " << h[k].instance << ", prim "
                        << h[k].prim << ", t " << h[k].t << ") is not near any double hit";
        }
      }
      const double last = m.counts[i] == N ? double(h[N - 1].t) : INFINITY;
      cut += m.counts[i] == N && ref.size() > N;
      for (const auto& [k, t_ref] : ref) {
        if (std::find(mine.begin(), mine.end(), k) != mine.end()) continue;
        double t;
        if (t_ref > last + kTol) continue;  // beyond rtpack's 64th: not asked for
        if (t_ref < last - kTol && hit(tris[k], r, 1 - 1e-4, r.tnear + kTol, r.tfar - kTol, &t))
          ADD_FAILURE() << isa_name(isa) << " ray " << i << ": the double hit on triangle " << k << " at t " << t_ref
                        << " is missing from rtpack's " << m.counts[i] << " hits";
        else
          ++ties;
      }
    }
    EXPECT_GT(compared, 50000u) << isa_name(isa);
    EXPECT_GT(cut, 100u) << isa_name(isa) << ": rays with more than 64 double hits";
    EXPECT_LE(ties, compared / 100) << isa_name(isa) << ": edge and interval ties";
    std::printf("[ multi-hit] %s: %zu hits the same as the double list, %zu edge or interval ties, %zu rays cut at 64\n",
                isa_name(isa), compared, ties, cut);
  }
}

TEST(MultiHit, RefusesNOutsideOneTo64) {
  const Scene scene = layered_scene();
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  fmt::Ray r{{1, 1, -1}, 0, {0, 0, 1}, INFINITY};
  std::vector<fmt::Hit> h(65);
  uint32_t c = 0;
  for (uint32_t bad : {0u, 65u}) {
    try {
      trace_multi<8, 8>(bvh.view(), &r, 1, bad, h.data(), &c, TraceOptions{});
      ADD_FAILURE() << "N = " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ExitCode::kUsage);
      EXPECT_NE(std::string(e.what()).find("outside [1, 64]"), std::string::npos) << e.what();
    }
  }
}

// Through a package of many batching points (each instance in one of them): the same N closest as in
// core over the converted scene, out of core at 100 % and 10 % budgets as in core, and rtpack-trace
// --multi-hit writes them (with --memory-budget too).
TEST(MultiHit, ThroughThePackageAndRtpackTrace) {
  const auto dir = temp_dir("multi_hit");
  ConvertSettings cs;
  cs.input = (source_dir() / "samples/generated/forest-small.glb").string();
  cs.output = (dir / "forest.rtp").string();
  cs.chunk_target = 20000;
  const Scene scene = convert_scene(cs).scene;
  const PackageReader reader(cs.output);
  const auto pkg = load_package_in_core(reader);
  ASSERT_GT(pkg->batching_points(), 4u);
  const InCoreScene<8, 8> bvh = InCoreScene<8, 8>::build(scene);
  RayGenOptions g;
  g.seed = 8;
  std::vector<fmt::Ray> rays = generate_rays(scene, RayKind::kRandom, 3000, g);
  g.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { pkg->closest(r, h, n, PackageTraceOptions{}); };
  const auto bounce = generate_rays(scene, RayKind::kBounce, 2000, g);
  rays.insert(rays.end(), bounce.begin(), bounce.end());
  const size_t n = rays.size();
  size_t many = 0;
  for (uint32_t N : kNs) {
    for (bool cull : {true, false}) {
      PackageTraceOptions o;
      o.isa = detect_isa();
      o.cull = cull;
      Multi p{std::vector<fmt::Hit>(n * N), std::vector<uint32_t>(n)}, c = p;
      pkg->multi(rays.data(), n, N, p.hits.data(), p.counts.data(), o);
      trace_multi<8, 8>(bvh.view(), rays.data(), n, N, c.hits.data(), c.counts.data(), o);
      expect_well_formed(rays, p, N, "package N=" + std::to_string(N));
      ASSERT_EQ(p.counts, c.counts) << "N=" << N;
      ASSERT_EQ(std::memcmp(p.hits.data(), c.hits.data(), n * N * sizeof(fmt::Hit)), 0) << "N=" << N;
      for (const char* budget : {"100%", "10%"}) {
        const uint64_t bytes = std::max(minimum_budget(reader), parse_memory_budget(budget, on_demand_bytes(reader)));
        Multi b{std::vector<fmt::Hit>(n * N), std::vector<uint32_t>(n)};
        const OutOfCoreStats st = open_out_of_core(reader, bytes)->multi(rays.data(), n, N, b.hits.data(), b.counts.data(), o);
        ASSERT_EQ(b.counts, p.counts) << "out of core at " << budget << ", N=" << N;
        ASSERT_EQ(std::memcmp(b.hits.data(), p.hits.data(), n * N * sizeof(fmt::Hit)), 0) << budget << ", N=" << N;
        EXPECT_LE(st.cache.peak_resident_bytes, bytes);
        if (std::string(budget) == "10%") {
          EXPECT_GT(st.rounds, 1u);
        }
      }
      if (N == 8)
        for (uint32_t k : p.counts) many += k >= 3;
    }
  }
  EXPECT_GT(many, 100u) << "rays that cross several trees";

  // rtpack-trace --multi-hit 8: K records per ray; the first is the closest hit of --hits.
  const std::string rays_path = (dir / "r.bin").string();
  std::FILE* f = std::fopen(rays_path.c_str(), "wb");
  ASSERT_TRUE(f);
  ASSERT_EQ(std::fwrite(rays.data(), sizeof(fmt::Ray), n, f), n);
  std::fclose(f);
  const std::string multi_path = (dir / "m.bin").string(), hits_path = (dir / "h.bin").string();
  const ToolResult m =
      run_tool("rtpack-trace", {cs.output, "--rays", rays_path, "--hits", multi_path, "--multi-hit", "8", "--json"}, dir);
  ASSERT_EQ(m.code, 0) << m.err;
  const ToolResult h = run_tool("rtpack-trace", {cs.output, "--rays", rays_path, "--hits", hits_path}, dir);
  ASSERT_EQ(h.code, 0) << h.err;
  const auto read = [](const std::string& p) {
    std::vector<fmt::Hit> v(std::filesystem::file_size(p) / sizeof(fmt::Hit));
    std::FILE* in = std::fopen(p.c_str(), "rb");
    EXPECT_EQ(std::fread(v.data(), sizeof(fmt::Hit), v.size(), in), v.size());
    std::fclose(in);
    return v;
  };
  const auto mh = read(multi_path), ch = read(hits_path);
  ASSERT_EQ(mh.size(), 8 * n);
  ASSERT_EQ(ch.size(), n);
  Multi expect{std::vector<fmt::Hit>(n * 8), std::vector<uint32_t>(n)};
  trace_multi<8, 8>(bvh.view(), rays.data(), n, 8, expect.hits.data(), expect.counts.data(), TraceOptions{detect_isa()});
  EXPECT_EQ(std::memcmp(mh.data(), expect.hits.data(), mh.size() * sizeof(fmt::Hit)), 0);
  for (size_t i = 0; i < n; ++i) ASSERT_EQ(std::memcmp(&mh[i * 8], &ch[i], sizeof(fmt::Hit)), 0) << "ray " << i;
  const std::string ooc_path = (dir / "o.bin").string();
  const ToolResult o = run_tool("rtpack-trace",
                                {cs.output, "--rays", rays_path, "--hits", ooc_path, "--multi-hit", "8", "--memory-budget",
                                 std::to_string(minimum_budget(reader))},
                                dir);
  ASSERT_EQ(o.code, 0) << o.err;
  EXPECT_EQ(read(ooc_path).size(), mh.size());
  EXPECT_EQ(std::memcmp(read(ooc_path).data(), mh.data(), mh.size() * sizeof(fmt::Hit)), 0) << "out of core";
  uint64_t total = 0;
  for (uint32_t k : expect.counts) total += k;
  const auto j = nlohmann::json::parse(m.out);
  EXPECT_EQ(j["multi_hit"]["k"], 8);
  EXPECT_EQ(j["multi_hit"]["hits"].get<uint64_t>(), total);
  for (const std::vector<std::string>& bad : {std::vector<std::string>{"--multi-hit", "0"},
                                              {"--multi-hit", "65"},
                                              {"--multi-hit", "4", "--any"},
                                              {"--multi-hit", "4", "--shading", (dir / "s.bin").string()}}) {
    std::vector<std::string> args = {cs.output, "--rays", rays_path, "--hits", (dir / "x.bin").string()};
    args.insert(args.end(), bad.begin(), bad.end());
    const ToolResult r = run_tool("rtpack-trace", args, dir);
    EXPECT_EQ(r.code, 1) << bad[0] << " " << bad[1] << ": " << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "x.bin"));
  }
  std::filesystem::remove_all(dir);
}

}  // namespace RTP_UNITY_ID
}  // namespace
}  // namespace rtp::test
