// rtp_peak_rss RSS_FILE PROGRAM [ARGS...]: runs PROGRAM as a child of this small process and writes the
// child's peak resident set size (KiB, wait4's ru_maxrss) to RSS_FILE. tests/tool_run.h starts tools
// through it: a tool forked straight from the test binary would start with the test binary's resident
// pages (fork copies them, and exec keeps that high-water mark), so its own peak could not be seen.
// Exits with PROGRAM's exit status, or dies of the same signal; 127 when PROGRAM cannot be run.
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: rtp_peak_rss RSS_FILE PROGRAM [ARGS...]\n");
    return 127;
  }
  const pid_t pid = ::fork();
  if (pid < 0) return 127;
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);  // a timed-out test kills this process: the tool goes with it
    ::execv(argv[2], argv + 2);
    ::_exit(127);
  }
  int status = 0;
  struct rusage ru {};
  while (::wait4(pid, &status, 0, &ru) < 0) {}
  if (std::FILE* f = std::fopen(argv[1], "w")) {
    std::fprintf(f, "%ld\n", ru.ru_maxrss);
    std::fclose(f);
  }
  if (WIFSIGNALED(status)) {
    ::signal(WTERMSIG(status), SIG_DFL);
    ::raise(WTERMSIG(status));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 127;
}
