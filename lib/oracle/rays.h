#pragma once
// Deterministic test and benchmark rays from a Scene (TESTING.md "Rays to test").
//
// Every ray depends only on (scene, kind, seed, index) and, for the kinds built on hits, on the answers
// of the `closest` callback: the same inputs give the same rays bit for bit, whatever the thread count.
// Randomness is a counter-based hash (splitmix64), not <random>, whose distributions differ across
// standard libraries.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "formats/ray_file.h"
#include "scene/scene.h"

namespace rtp {

enum class RayKind {
  kPrimary,  ///< camera rays over an image grid (4x4 tiles in scanline order, jittered), glTF cameras or an automatic one
  kRandom,   ///< incoherent rays through the bounds: from a sphere around the scene to a point inside,
             ///< or from a point inside in a uniform direction; direction lengths vary (0.25..4)
  kBounce,   ///< cosine-weighted diffuse bounces from primary hits (origin offset along the normal)
  kShadow,   ///< segments from primary hits toward a point light above the scene (tfar just short of it)
  kInside,   ///< uniform directions from the centroid of closed connected parts of mesh instances
  kShort,    ///< tfar (and sometimes tnear) inside the scene: a fraction of / beyond the first hit,
             ///< or past the first hit with tnear just behind it
};
inline constexpr RayKind kAllRayKinds[] = {RayKind::kPrimary, RayKind::kBounce, RayKind::kShadow,
                                           RayKind::kRandom,  RayKind::kInside, RayKind::kShort};

const char* ray_kind_name(RayKind kind);  // "primary", "random", "bounce", "shadow", "inside", "short"
std::optional<RayKind> parse_ray_kind(std::string_view name);

/// Closest-hit callback for the kinds built on hits (bounce, shadow, short): any correct tracer.
using ClosestFn = std::function<void(const fmt::Ray* rays, fmt::Hit* hits, size_t n)>;

struct RayGenOptions {
  uint64_t seed = 1;
  ClosestFn closest;  ///< required for kBounce, kShadow, kShort
};

/// What the generator did, for reports.
struct RayGenInfo {
  size_t rays = 0;
  size_t fallback = 0;  ///< rays replaced by kRandom rays because too few primary rays hit (bounce,
                        ///< shadow) or no mesh part is closed (inside: centroids of all parts used)
  std::string note;
};

/// `count` rays of `kind`. Throws std::invalid_argument when a hit-based kind has no callback.
/// Scenes without triangles (empty bounds) give rays around the origin.
std::vector<fmt::Ray> generate_rays(const Scene& scene, RayKind kind, size_t count, const RayGenOptions& options,
                                    RayGenInfo* info = nullptr);

/// The cameras primary rays come from: the scene's glTF cameras, or one automatic perspective camera
/// (45 degrees, aspect 1.5) looking at the centre of the bounds from (1, 0.6, 1.4), framing the 8 corners of the bounds.
std::vector<Camera> ray_cameras(const Scene& scene);

/// The point light of kShadow rays: centre + R (0.3, 1.2, 0.2), R = half the bounds diagonal.
Vec3d shadow_light(const Scene& scene);

}  // namespace rtp
