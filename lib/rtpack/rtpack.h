#pragma once
// rtpack reader library: the public API (installed as <rtpack/rtpack.h>, linked as rtpack::reader).
//
//   find_package(rtpack CONFIG REQUIRED)
//   target_link_libraries(app PRIVATE rtpack::reader)
//
//   rtpack::Package pkg = rtpack::Package::open("scene.rtp");   // checks header, TOC, every chunk
//   std::vector<rtpack::Hit> hits(rays.size());
//   pkg.trace(rays.data(), hits.data(), rays.size());           // closest hits, all cores
//
// Everything here is plain data and one handle; the package's own layout (formats/SPEC.md) stays inside
// the library. A hostile or damaged file never crashes it: every failure is an rtpack::Error whose
// message names the file, the chunk and what is wrong, and whose code() is the tools' exit code.
// Thread-safety: a Package is immutable after open(); trace(), occluded() and shade() may be called from
// any number of threads at once (on a package opened out of core they take turns).
//
// Out of core (docs/library.md "Out of core"): Package::open(path, {.memory_budget = bytes}) keeps only
// the top level, the descriptors and the culling DAGs resident and loads batching points and mesh
// segments through a cache of that many bytes; a RayStream (Package::stream) batches a renderer's rays
// at batching points and hands their hits back to a callback that may submit the next rays of its paths.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(RTPACK_BUILDING_LIBRARY)
#define RTPACK_API __attribute__((visibility("default")))
#else
#define RTPACK_API
#endif

namespace rtpack {

// The library's version ("0.1.0") and the package format versions it reads ("2.0").
RTPACK_API const char* version();
RTPACK_API const char* format_version();

// 32 bytes, the layout of a ray file (formats/ray_file.h): origin, tnear, direction, tfar.
// A ray with NaN/Inf, tnear > tfar or tnear = +inf is invalid and returned as a miss.
struct Ray {
  float org[3];
  float tnear;
  float dir[3];
  float tfar;
};
// 20 bytes, the layout of a hit file: t (+inf on a miss), the scene instance, the triangle within the
// instance's mesh, barycentrics (hit point = (1-u-v)*v0 + u*v1 + v*v2). A miss has instance = prim = kNone.
struct Hit {
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  float t;
  uint32_t instance;
  uint32_t prim;
  float u;
  float v;
};
// Interpolated world-space normal and TEXCOORD_0 of a hit (zeros for a miss or a mesh without them).
struct Shading {
  float normal[3];
  float uv[2];
};
static_assert(sizeof(Ray) == 32 && sizeof(Hit) == 20 && sizeof(Shading) == 20);

struct Bounds {
  float lo[3];
  float hi[3];
};

// What the header says about the whole package.
struct Info {
  uint32_t format_major = 0, format_minor = 0;
  uint64_t package_bytes = 0;        // the file, as rtpack-convert and rtpack-inspect --json name it
  uint64_t unique_triangles = 0;     // stored triangles
  uint64_t instanced_triangles = 0;  // triangles as the scene shows them (instances expanded)
  uint64_t instances = 0;
  uint32_t bvh_width = 0, leaf_width = 0;
  Bounds bounds{};
  bool has_normals = false, has_uvs = false, has_dags = false;
  uint32_t cameras = 0;  // glTF cameras kept in the metadata
};

// One batching point (a cluster of objects traced as one unit; Molenaar 2019 §3.1).
struct BatchingPoint {
  Bounds bounds{};
  uint64_t unique_triangles = 0;
  uint64_t instanced_triangles = 0;
  uint32_t instances = 0;
  uint64_t stored_bytes = 0;  // its chunk on disk (compressed)
  uint64_t raw_bytes = 0;     // its chunk in memory
};

// One instanced mesh (stored once, referenced by instances).
struct Mesh {
  uint64_t triangles = 0;
  uint32_t segment = 0;  // the mesh-segment chunk holding it
};

enum class Isa { kBest, kScalar, kAvx2, kAvx512 };

struct TraceOptions {
  Isa isa = Isa::kBest;  // kBest: the widest this CPU runs; asking for more than it runs throws
  // Test batching points' culling DAGs first (same hits either way). Off: in core (this API's tracing) the
  // DAG test costs more than the BVH walks it saves (1.3-2.4x slower on the samples); it pays out of core.
  bool cull = false;
  int threads = 0;  // 0: all cores (TBB); 1: the calling thread only
  // trace(): each run of `packet` consecutive rays (4, 8 or 16, from the first ray) goes through the
  // package as one packet (Wu 2016); 0 traces ray by ray. The hits are the same bit for bit; packets
  // are faster on coherent runs such as camera_rays(..., PixelOrder::kTiles) and slower on scattered
  // rays. Isa::kScalar traces single rays; occluded() ignores it (single rays).
  int packet = 0;
};

// What a trace() or occluded() call did (summed over its threads), for a renderer's diagnostics.
struct TraceStats {
  uint64_t rays = 0;
  uint64_t invalid_rays = 0;           // returned as misses
  uint64_t batching_point_visits = 0;  // batching points whose box a ray entered within its interval
  uint64_t culled_visits = 0;          // of those, skipped because the culling DAG is empty along the ray
  // TraceOptions::packet: packets traced, the traced (not culled) batching-point visits made in them
  // (the others went alone: another octant, too few rays left), node tests by packets and their active
  // rays summed (SIMD utilization = packet_active_lanes / (packet_node_tests * packet), Wu 2016 §4.2.1).
  uint64_t packets = 0, packet_ray_visits = 0, packet_node_tests = 0, packet_active_lanes = 0;
};

// The order of camera_rays(): kRows is row-major, top row first (ray y * width + x is pixel (x, y));
// kTiles is 4x4 pixel tiles along a Hilbert curve, each tile's pixels along its own 4x4 curve, so runs
// of 4, 8 and 16 rays are 2x2, 2x4 and 4x4 pixel blocks (packets); tile_order() maps them to pixels.
enum class PixelOrder { kRows, kTiles };

// The pixel (y * width + x) of each ray of camera_rays(width, height, camera, PixelOrder::kTiles), in
// order: every pixel once. Throws rtpack::Error (code 1) for a size camera_rays() refuses.
RTPACK_API std::vector<uint32_t> tile_order(int width, int height);

class RTPACK_API Error : public std::runtime_error {
 public:
  Error(int code, const std::string& message) : std::runtime_error(message), code_(code) {}
  // 1 usage, 2 cannot read, 3 invalid package, 5 internal (the tools' exit codes).
  int code() const { return code_; }

