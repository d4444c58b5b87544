#pragma once
// Shared by the libFuzzer harnesses (tests/fuzz/, docs/fuzzing.md): the readers under test take paths,
// so each input is written to a file in a per-process work directory first.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <unistd.h>

#include "core/error.h"

namespace rtp::fuzz {

// $RTP_FUZZ_WORKDIR (scripts/fuzz puts the glTF seeds' .bin buffers there), else a fresh directory
// under $TMPDIR (default /tmp) made once per process.
inline const std::string& work_dir() {
  static const std::string dir = [] {
    if (const char* d = std::getenv("RTP_FUZZ_WORKDIR"); d && *d) return std::string(d);
    const char* t = std::getenv("TMPDIR");
    std::string templ = std::string(t && *t ? t : "/tmp") + "/rtp-fuzz-XXXXXX";
    if (!mkdtemp(templ.data())) std::abort();
    return templ;
  }();
  return dir;
}

// Writes `data` to work_dir()/name (replacing it) and returns the path.
inline std::string write_input(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = work_dir() + "/" + name + "." + std::to_string(getpid());
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) std::abort();
  return path;
}

// What counts as a clean rejection: rtp::Error (the tools map it to its exit code). Any other exception
// reaches the tools' "internal error" (exit 5); with RTP_FUZZ_STRICT=1 it aborts so libFuzzer saves it.
template <class F>
inline void run_guarded(F&& f) {
  try {
    f();
  } catch (const rtp::Error&) {
  } catch (const std::exception& e) {
    static const bool strict = [] {
      const char* s = std::getenv("RTP_FUZZ_STRICT");
      return s && *s == '1';
    }();
    if (strict) {
      std::fprintf(stderr, "fuzz: exception other than rtp::Error (tools exit 5): %s\n", e.what());
      std::abort();
    }
  }
}

}  // namespace rtp::fuzz
