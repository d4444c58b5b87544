#pragma once
// Process-wide glibc malloc settings for the tools that convert (rtpack-convert, and rtpack-bench, which
// times the same pipeline).
//
// Freed memory stays in the process for the next stage instead of going back to the kernel and being
// faulted in and zeroed again. By default glibc maps large blocks on their own (a threshold that adapts
// up to 32 MiB) and trims the heap top beyond 128 KiB; a convert frees and reallocates such blocks in
// every stage, and on a VM each fresh page costs a trap into the host. Measured (rtpack-convert, whole
// process, 5 runs each, this project's 2-core VM): FlightHelmet 0.32 -> 0.22-0.31 s at 1 thread,
// forest-2k 0.47-0.49 -> 0.40-0.46 s at 2 threads, forest-1m 7.2-7.3 -> 6.8-7.0 s at 2 threads, peak RSS
// unchanged.
//
// Transparent huge pages for malloc's heaps: where the kernel's THP mode is "madvise" (Debian's
// default), only ranges a program marks with madvise(MADV_HUGEPAGE) get 2 MiB pages. The buffers of
// 4 MiB and more (core/aligned.h) do that themselves; glibc (2.35 and later) does it for its own heaps
// when the tunable glibc.malloc.hugetlb=1 is set, which it reads once at start-up, so the tool sets it
// and executes itself again (same pid, same argv) before anything else runs. Measured (rtpack-convert
// forest-1m, 1 thread, this VM): 213804 -> 6633 minor page faults, 7.5-8.0 -> 5.0-5.3 s, same bytes.
// A GLIBC_TUNABLES that already names glibc.malloc.hugetlb is left as it is (=0 turns this off); under
// AddressSanitizer (its own allocator) and valgrind (an exec would leave the tool) nothing is changed.
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#ifdef __GLIBC__
#include <malloc.h>
#include <unistd.h>
#endif

namespace rtp::tools {

// What configure_malloc did, for -v: "on (...)", "off (why)" or "as GLIBC_TUNABLES sets it (...)".
inline std::string& huge_page_state() {
  static std::string s = "off (not configured)";
  return s;
}

// The kernel's THP mode, the bracketed word of /sys/kernel/mm/transparent_hugepage/enabled ("" if none).
inline std::string thp_mode() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string line;
  std::getline(f, line);
  const size_t a = line.find('['), b = line.find(']');
  return a != std::string::npos && b != std::string::npos && b > a ? line.substr(a + 1, b - a - 1) : std::string();
}

// Call first in main, before any allocation that matters and before any output: may re-execute the tool.
inline void configure_malloc([[maybe_unused]] char** argv) {
#ifdef __GLIBC__
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest: blocks below it come from the heaps
  mallopt(M_TRIM_THRESHOLD, 1 << 30);   // the heap top is returned only beyond 1 GiB free
  std::string& state = huge_page_state();
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (tunables && std::strstr(tunables, "glibc.malloc.hugetlb=")) {
    const char* v = std::strstr(tunables, "glibc.malloc.hugetlb=") + std::strlen("glibc.malloc.hugetlb=");
    const std::string value(v, std::strcspn(v, ":"));
    state = value == "1"   ? "on (glibc.malloc.hugetlb=1)"
            : value == "0" ? "off (GLIBC_TUNABLES sets glibc.malloc.hugetlb=0)"
                           : "as GLIBC_TUNABLES sets it (glibc.malloc.hugetlb=" + value + ")";
    return;
  }
#if defined(__SANITIZE_ADDRESS__) || defined(RTP_SANITIZED_BUILD)
  state = "off (sanitizer build: its own allocator)";
  return;
#endif
  const char* preload = std::getenv("LD_PRELOAD");
  if (preload && (std::strstr(preload, "vgpreload") || std::strstr(preload, "valgrind"))) {
    state = "off (under valgrind)";
    return;
  }
  const std::string mode = thp_mode();
  if (mode != "madvise") {
    state = "off (kernel THP mode '" + (mode.empty() ? std::string("unknown") : mode) + "')";
    return;
  }
  const std::string value = tunables && *tunables ? std::string(tunables) + ":glibc.malloc.hugetlb=1" : "glibc.malloc.hugetlb=1";
  if (::setenv("GLIBC_TUNABLES", value.c_str(), 1) == 0) {
    ::execv("/proc/self/exe", argv);  // returns only on failure
    if (tunables)
      ::setenv("GLIBC_TUNABLES", tunables, 1);
    else
      ::unsetenv("GLIBC_TUNABLES");
  }
  state = std::string("off (could not re-execute: ") + std::strerror(errno) + ")";
#endif
}

// The process's resident anonymous huge pages in MiB (/proc/self/smaps_rollup), -1 if unknown.
inline double anon_huge_pages_mib() {
  std::ifstream f("/proc/self/smaps_rollup");
  std::string key;
  while (f >> key) {
    if (key == "AnonHugePages:") {
      double kib = 0;
      f >> kib;
      return kib / 1024.0;
    }
    f.ignore(4096, '\n');
  }
  return -1;
}

}  // namespace rtp::tools
