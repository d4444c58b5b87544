#pragma once
// rtpack-bench's default mode: one ray kind's rays, prepared once for every timed configuration.
#include <cstddef>
#include <cstdint>

#include "bench_agreement.h"
#include "oracle/embree_oracle.h"
#include "oracle/rays.h"
#include "scene/scene.h"

namespace rtp::bench {

// `count` rays of `kind` (seeded; with hot_rays > 0 the first hot_rays repeated), Embree's robust stream
// answers as the reference, the rays it cannot take, how Embree is timed on them, and how many of
// Embree's answers on each timed path (packets, stream, one call per ray) disagree with that reference.
KindData make_kind(const Scene& scene, const EmbreeOracle& embree, RayKind kind, size_t count, uint64_t seed, size_t hot_rays);

}  // namespace rtp::bench
