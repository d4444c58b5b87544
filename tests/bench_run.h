#pragma once
// Runs the built rtpack-bench with arguments and collects its stdout and exit code (tests of the
// bench modes; the table and progress on stderr are dropped).
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace rtp::test {

// Shell-quotes a path (appending, not operator+: GCC 12 warns -Wrestrict on "'" + std::string).
inline std::string q(const std::string& path) {
  std::string r = "'";
  r += path;
  r += "'";
  return r;
}

struct BenchRun {
  int code = -1;
  std::string out;  // stdout only
};

inline BenchRun run_bench(const std::string& args) {
  BenchRun r;
  std::string cmd = q(RTP_BINARY_DIR "/rtpack-bench");
  cmd += " ";
  cmd += args;
  cmd += " 2>/dev/null";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace rtp::test
