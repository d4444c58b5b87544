#pragma once
// The order of a ray's hits that every tracer and oracle reports (TESTING.md item 7): t, then instance,
// then primitive.
#include "formats/ray_file.h"

namespace rtp {

// For baseline code (the package tracer, the Embree oracle, tests); the ISA kernels keep their own
// copy (lib/trace/kernels/multi_hit.h) so nothing compiled with -mavx512* is shared with them.
inline bool hit_order_less(const fmt::Hit& a, const fmt::Hit& b) {
  return a.t != b.t ? a.t < b.t : (a.instance != b.instance ? a.instance < b.instance : a.prim < b.prim);
}

}  // namespace rtp
