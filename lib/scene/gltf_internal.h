#pragma once
// Internals of the glTF importer (not part of the public lib/scene interface).
// The same configuration in every translation unit (tinygltf_impl.cpp adds the implementation).
// Draco is decoded by draco.cpp, never by tinygltf (which trusts the payload's attribute ids).
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#define TINYGLTF_NOEXCEPTION
#define TINYGLTF_USE_CPP14
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wall"
#pragma GCC diagnostic ignored "-Wextra"
#include <tiny_gltf.h>
#pragma GCC diagnostic pop

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "scene/scene.h"

namespace rtp::gltf {

// A glTF document as loaded: our own JSON view (validated first) and tinygltf's model.
struct [[gnu::visibility("hidden")]] Document {
  std::string path;
  std::string base_dir;
  nlohmann::json json;
  tinygltf::Model model;
  std::vector<std::string> warnings;
  InputFiles input;  // the file, the external buffers approved for reading, the images (not read)
};

// Reads the file (a regular file only), checks the container (.glb header and chunks, file size), parses and validates
// the JSON (references, ranges, cycles, required extensions), decodes EXT_meshopt_compression
// buffer views and lets tinygltf (with Draco) build the model.
// External buffers must resolve (after percent-decoding, `..` and symbolic links) inside the glTF's
// directory or one of `allowed_dirs`; only regular files are read, and only once their size is checked.
Document load_document(const std::string& path, const std::vector<std::string>& allowed_dirs = {});

// For a file that is neither a .glb nor JSON text: "not a glTF file: this looks like an FBX file; …" with
// a conversion hint (lib/scene/sniff.cpp), judged by `head`, the file's first bytes; "" for JSON text.
std::string foreign_format_message(std::string_view head);

// Validation of the JSON alone (before tinygltf sees it). `buffer_sizes` are the real byte sizes
// of each buffer's data where known (external file, data URI, BIN chunk), or -1.
void validate_json(const nlohmann::json& doc, const std::vector<int64_t>& buffer_sizes);

// EXT_meshopt_compression: decode every compressed bufferView into its fallback buffer.
void decode_meshopt(Document& doc);

// KHR_draco_mesh_compression: strip_draco removes the extension from the JSON handed to tinygltf;
// decode_draco then decodes each compressed primitive with the draco library, checks its attribute
// ids and component counts against the accessors, and points those accessors at the decoded data.
void strip_draco(nlohmann::json& patched);
void decode_draco(Document& doc);

// Accessor reading with byteStride, normalization (KHR_mesh_quantization), sparse substitution.
// `pointer` is the JSON pointer used in error messages. Every read is bounds-checked against the
// real buffer data.
std::vector<Vec3f> read_vec3(const tinygltf::Model& model, int accessor, const std::string& pointer);
std::vector<uint32_t> read_indices(const tinygltf::Model& model, int accessor, const std::string& pointer);
// Reads `components` (1..4) per element as double (normalized integers mapped per the glTF spec).
std::vector<double> read_components(const tinygltf::Model& model, int accessor, int components, const std::string& pointer);

// Builds one Mesh from all triangle primitives of glTF mesh `gltf_mesh`.
// `normals` / `uvs`: also read NORMAL / TEXCOORD_0 (see ImportOptions).
Mesh build_mesh(const tinygltf::Model& model, int gltf_mesh, std::vector<std::string>& warnings, bool normals = false,
                bool uvs = false);

// Walks the node hierarchy of glTF scene `scene` (-1: every root node): appends instances (with
// EXT_mesh_gpu_instancing expanded) whose `mesh` is the *glTF* mesh index, and cameras.
void walk_nodes(const Document& doc, int scene, Scene& out);

}  // namespace rtp::gltf
