#pragma once
// Process-wide glibc malloc settings for the tools that convert (rtpack-convert, and rtpack-bench, which
// times the same pipeline): freed memory stays in the process for the next stage instead of going back
// to the kernel and being faulted in and zeroed again. By default glibc maps large blocks on their own
// (a threshold that adapts up to 32 MiB) and trims the heap top beyond 128 KiB; a convert frees and
// reallocates such blocks in every stage, and on a VM each fresh page costs a trap into the host.
// Measured (rtpack-convert, whole process, 5 runs each, this project's 2-core VM): FlightHelmet
// 0.32 -> 0.22-0.31 s at 1 thread, forest-2k 0.47-0.49 -> 0.40-0.46 s at 2 threads, forest-1m 7.2-7.3 ->
// 6.8-7.0 s at 2 threads, peak RSS unchanged. The buffers of 4 MiB and more (core/aligned.h) have their
// own mappings and are not affected.
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace rtp::tools {

inline void keep_freed_memory() {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest: blocks below it come from the heaps
  mallopt(M_TRIM_THRESHOLD, 1 << 30);   // the heap top is returned only beyond 1 GiB free
#endif
}

}  // namespace rtp::tools
