// Ray file reader (see ray_file.h).
#include "trace/ray_file.h"

#include <filesystem>
#include <fstream>

#include "core/error.h"

namespace rtp {

std::vector<fmt::Ray> read_ray_file(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const uint64_t size = fs::file_size(path, ec);
  if (ec) throw Error(ExitCode::kInputIo, "cannot open ray file '" + path + "'");
  if (size % sizeof(fmt::Ray))
    fail_invalid("ray file '" + path + "': " + std::to_string(size) + " bytes is not a multiple of 32 (8 float32 per ray)");
  std::vector<fmt::Ray> rays(size / sizeof(fmt::Ray));
  std::ifstream f(path, std::ios::binary);
  if (!f.read(reinterpret_cast<char*>(rays.data()), std::streamsize(size)))
    throw Error(ExitCode::kInputIo, "cannot read ray file '" + path + "'");
  return rays;
}

}  // namespace rtp
