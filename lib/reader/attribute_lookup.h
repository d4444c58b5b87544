#pragma once
// Shading attributes of a hit, read from a package's attribute chunks (formats/SPEC.md §4.4): the
// interpolated world-space normal and TEXCOORD_0 of (instance, prim, u, v). In core: every
// attribute chunk is loaded once; lookups are allocation-free and thread-safe.
#include <cstdint>
#include <memory>
#include <vector>

#include "formats/ray_file.h"
#include "reader/reader.h"

namespace rtp {

class AttributeLookup {
 public:
  // Loads the instance table and every attribute chunk (throws rtp::Error naming a bad chunk).
  explicit AttributeLookup(const PackageReader& reader);
  ~AttributeLookup();
  bool has_normals() const;
  bool has_uvs() const;
  // Misses and meshes without attributes give zeros (formats/ray_file.h, fmt::Shading).
  fmt::Shading shade(const fmt::Hit& hit) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rtp
