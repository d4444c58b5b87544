#pragma once
// Small procedural meshes (tests, samples): every triangle gets its own source entry
// {primitive 0, triangle i} and the mesh one primitive {kNoIndex, kNoIndex}. Outward CCW winding.
#include <cstdint>

#include "scene/scene.h"

namespace rtp {

Mesh make_tetrahedron();                    // 4 vertices, 4 triangles, closed
Mesh make_cube(double half_size = 1);       // 8 vertices, 12 triangles, closed, centred at 0
Mesh make_icosphere(int subdivisions = 0);  // unit sphere: 20 * 4^s triangles, closed
Mesh make_grid(uint32_t nx, uint32_t ny);   // open quad grid in z = 0 over [0,nx]x[0,ny], 2*nx*ny tris

}  // namespace rtp