 private:
  int code_;
};

// How Package::open reads a package.
struct OpenOptions {
  // The decompressed bytes of geometry (batching points and their mesh segments) held at once; 0 (and
  // memory_fraction 0): every chunk loaded and checked at open, in core. Below the largest batching point
  // with its mesh segments, open() throws Error code 1 naming that minimum.
  uint64_t memory_budget = 0;
  // The budget as a fraction (0, 1] of the package's geometry bytes (Package::geometry_bytes), when
  // memory_budget is 0; raised to the minimum when below it.
  double memory_fraction = 0;
  bool direct_io = false;  // read chunks with O_DIRECT (the page cache left out; falls back when unsupported)
};

// A ray submitted to a RayStream, 48 bytes: the ray, what the renderer needs to know it by, the kind.
struct StreamRay {
  Ray ray;
  uint64_t payload = 0;  // handed back unchanged with the answer
  uint32_t any = 0;      // 1: any hit (shadow ray: occluded in [tnear, tfar]?); 0: closest hit
  uint32_t reserved = 0;
};
// Its answer, 48 bytes. Everything shading needs is computed while the hit's chunk is resident.
struct StreamHit {
  Hit hit;            // closest hit, as trace() gives it (t = +inf and kNone on a miss and for any-hit rays)
  float normal[3];    // unit geometric normal of the hit triangle in world space, following its winding
                      // (cross(v1 - v0, v2 - v0)); zeros on a miss and for any-hit rays
  uint32_t occluded;  // any-hit rays: 1 when occluded; closest: 1 when hit
  uint64_t payload;   // the StreamRay's
};
static_assert(sizeof(StreamRay) == 48 && sizeof(StreamHit) == 48);

struct StreamOptions {
  uint32_t max_in_flight = 1u << 16;  // rays traced at once (their state is ~100 bytes each); more wait
  bool cull = true;                   // culling DAGs test rays before a point is loaded, while cheaper than loading it
  Isa isa = Isa::kBest;
  int threads = 0;  // 0: all cores (TBB); n: flush() runs in an arena of n threads
};

// What one RayStream::flush did.
struct StreamStats {
  uint64_t rays = 0;                   // rays traced (submitted before or during the flush)
  uint64_t rounds = 0;                 // sets of batching points made resident together
  uint64_t passes = 0;                 // tracing passes over a round's points (continuation rays join them)
  uint64_t batching_point_visits = 0;  // a ray reaching a batching point
  uint64_t culled_visits = 0;          // of those, answered by the point's DAG without loading it
  uint64_t dag_tests = 0;              // rays tested against a DAG before the point was loaded
  uint64_t chunks_loaded = 0;          // chunks read from the file (cache misses)
  uint64_t bytes_read = 0;             // their stored (compressed) bytes
  uint64_t raw_bytes_loaded = 0;       // their decompressed bytes
  uint64_t budget_bytes = 0;           // the cache's budget
  uint64_t peak_resident_bytes = 0;    // resident tables + cache + ray state, at the largest
  double seconds = 0, load_seconds = 0, trace_seconds = 0, walk_seconds = 0;
};

// Batched tracing for renderers (Molenaar 2019 §4.1, §4.3): submit rays, then flush() traces them, rays
// waiting at each batching point until it is loaded, and calls `on_hits` with the answered rays between
// tracing passes; rays it submits (a path's next bounce, its shadow ray) are traced in the same flush,
// with the points still resident. Answers are trace()'s and occluded()'s bit for bit, whatever the
// budget, threads, culling or order. Threading: submit() and flush() from one thread at a time;
// on_hits runs on flush()'s thread, one batch at a time, and may call submit() (and may itself run
// parallel work); it must not call flush(), nor trace()/occluded() on an out-of-core package (both throw).
// A flush that throws (a refused chunk, the callback's exception) leaves the stream empty.
class RTPACK_API RayStream {
 public:
  ~RayStream();
  RayStream(RayStream&&) noexcept;
  RayStream& operator=(RayStream&&) noexcept;
  void submit(const StreamRay* rays, size_t count);
  StreamStats flush(const std::function<void(const StreamHit* hits, size_t count)>& on_hits);

