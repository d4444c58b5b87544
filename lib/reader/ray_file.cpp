// Ray file reader (see ray_file.h).
#include "reader/ray_file.h"

#include <unistd.h>

#include "core/error.h"
#include "core/input_file.h"

namespace rtp {

std::vector<fmt::Ray> read_ray_file(const std::string& path) {
  uint64_t size = 0;
  const int fd = open_input_file(path, "ray file", 0, &size);  // regular files only, never blocks
  std::vector<fmt::Ray> rays;
  try {
    if (size % sizeof(fmt::Ray))
      fail_invalid("ray file '" + path + "': " + std::to_string(size) + " bytes is not a multiple of 32 (8 float32 per ray)");
    rays.resize(size / sizeof(fmt::Ray));
    read_exact(fd, 0, rays.data(), size, path);
  } catch (...) {
    ::close(fd);
    throw;
  }
  ::close(fd);
  return rays;
}

}  // namespace rtp
