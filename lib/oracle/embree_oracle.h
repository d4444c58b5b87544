#pragma once
// The independent oracle and performance peer (TESTING.md "The oracle"): Embree 3 with
// RTC_SCENE_FLAG_ROBUST, built directly from an rtp::Scene, never from an rtpack BVH.
//
// One Embree triangle geometry (in its own Embree scene) per rtp::Mesh, placed once per rtp::Instance
// with an RTC_GEOMETRY_TYPE_INSTANCE whose geometry ID is the rtp instance index and whose transform
// is the instance's stored float 3x4 (RTC_FORMAT_FLOAT3X4_ROW_MAJOR). So Embree's instID[0] is the
// rtp instance, primID the triangle index within the mesh, and u, v follow formats/ray_file.h
// (p = (1-u-v) v0 + u v1 + v v2), which is Embree's own convention.
//
// The Debian Embree build keeps its assertions and aborts the process on rays it does not accept
// (ANCHORS.md): those are never passed to Embree. They come back as misses and are counted.
#include <cstddef>
#include <cstdint>

#include "formats/ray_file.h"
#include "scene/scene.h"

namespace rtp {

/// What the oracle can say about a ray before tracing it.
enum class RayStatus : uint8_t {
  kValid = 0,        ///< traced by Embree
  kInvalid = 1,      ///< invalid by formats/ray_file.h (NaN/Inf org/dir, NaN tnear/tfar, tnear > tfar,
                     ///< tnear = +inf): every tracer must answer a miss
  kUnsupported = 2,  ///< valid by our spec, but Embree cannot take it (|org| or |dir| component
                     ///< > 1.8e18, or tnear < 0): answered as a miss by the wrapper, and no reference
};

/// Classifies one ray (see RayStatus). Pure, cheap, usable to build skip masks for comparisons.
RayStatus ray_status(const fmt::Ray& ray);

/// Largest |component| of org/dir Embree accepts (its FLT_LARGE is 1.844e18; we stay a little below).
inline constexpr float kEmbreeMaxMagnitude = 1.8e18f;

/// Embree build quality (RTC_BUILD_QUALITY_*). kHigh enables spatial splits: use it for build-time
/// comparisons and as the performance peer.
enum class OracleQuality { kLow, kMedium, kHigh };
const char* quality_name(OracleQuality q);

/// How the rays of one call are laid out. kIncoherent: rtcIntersect1M / rtcOccluded1M streams with
/// RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT (single-ray traversal); kCoherent: closest hits in rtcIntersect16
/// packets of 16 consecutive valid rays loaded straight into SoA, with the COHERENT flag (for primary rays
/// in 4x4 tile order the fastest Embree path measured here), any hits in an rtcOccluded1M stream with the
/// COHERENT flag (rtcOccluded16 hangs in the Debian build, see embree_oracle.cpp).
/// kCoherent is for timing only: Embree's packet traversal is not robust (it misses a ray straight down
/// from gallery.glb's orthographic camera, direction (0, -1, -2.2e-16), that the stream path hits).
/// Reference answers always use kIncoherent. kSingle: one rtcIntersect1 / rtcOccluded1 call per ray
/// (INCOHERENT flag): in Embree 3.13.5 an incoherent 1M stream runs small hybrid packets, which one call
/// per ray beats on some scenes (rtpack-bench times both and compares with the faster).
enum class RayCoherence { kIncoherent, kCoherent, kSingle };

/// Counts returned by every query.
struct OracleStats {
  uint64_t rays = 0;         ///< all rays of the call
  uint64_t invalid = 0;      ///< RayStatus::kInvalid: answered as misses
  uint64_t unsupported = 0;  ///< RayStatus::kUnsupported: answered as misses, not a reference answer
};

/// Embree ROBUST scene over an rtp::Scene. Queries are const and thread-safe; they parallelize over
/// the rays with TBB in the caller's task arena (wrap calls in a tbb::task_arena to limit threads).
class EmbreeOracle {
 public:
  /// Builds the Embree scene. Throws rtp::Error(kInternal) if Embree reports an error.
  /// Meshes without triangles get no geometry; their instances never hit anything.
  /// gather_filter: scenes built with RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION, for multi_hit().
  explicit EmbreeOracle(const Scene& scene, OracleQuality quality = OracleQuality::kHigh, bool gather_filter = false);
  ~EmbreeOracle();
  EmbreeOracle(const EmbreeOracle&) = delete;
  EmbreeOracle& operator=(const EmbreeOracle&) = delete;

  /// Closest hit of rays[0..n) into hits[0..n) (t = +inf, instance = prim = kNone, u = v = 0 on a miss).
  OracleStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, RayCoherence coherence = RayCoherence::kIncoherent) const;

  /// Any hit in [tnear, tfar]: occluded[i] = 1 or 0 (0 for invalid/unsupported rays).
  OracleStats occluded(const fmt::Ray* rays, uint8_t* occluded, size_t n,
                       RayCoherence coherence = RayCoherence::kIncoherent) const;

  /// The N closest hits (N = max_hits), as Embree 3 users get them (Gribble 2016 §2.2, the
  /// reject-intersection callback of Amstutz et al. 2015): an intersection-context filter records every
  /// hit and rejects it so traversal goes on over [tnear, tfar]; then sorted by (t, instance, prim) and
  /// cut to N. Layout as rtp::trace_multi (trace.h). Needs gather_filter (else Error(kUsage)).
  OracleStats multi_hit(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts) const;

  /// Wall time of the build: copying the triangles into Embree buffers and committing every mesh
  /// scene and the instance scene (the same work InCoreScene::build does from an rtp::Scene).
  double build_seconds() const { return build_seconds_; }
  OracleQuality quality() const { return quality_; }
  uint64_t geometry_count() const { return geometries_; }

 private:
  struct Impl;
  Impl* impl_ = nullptr;
  double build_seconds_ = 0;
  OracleQuality quality_;
  bool gather_filter_ = false;
  uint64_t geometries_ = 0;
};

}  // namespace rtp
