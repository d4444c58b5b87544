#pragma once
// Reading a ray file (formats/ray_file.h, formats/SPEC.md §5): N x 32-byte fmt::Ray records, no header.
// The one reader rtpack-trace and the fuzz harness (tests/fuzz/fuzz_rays.cpp) share.
#include <string>
#include <vector>

#include "formats/ray_file.h"

namespace rtp {

// Throws Error(kInputIo) when the file cannot be opened or read, Error(kInputInvalid) when its size is
// not a multiple of 32 bytes. Invalid rays (NaN, tnear > tfar, ...) are returned as they are: the
// tracers count them and return misses.
std::vector<fmt::Ray> read_ray_file(const std::string& path);

}  // namespace rtp
