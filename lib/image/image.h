#pragma once
// Pictures of what a package holds: primary-ray hits shaded by normal, depth or instance, and PNG
// encoding (stb_image_write from Debian's libstb-dev). Used by rtpack-trace --image.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "formats/ray_file.h"

namespace rtp::image {

enum class Shade {
  kNormal,    // world normal as colour, 0.5 * (n + 1): stored normals when given, else from the hit positions
  kDepth,     // distance along the ray, near bright, over the hits' own range
  kInstance,  // a colour per scene instance, darkened by the angle to the ray so shapes stay readable
};

// Parses "normal", "depth" or "instance".
bool parse_shade(const std::string& name, Shade* out);

struct Rgb8 {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;  // width * height * 3, row-major, top row first
};

// Pixels where the ray missed (or was invalid).
inline constexpr std::array<uint8_t, 3> kBackground = {28, 30, 36};

// The flat colour of a scene instance (kInstance scales it by a factor in [0.3, 1]); never the background.
std::array<uint8_t, 3> instance_color(uint32_t instance);

// Shades width x height primary rays (row-major) and their closest hits. `shading` (per hit, may be
// null) holds stored normals (rtpack-trace --shading); a zero normal there falls back to the normal
// estimated from the world positions of neighbouring pixels that hit the same instance.
Rgb8 shade(const fmt::Ray* rays, const fmt::Hit* hits, int width, int height, Shade mode, const fmt::Shading* shading = nullptr);

// PNG bytes of the image (8-bit RGB).
std::vector<uint8_t> encode_png(const Rgb8& image);
// Binary PPM (P6, maxval 255) bytes of the image: what a renderer without an image library writes.
std::vector<uint8_t> encode_ppm(const Rgb8& image);
// encode_ppm for a path ending in ".ppm" (any case), else encode_png.
std::vector<uint8_t> encode_for_path(const Rgb8& image, const std::string& path);

}  // namespace rtp::image
