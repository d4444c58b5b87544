#pragma once
// Runs one ray set through every ISA × traversal order of lib/trace, and every SIMD ISA × packet size
// (TraceOptions::packet: runs of consecutive rays as packets), and checks that all of them give the
// scalar octant-stack answer bit for bit (closest: t, instance, prim, u, v; any: the flag), and that
// any-hit agrees with closest-hit.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "trace/trace.h"

namespace rtp::trace_test {

struct PathResult {
  std::vector<fmt::Hit> hits;
  std::vector<uint8_t> occluded;
  TraceStats closest_stats, any_stats;
};

inline std::vector<TraceOptions> all_paths() {
  std::vector<TraceOptions> out;
  for (Isa isa : {Isa::kScalar, Isa::kAvx2, Isa::kAvx512}) {
    if (static_cast<int>(isa) > static_cast<int>(detect_isa())) continue;
    for (TraversalOrder o : {TraversalOrder::kOctantStack, TraversalOrder::kActiveList}) out.push_back({isa, o, 0});
    if (isa != Isa::kScalar)
      for (uint32_t p : {4u, 8u, 16u}) out.push_back({isa, TraversalOrder::kOctantStack, p});
  }
  return out;
}

inline std::string path_name(const TraceOptions& o) {
  return std::string(isa_name(o.isa)) + "/" + (o.packet ? "packets of " + std::to_string(o.packet) : order_name(o.order));
}

template <int W, int B>
PathResult run_path(const SceneView<W, B>& view, const std::vector<fmt::Ray>& rays, const TraceOptions& opt) {
  PathResult r;
  r.hits.resize(rays.size());
  r.occluded.assign(rays.size(), 7);
  r.closest_stats = trace_closest<W, B>(view, rays.data(), r.hits.data(), rays.size(), opt);
  r.any_stats = trace_any<W, B>(view, rays.data(), r.occluded.data(), rays.size(), opt);
  return r;
}

inline bool same_hit(const fmt::Hit& a, const fmt::Hit& b) { return std::memcmp(&a, &b, sizeof(fmt::Hit)) == 0; }

// Returns the scalar octant-stack result after checking every other path against it.
template <int W, int B>
PathResult check_all_paths(const SceneView<W, B>& view, const std::vector<fmt::Ray>& rays, const std::string& what) {
  const PathResult ref = run_path<W, B>(view, rays, {Isa::kScalar, TraversalOrder::kOctantStack, 0});
  for (size_t i = 0; i < rays.size(); ++i) {
    const bool hit = ref.hits[i].instance != fmt::Hit::kNone;
    EXPECT_EQ(ref.occluded[i], hit ? 1 : 0) << what << ": any-hit disagrees with closest-hit, ray " << i;
    if (!hit) {
      EXPECT_EQ(ref.hits[i].t, INFINITY);
      EXPECT_EQ(ref.hits[i].prim, fmt::Hit::kNone);
      EXPECT_EQ(ref.hits[i].u, 0.0f);
      EXPECT_EQ(ref.hits[i].v, 0.0f);
    }
  }
  for (const TraceOptions& opt : all_paths()) {
    const PathResult got = run_path<W, B>(view, rays, opt);
    const std::string path = what + " " + path_name(opt) + " W=" + std::to_string(W) + " B=" + std::to_string(B);
    EXPECT_EQ(got.closest_stats.rays, rays.size()) << path;
    EXPECT_EQ(got.closest_stats.invalid_rays, ref.closest_stats.invalid_rays) << path;
    EXPECT_EQ(got.any_stats.invalid_rays, ref.closest_stats.invalid_rays) << path;
    EXPECT_EQ(got.closest_stats.overflow_rays, 0u) << path;
    int bad = 0;
    for (size_t i = 0; i < rays.size() && bad < 5; ++i) {
      if (!same_hit(got.hits[i], ref.hits[i])) {
        ++bad;
        ADD_FAILURE() << path << " ray " << i << ": t " << got.hits[i].t << " vs " << ref.hits[i].t << ", instance "
                      << got.hits[i].instance << " vs " << ref.hits[i].instance << ", prim " << got.hits[i].prim << " vs "
                      << ref.hits[i].prim;
      }
      if (got.occluded[i] != ref.occluded[i]) {
        ++bad;
        ADD_FAILURE() << path << " ray " << i << ": occluded " << int(got.occluded[i]) << " vs " << int(ref.occluded[i]);
      }
    }
  }
  return ref;
}

}  // namespace rtp::trace_test
