// Our own tinygltf implementation: the Debian libtinygltf is built without Draco, so we compile the
// header with KHR_draco_mesh_compression support and without any image decoding (see gltf_internal.h).
#define TINYGLTF_IMPLEMENTATION
#include "scene/gltf_internal.h"
