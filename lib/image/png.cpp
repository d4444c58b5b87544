// Image files: PNG with stb_image_write (Debian libstb-dev, implementation in libstb.so), and binary PPM.
#include <stb_image_write.h>

#include <cctype>

#include "core/error.h"
#include "image/image.h"

namespace rtp::image {

std::vector<uint8_t> encode_png(const Rgb8& image) {
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != size_t(image.width) * image.height * 3)
    throw Error(ExitCode::kInternal, "encode_png: image size and pixels disagree");
  std::vector<uint8_t> out;
  const int ok = stbi_write_png_to_func(
      [](void* ctx, void* data, int size) {
        auto* o = static_cast<std::vector<uint8_t>*>(ctx);
        o->insert(o->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
      },
      &out, image.width, image.height, 3, image.rgb.data(), image.width * 3);
  if (!ok) throw Error(ExitCode::kOutput, "PNG encoding failed");
  return out;
}

std::vector<uint8_t> encode_ppm(const Rgb8& image) {
  if (image.width <= 0 || image.height <= 0 || image.rgb.size() != size_t(image.width) * image.height * 3)
    throw Error(ExitCode::kInternal, "encode_ppm: image size and pixels disagree");
  const std::string head = "P6\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n255\n";
  std::vector<uint8_t> out(head.begin(), head.end());
  out.insert(out.end(), image.rgb.begin(), image.rgb.end());
  return out;
}

std::vector<uint8_t> encode_for_path(const Rgb8& image, const std::string& path) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : "";
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".ppm" ? encode_ppm(image) : encode_png(image);
}

}  // namespace rtp::image
