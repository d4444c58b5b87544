#pragma once
// Test helper: runs an rtpack tool as a subprocess with an exact argv (no shell quoting, so file
// names with any bytes work), extra environment variables, a timeout and the child's peak RSS.
// RTP_TOOL_DIR (environment) overrides the build directory, so the same tests can be pointed at
// older binaries to show that they fail there.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace rtp::test {

struct ToolResult {
  int code = -1;   // exit status, or -1 when killed by a signal / timed out
  int signal = 0;  // the terminating signal, if any
  bool timed_out = false;
  long max_rss_kib = 0;  // the tool's peak resident set (KiB); see wait_tool
  std::string out, err;
};

inline std::string tool_path(const std::string& tool) {
  const char* dir = std::getenv("RTP_TOOL_DIR");
  return std::string(dir && *dir ? dir : RTP_BINARY_DIR) + "/" + tool;
}

inline std::string slurp_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// Starts `tool args...` with stdout/stderr to `io_dir`/out and /err and `env` ("K=V") added.
inline pid_t spawn_tool(const std::string& tool, const std::vector<std::string>& args, const std::filesystem::path& io_dir,
                        const std::vector<std::string>& env = {}, bool peak_rss = false) {
  // With peak_rss, through rtp_peak_rss (tests/tools/peak_rss.cpp), which writes the tool's own peak RSS
  // to io_dir/rss; without it the tool is the direct child (signals sent to the pid reach the tool).
  std::filesystem::remove(io_dir / "rss");
  std::vector<std::string> argv_s;
  if (peak_rss) argv_s = {std::string(RTP_BINARY_DIR) + "/rtp_peak_rss", (io_dir / "rss").string()};
  argv_s.push_back(tool_path(tool));
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_s(env.begin(), env.end());
  for (char** e = environ; *e; ++e) env_s.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);
  const std::string out = (io_dir / "out").string(), err = (io_dir / "err").string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int i = ::open("/dev/null", O_RDONLY);
    if (o < 0 || e < 0 || i < 0) ::_exit(127);
    ::dup2(i, 0);
    ::dup2(o, 1);
    ::dup2(e, 2);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  return pid;
}

// Waits for `pid` (SIGKILL after `timeout_s`), collecting its exit and output.
inline ToolResult wait_tool(pid_t pid, const std::filesystem::path& io_dir, double timeout_s = 60) {
  ToolResult r;
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  struct rusage ru {};
  for (;;) {
    const pid_t w = ::wait4(pid, &status, WNOHANG, &ru);
    if (w == pid) break;
    if (std::chrono::steady_clock::now() > end) {
      ::kill(pid, SIGKILL);
      ::wait4(pid, &status, 0, &ru);
      r.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (WIFEXITED(status)) r.code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  // The tool's peak as rtp_peak_rss saw it when it ran the tool; wait4's own figure starts at the
  // forked test binary's resident pages, so it is only an upper bound.
  r.max_rss_kib = ru.ru_maxrss;
  if (std::ifstream rss(io_dir / "rss"); rss) rss >> r.max_rss_kib;
  r.out = slurp_file(io_dir / "out");
  r.err = slurp_file(io_dir / "err");
  return r;
}

inline ToolResult run_tool(const std::string& tool, const std::vector<std::string>& args, const std::filesystem::path& io_dir,
                           const std::vector<std::string>& env = {}, double timeout_s = 60) {
  return wait_tool(spawn_tool(tool, args, io_dir, env, true), io_dir, timeout_s);
}

}  // namespace rtp::test
