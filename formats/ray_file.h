#pragma once
// Ray and hit records: the in-memory layout of the tracer and of the ray/hit files that outside
// tools exchange with rtpack-trace (formats/SPEC.md §5). Little-endian, no header.
#include <cstddef>
#include <cstdint>

namespace rtp::fmt {

// 32 bytes: origin, tnear, direction, tfar. The ray is the segment org + t*dir, t in [tnear, tfar].
// Directions need not be normalized. A ray with any NaN/Inf in org/dir, NaN tnear/tfar,
// tnear > tfar or tnear = +inf is invalid: it comes back as a miss and is counted.
struct Ray {
  float org[3];
  float tnear;
  float dir[3];
  float tfar;
};
static_assert(sizeof(Ray) == 32 && offsetof(Ray, tnear) == 12 && offsetof(Ray, dir) == 16 && offsetof(Ray, tfar) == 28);

// 20 bytes: t (+inf when missed), instance index, primitive (triangle index within the instance's
// mesh; Mesh::source maps it to glTF mesh/primitive/triangle), barycentrics u, v of the hit point
// p = (1-u-v)*v0 + u*v1 + v*v2. On a miss instance = primitive = 0xFFFFFFFF and u = v = 0.
struct Hit {
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  float t;
  uint32_t instance;
  uint32_t prim;
  float u;
  float v;
};
static_assert(sizeof(Hit) == 20 && offsetof(Hit, prim) == 8 && offsetof(Hit, v) == 16);

// A multi-hit file (rtpack-trace --multi-hit K) holds K Hit records per ray: its hits in (t, instance,
// prim) order, each triangle once, then misses (SPEC §5).

// 20 bytes per hit (rtpack-trace --shading, packages converted with --attributes): the shading
// normal (the stored vertex normals interpolated with u, v, taken to world space by the inverse
// transpose of the instance transform, normalized) and TEXCOORD_0 interpolated with u, v.
// normal = (0,0,0) on a miss, when the package has no normals for that mesh, or when the
// interpolated normal is zero; uv = (0,0) on a miss or without uvs.
struct Shading {
  float normal[3];
  float uv[2];
};
static_assert(sizeof(Shading) == 20 && offsetof(Shading, uv) == 12);

}  // namespace rtp::fmt
