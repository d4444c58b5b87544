// PNG encoding with stb_image_write (Debian libstb-dev, implementation in libstb.so).
#include <stb_image_write.h>

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

}  // namespace rtp::image
