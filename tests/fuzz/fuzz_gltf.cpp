// libFuzzer harness: the glTF importer (rtp::import_gltf) on one .glb or .gltf file, the way
// rtpack-convert reads its input. Inputs starting with the glb magic are written as .glb, others as
// .gltf; relative buffer URIs resolve in the work directory (scripts/fuzz copies the seeds' .bin files
// there). Any rtp::Error is a clean rejection; crashes, leaks, UB, hangs and huge allocations are bugs.
#include <cstring>

#include "fuzz_util.h"
#include "scene/import.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::string path = rtp::fuzz::write_input(glb ? "input.glb" : "input.gltf", data, size);
  rtp::fuzz::run_guarded([&] {
    rtp::ImportOptions options;
    options.normals = options.uvs = true;  // read every attribute the importer knows
    options.on_warning = [](const std::string&) {};
    (void)rtp::import_gltf(path, options);
  });
  return 0;
}
