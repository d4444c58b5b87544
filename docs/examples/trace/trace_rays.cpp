// trace_rays PACKAGE RAYS HITS [PACKET]: what a renderer does with rtpack's reader library. Opens a
// package, prints what it holds, traces a ray file (32-byte rays) and writes the closest hits (20-byte
// hits), the same files rtpack-trace --rays --hits reads and writes. PACKET (4, 8 or 16) traces each run
// of that many consecutive rays as one packet: worth it for coherent rays such as camera rays, same hits.
#include <rtpack/rtpack.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 4 && argc != 5) {
    std::fprintf(stderr, "usage: trace_rays PACKAGE RAYS HITS [PACKET]\n");
    return 1;
  }
  rtpack::TraceOptions options;
  if (argc == 5) options.packet = std::atoi(argv[4]);  // the library refuses sizes other than 0, 4, 8, 16
  try {
    const rtpack::Package pkg = rtpack::Package::open(argv[1]);
    const rtpack::Info& info = pkg.info();
    std::printf("rtpack %s, package format %u.%u: %llu unique triangles, %llu instances, %zu batching points, %zu meshes\n",
                rtpack::version(), info.format_major, info.format_minor, (unsigned long long)info.unique_triangles,
                (unsigned long long)info.instances, pkg.batching_points().size(), pkg.meshes().size());

    std::ifstream in(argv[2], std::ios::binary);
    if (!in) {
      std::fprintf(stderr, "%s: cannot open\n", argv[2]);
      return 2;
    }
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (bytes.size() % sizeof(rtpack::Ray) != 0) {
      std::fprintf(stderr, "%s: not a ray file (%zu bytes, not a multiple of 32)\n", argv[2], bytes.size());
      return 2;
    }
    std::vector<rtpack::Ray> rays(bytes.size() / sizeof(rtpack::Ray));
    std::copy(bytes.begin(), bytes.end(), reinterpret_cast<char*>(rays.data()));
    std::vector<rtpack::Hit> hits(rays.size());
    rtpack::TraceStats stats;
    const size_t hit = pkg.trace(rays.data(), hits.data(), rays.size(), options, &stats);
    std::printf("%zu rays, %zu hit\n", rays.size(), hit);
    if (options.packet)
      std::printf("%llu packets of %d; SIMD utilization %.1f%%\n", (unsigned long long)stats.packets, options.packet,
                  stats.packet_node_tests
                      ? 100.0 * double(stats.packet_active_lanes) / (double(stats.packet_node_tests) * options.packet)
                      : 0.0);

    std::ofstream out(argv[3], std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(hits.data()), std::streamsize(hits.size() * sizeof(rtpack::Hit)));
    if (!out.flush()) {
      std::fprintf(stderr, "%s: cannot write\n", argv[3]);
      return 4;
    }
    return 0;
  } catch (const rtpack::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return e.code();
  }
}
