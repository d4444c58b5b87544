// rtpack-bench: one ray kind's rays and reference answers (bench_kinds.h).
#include "bench_kinds.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <vector>

#include "oracle/compare.h"

namespace rtp::bench {
namespace {

// Rays that differ in some byte.
size_t distinct_rays(const std::vector<fmt::Ray>& rays) {
  std::vector<std::array<uint32_t, 8>> keys(rays.size());
  static_assert(sizeof(fmt::Ray) == sizeof(std::array<uint32_t, 8>));
  for (size_t i = 0; i < rays.size(); ++i) std::memcpy(keys[i].data(), &rays[i], sizeof(fmt::Ray));
  std::sort(keys.begin(), keys.end());
  return size_t(std::unique(keys.begin(), keys.end()) - keys.begin());
}

}  // namespace

KindData make_kind(const Scene& scene, const EmbreeOracle& embree, RayKind kind, size_t count, uint64_t seed, size_t hot_rays) {
  KindData k;
  k.kind = kind;
  k.any = kind == RayKind::kShadow;
  RayGenOptions gen;
  gen.seed = seed;
  gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) { embree.closest(r, h, n); };
  k.rays = generate_rays(scene, kind, count, gen, &k.info);
  // --hot-rays: the same few rays over and over, so their nodes and leaves stay in cache and the branch
  // predictor learns their walks: what the tracers cost in instructions, without the cache misses and
  // mispredictions of distinct rays (the default run has both).
  if (hot_rays)
    for (size_t i = hot_rays; i < k.rays.size(); ++i) k.rays[i] = k.rays[i % hot_rays];
  k.distinct_rays = distinct_rays(k.rays);
  const size_t n = k.rays.size();
  k.ref_hits.resize(n);
  embree.closest(k.rays.data(), k.ref_hits.data(), n);
  k.skip = unsupported_mask(k.rays.data(), n);
  k.coherence = kind == RayKind::kPrimary ? RayCoherence::kCoherent : RayCoherence::kIncoherent;
  // Embree's answers on the path it is timed on are checked too (its packet path is not robust).
  std::vector<fmt::Hit> hits(n);
  std::vector<uint8_t> occ(n);
  CompareOptions copt;
  copt.scene = &scene;
  for (RayCoherence c : {k.coherence, RayCoherence::kSingle}) {  // both timed paths of incoherent rays
    if (c == RayCoherence::kSingle && k.coherence != RayCoherence::kIncoherent) continue;
    if (k.any) {
      embree.occluded(k.rays.data(), occ.data(), n, c);
      k.embree_timed_failures += check_any_hit(k.rays.data(), k.ref_hits.data(), occ.data(), n, copt, k.skip.data()).failures;
    } else {
      embree.closest(k.rays.data(), hits.data(), n, c);
      k.embree_timed_failures += compare_closest(k.rays.data(), k.ref_hits.data(), hits.data(), n, copt, k.skip.data()).failures;
    }
  }
  return k;
}

}  // namespace rtp::bench
