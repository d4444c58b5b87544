// Atomic, leave-nothing-behind output files (core/output_file.h).
#include "core/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <system_error>

#include "core/background_sync.h"
#include "core/error.h"

namespace rtp {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail_output(const std::string& path, const std::string& why) {
  throw Error(ExitCode::kOutput, "cannot write '" + path + "': " + why);
}

const char* non_regular_kind(mode_t m) {
  if (S_ISDIR(m)) return "it is a directory";
  if (S_ISFIFO(m)) return "it is not a regular file (FIFO)";
  if (S_ISSOCK(m)) return "it is not a regular file (socket)";
  if (S_ISBLK(m)) return "it is not a regular file (block device)";
  return nullptr;  // regular file or character device
}

// Named temporaries of the O_TMPFILE fallback (and of the instant between linking a finished file
// to a fresh name and renaming it), removed by the signal handler. Async-signal-safe: fixed slots,
// written before the handler can see them.
constexpr int kSlots = 16;
constexpr size_t kPathMax = 4096;
char g_paths[kSlots][kPathMax];
std::atomic<bool> g_used[kSlots];
std::mutex g_install;
bool g_installed = false;

extern "C" void remove_temporaries_and_die(int sig) {
  for (int i = 0; i < kSlots; ++i)
    if (g_used[i].load()) ::unlink(g_paths[i]);
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  ::raise(sig);
}

void install_handlers() {
  std::lock_guard<std::mutex> lock(g_install);
  if (g_installed) return;
  g_installed = true;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler != SIG_DFL || (old.sa_flags & SA_SIGINFO)) continue;
    struct sigaction sa {};
    sa.sa_handler = remove_temporaries_and_die;
    sigemptyset(&sa.sa_mask);
    ::sigaction(sig, &sa, nullptr);
  }
}

std::mutex g_slots;  // registration from several threads; the handler only reads

int register_temporary(const std::string& path) {
  if (path.empty() || path.size() >= kPathMax) return -1;
  install_handlers();
  std::lock_guard<std::mutex> lock(g_slots);
  for (int i = 0; i < kSlots; ++i)
    if (!g_used[i].load()) {
      std::memcpy(g_paths[i], path.c_str(), path.size() + 1);
      g_used[i].store(true);  // the path is complete before the handler can see the slot
      return i;
    }
  return -1;  // more than kSlots at once: still removed on destruction, just not on a signal
}

void unregister_temporary(int slot) {
  std::lock_guard<std::mutex> lock(g_slots);
  if (slot >= 0) g_used[slot].store(false);
}

int slot_of(const std::string& path) {
  std::lock_guard<std::mutex> lock(g_slots);
  for (int i = 0; i < kSlots; ++i)
    if (g_used[i].load() && path == g_paths[i]) return i;
  return -1;
}

std::string unique_suffix() {
  static std::atomic<uint64_t> counter{0};
  return std::to_string(::getpid()) + "-" + std::to_string(counter++);
}

}  // namespace

void check_output_path(const std::string& path) {
  if (path.empty()) throw Error(ExitCode::kOutput, "no output path");
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (const char* bad = non_regular_kind(st.st_mode)) fail_output(path, bad);
    if (::access(path.c_str(), W_OK) != 0)
      fail_output(path, S_ISCHR(st.st_mode) ? "the device is not writable" : "the existing file is not writable");
    if (S_ISCHR(st.st_mode)) return;  // written in place
  }
  std::error_code ec;
  const fs::path dir = fs::absolute(path, ec).parent_path();
  if (!fs::is_directory(dir, ec)) fail_output(path, "no directory " + dir.string());
  if (::access(dir.c_str(), W_OK) != 0) fail_output(path, "directory " + dir.string() + " is not writable");
}

OutputFile::OutputFile(const std::string& path) : path_(path) {
  if (path.empty()) throw Error(ExitCode::kOutput, "no output path");
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (const char* bad = non_regular_kind(st.st_mode)) fail_output(path, bad);
    if (S_ISCHR(st.st_mode)) {
      device_ = true;
      fd_ = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd_ < 0) fail_output(path, std::strerror(errno));
      return;
    }
  }
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec);
  dir_ = abs.parent_path().string();
  name_ = abs.filename().string();
  if (name_.empty() || name_ == "." || name_ == "..") fail_output(path, "not a file name");
  dir_fd_ = ::open(dir_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir_fd_ < 0) fail_output(path, "directory " + dir_ + ": " + std::strerror(errno));
  const char* no_tmpfile = std::getenv("RTP_TEST_NO_O_TMPFILE");
  if (!(no_tmpfile && *no_tmpfile && std::strcmp(no_tmpfile, "0") != 0)) {
    fd_ = ::openat(dir_fd_, ".", O_TMPFILE | O_WRONLY | O_CLOEXEC, 0644);
    if (fd_ >= 0) return;
    if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL && errno != ENOENT) {
      const int e = errno;
      ::close(dir_fd_);
      fail_output(path, std::strerror(e));
    }
  }
  // Fallback: a hidden named temporary, removed on destruction and on SIGINT/SIGTERM/SIGHUP.
  std::string tmpl = dir_ + "/." + name_ + ".tmp-" + std::to_string(::getpid()) + "-XXXXXX";
  fd_ = ::mkostemp(tmpl.data(), O_CLOEXEC);
  if (fd_ < 0) {
    const int e = errno;
    ::close(dir_fd_);
    fail_output(path, std::strerror(e));
  }
  ::fchmod(
      fd_, 0644 & ~[] {
        const mode_t m = ::umask(0);
        ::umask(m);
        return m;
      }());
  named_tmp_ = tmpl;
  register_temporary(named_tmp_);
}