 private:
  friend class Package;
  struct Impl;
  explicit RayStream(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

class RTPACK_API Package {
 public:
  // Opens and checks the package (header, TOC, every chunk's CRC and structure) and loads it in core.
  // Throws rtpack::Error naming the file and the bad chunk.
  static Package open(const std::string& path);
  // In core, or out of core under a memory budget (OpenOptions): then open() reads and checks the
  // resident chunks, and every other chunk is checked as it loads; a bad one makes the call that loads
  // it throw rtpack::Error (code 3) naming it.
  static Package open(const std::string& path, const OpenOptions& options);
  ~Package();
  Package(Package&&) noexcept;
  Package& operator=(Package&&) noexcept;

  const Info& info() const;
  const std::vector<BatchingPoint>& batching_points() const;
  const std::vector<Mesh>& meshes() const;
  bool out_of_core() const;
  // The decompressed bytes of all batching points and mesh segments (what a budget is a part of), and
  // the smallest budget open() accepts.
  uint64_t geometry_bytes() const;
  uint64_t minimum_budget() const;
  // A ray stream over this package (which must outlive it). In core, the stream loads the geometry a
  // second time into its own cache the first time one is made (open out of core to avoid that).
  RayStream stream(const StreamOptions& options = {}) const;

  // Closest hit of each ray (hits[i] for rays[i]). Returns the number of rays that hit; fills *stats
  // when given.
  size_t trace(const Ray* rays, Hit* hits, size_t count, const TraceOptions& options = {}, TraceStats* stats = nullptr) const;
  // Any hit within [tnear, tfar]: occluded[i] = 1 or 0. Returns the number occluded.
  size_t occluded(const Ray* rays, uint8_t* occluded, size_t count, const TraceOptions& options = {},
                  TraceStats* stats = nullptr) const;
  // Interpolated normal and uv of each hit, from the package's attribute chunks (rtpack-convert
  // --attributes normal,uv); zeros where the package has none. The chunks load on the first call.
  void shade(const Hit* hits, Shading* out, size_t count) const;
  // Primary rays of the package's glTF camera `camera` (-1: the first, or an automatic camera framing
  // the bounds when there is none), width x height, in `order` (row-major, top row first by default).
  std::vector<Ray> camera_rays(int width, int height, int camera = -1, PixelOrder order = PixelOrder::kRows) const;

  struct Impl;  // internal (lib/rtpack/package_impl.h)

 private:
  explicit Package(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace rtpack
