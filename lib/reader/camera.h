#pragma once
// Primary rays from a package's glTF cameras (metadata /cameras, written by rtpack-convert) or from an
// automatic camera framing the package's bounds: what rtpack-trace --make-camera-rays and --image trace.
#include <string>
#include <vector>

#include "formats/ray_file.h"
#include "reader/reader.h"

namespace rtp {

struct CameraRays {
  std::vector<fmt::Ray> rays;  // width x height, row-major, top row first; pixel centres
  std::string description;     // e.g. "camera 0 'Camera' (perspective, yfov 39.6 deg)" or "automatic camera"
};

// `camera` indexes the package's cameras; -1 takes the first one, or the automatic camera (from +z, 45
// degrees, looking at the centre of the bounds) when the package has none. A perspective camera keeps its
// yfov and takes the image's aspect ratio; an orthographic one its ymag. Throws rtp::Error (kUsage) for a
// camera the package does not have, and (kInputInvalid) for malformed camera metadata, naming the pointer.
CameraRays camera_rays(const PackageReader& reader, int width, int height, int camera = -1);

// A camera's world transform (row-major 3x4, camera -> world) as the converter writes it: finite, within
// float range, and its 3x3 part a rotation (scale stripped: determinant +-1 within 1e-3). Throws
// rtp::Error (kInputInvalid) naming `pointer` (e.g. "chunk 0 (metadata): /cameras/1/world") otherwise.
void check_camera_world(const double m[12], const std::string& pointer);

// The number of glTF cameras in the package's metadata.
size_t camera_count(const PackageReader& reader);

}  // namespace rtp