OutputFile::~OutputFile() {
  sync_.reset();  // its thread joined before the descriptor it flushes is closed
  if (fd_ >= 0) ::close(fd_);
  if (!named_tmp_.empty() && !committed_) {
    ::unlink(named_tmp_.c_str());
    unregister_temporary(slot_of(named_tmp_));
  }
  if (dir_fd_ >= 0) ::close(dir_fd_);
}

void OutputFile::write_at(uint64_t offset, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size) {
    const ssize_t n = ::pwrite(fd_, p, size, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) fail_output(path_, std::strerror(errno));
    if (n == 0) fail_output(path_, "no progress writing (device full?)");
    p += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
}

void OutputFile::start_writeback() {
  if (device_ || fd_ < 0 || no_sync_thread_) return;
  if (!sync_) {
    // Test hook RTP_TEST_FLUSH_FAILS=1: the background flushes fail with EIO.
    const char* fails = std::getenv("RTP_TEST_FLUSH_FAILS");
    const int fail_with = fails && *fails && std::strcmp(fails, "0") != 0 ? EIO : 0;
    try {
      sync_ = std::make_unique<BackgroundSync>(fd_, fail_with);
    } catch (const std::system_error&) {  // no thread to be had: commit's fsync does it all
      no_sync_thread_ = true;
      return;
    }
  }
  sync_->request();
}

void OutputFile::set_size(uint64_t size) {
  if (!device_ && ::ftruncate(fd_, off_t(size)) != 0) fail_output(path_, std::strerror(errno));
}

void OutputFile::link_into_place() {
  if (!named_tmp_.empty()) {
    const std::string tmp_name = fs::path(named_tmp_).filename().string();
    if (::renameat(dir_fd_, tmp_name.c_str(), dir_fd_, name_.c_str()) != 0) fail_output(path_, std::strerror(errno));
    unregister_temporary(slot_of(named_tmp_));
    return;
  }
  const std::string proc = "/proc/self/fd/" + std::to_string(fd_);
  auto link_as = [&](const std::string& name) {
    if (::linkat(AT_FDCWD, proc.c_str(), dir_fd_, name.c_str(), AT_SYMLINK_FOLLOW) == 0) return 0;
    if (errno == EEXIST) return EEXIST;
    const int proc_errno = errno;  // no /proc: AT_EMPTY_PATH (needs CAP_DAC_READ_SEARCH)
    if (::linkat(fd_, "", dir_fd_, name.c_str(), AT_EMPTY_PATH) == 0) return 0;
    return errno == EEXIST ? EEXIST : proc_errno;
  };
  // No previous output: link straight to the name (no temporary name at any instant).
  int e = link_as(name_);
  if (e == 0) return;
  if (e != EEXIST) fail_output(path_, std::strerror(e));
  // A previous output: link to a fresh hidden name, then rename over it (atomic replacement).
  const std::string tmp_name = "." + name_ + ".tmp-" + unique_suffix();
  const int slot = register_temporary(dir_ + "/" + tmp_name);
  e = link_as(tmp_name);
  if (e != 0) {
    unregister_temporary(slot);
    fail_output(path_, std::strerror(e));
  }
  if (::renameat(dir_fd_, tmp_name.c_str(), dir_fd_, name_.c_str()) != 0) {
    e = errno;
    ::unlinkat(dir_fd_, tmp_name.c_str(), 0);
    unregister_temporary(slot);
    fail_output(path_, std::strerror(e));
  }
  unregister_temporary(slot);
}

void OutputFile::commit() {
  if (committed_) return;
  if (sync_) {
    const int e = sync_->finish();
    sync_.reset();
    if (e != 0) fail_output(path_, std::strerror(e));
  }
  if (!device_ && ::fsync(fd_) != 0) fail_output(path_, std::strerror(errno));
  if (const char* hold = std::getenv("RTP_TEST_HOLD_OUTPUT"); hold && *hold) {
    const int m = ::open(hold, O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    if (m >= 0) ::close(m);
    for (int i = 0; i < 600; ++i) ::usleep(100000);
  }
  if (device_) {
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail_output(path_, std::strerror(errno));
    committed_ = true;
    return;
  }
  link_into_place();
  committed_ = true;
  ::fsync(dir_fd_);  // the new name is durable (best effort)
}

void write_output_file(const std::string& path, const void* data, size_t size) {
  OutputFile f(path);
  f.write_at(0, data, size);
  f.set_size(size);
  f.commit();
}

}  // namespace rtp
