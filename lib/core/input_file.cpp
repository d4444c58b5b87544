// Regular-file-only input opening and same-file detection (core/input_file.h).
#include "core/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "core/error.h"

namespace rtp {
namespace {

std::string label(const std::string& what, const std::string& path) {
  return (what.empty() ? std::string() : what + " ") + "'" + path + "'";
}

const char* type_name(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

}  // namespace

int open_input_file(const std::string& path, const std::string& what, int extra_flags, uint64_t* size) {
  const int base = O_RDONLY | O_CLOEXEC | O_NONBLOCK;
  int fd = ::open(path.c_str(), base | extra_flags);
  if (fd < 0 && errno == EINVAL && (extra_flags & O_DIRECT)) fd = ::open(path.c_str(), base | (extra_flags & ~O_DIRECT));
  if (fd < 0)
    throw Error(ExitCode::kInputIo,
                "cannot open " + label(what, path) + ": " + (errno == ENOENT ? "no such file" : std::strerror(errno)));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw Error(ExitCode::kInputIo, "cannot stat " + label(what, path) + ": " + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    if (S_ISDIR(st.st_mode)) throw Error(ExitCode::kInputIo, "cannot open " + label(what, path) + ": is a directory");
    throw Error(ExitCode::kInputIo,
                "cannot open " + label(what, path) + ": is not a regular file (" + type_name(st.st_mode) + ")");
  }
  const int fl = ::fcntl(fd, F_GETFL);
  if (fl < 0 || ::fcntl(fd, F_SETFL, fl & ~O_NONBLOCK) != 0) {
    const int e = errno;
    ::close(fd);
    throw Error(ExitCode::kInputIo, "cannot open " + label(what, path) + ": " + std::strerror(e));
  }
  if (size) *size = uint64_t(st.st_size);
  return fd;
}

void read_exact(int fd, uint64_t offset, void* out, size_t size, const std::string& path) {
  char* p = static_cast<char*>(out);
  while (size) {
    const ssize_t n = ::pread(fd, p, size, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw Error(ExitCode::kInputIo, "cannot read '" + path + "': " + std::strerror(errno));
    if (n == 0)
      throw Error(ExitCode::kInputIo, "cannot read '" + path + "': the file is shorter than it was (changed while read?)");
    p += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
}

std::string read_input_file(const std::string& path, const std::string& what) {
  uint64_t size = 0;
  const int fd = open_input_file(path, what, 0, &size);
  std::string out;
  try {
    out.resize(size_t(size));
    read_exact(fd, 0, out.data(), out.size(), path);
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
  return out;
}

void check_not_same_file(const std::string& input, const std::string& output) {
  struct stat a {
  }, b{};
  if (input.empty() || output.empty() || ::stat(input.c_str(), &a) != 0 || ::stat(output.c_str(), &b) != 0) return;
  if (a.st_dev == b.st_dev && a.st_ino == b.st_ino)
    throw Error(ExitCode::kUsage, "output '" + output + "' is the input file '" + input +
                                      "' (same device and inode): refusing to overwrite an input");
}

}  // namespace rtp
