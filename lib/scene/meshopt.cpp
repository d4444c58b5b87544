// EXT_meshopt_compression: decode compressed bufferViews (meshoptimizer's decoders) into the
// fallback buffer that tinygltf saw only as a placeholder.
#include <meshoptimizer.h>

#include "core/error.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {

void decode_meshopt(Document& doc) {
  using std::to_string;
  const nlohmann::json& j = doc.json;
  if (!j.contains("bufferViews")) return;
  for (size_t v = 0; v < j["bufferViews"].size(); ++v) {
    const nlohmann::json& bv = j["bufferViews"][v];
    if (!bv.contains("extensions") || !bv["extensions"].contains("EXT_meshopt_compression")) continue;
    const nlohmann::json& e = bv["extensions"]["EXT_meshopt_compression"];
    const std::string ptr = "/bufferViews/" + to_string(v) + "/extensions/EXT_meshopt_compression";
    // Ranges were validated against the declared sizes; re-check against the loaded data.
    const auto& src = doc.model.buffers[e["buffer"].get<size_t>()].data;
    auto& dst = doc.model.buffers[bv["buffer"].get<size_t>()].data;
    const size_t so = e.value("byteOffset", size_t(0)), sl = e["byteLength"].get<size_t>();
    const size_t dof = bv.value("byteOffset", size_t(0)), dl = bv["byteLength"].get<size_t>();
    const size_t count = e["count"].get<size_t>(), stride = e["byteStride"].get<size_t>();
    if (so + sl > src.size() || dof + dl > dst.size()) fail_invalid(ptr + ": data out of range");
    const std::string mode = e.value("mode", std::string());
    const std::string filter = e.value("filter", std::string("NONE"));
    unsigned char* out = dst.data() + dof;
    const unsigned char* in = src.data() + so;
    int rc;
    if (mode == "ATTRIBUTES") {
      if (stride % 4) fail_invalid(ptr + "/byteStride: must be a multiple of 4 for ATTRIBUTES");
      rc = meshopt_decodeVertexBuffer(out, count, stride, in, sl);
    } else if (mode == "TRIANGLES" || mode == "INDICES") {
      if (stride != 2 && stride != 4) fail_invalid(ptr + "/byteStride: must be 2 or 4 for " + mode);
      if (mode == "TRIANGLES" && count % 3) fail_invalid(ptr + "/count: not a multiple of 3 for TRIANGLES");
      rc = mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(out, count, stride, in, sl)
                               : meshopt_decodeIndexSequence(out, count, stride, in, sl);
    } else {
      fail_invalid(ptr + "/mode: unknown mode '" + mode + "'");
    }
    if (rc != 0) fail_invalid(ptr + ": meshopt decoding failed (code " + to_string(rc) + ", corrupt data?)");
    if (filter == "OCTAHEDRAL") {
      if (stride != 4 && stride != 8) fail_invalid(ptr + "/filter: OCTAHEDRAL needs byteStride 4 or 8");
      meshopt_decodeFilterOct(out, count, stride);
    } else if (filter == "QUATERNION") {
      if (stride != 8) fail_invalid(ptr + "/filter: QUATERNION needs byteStride 8");
      meshopt_decodeFilterQuat(out, count, stride);
    } else if (filter == "EXPONENTIAL") {
      meshopt_decodeFilterExp(out, count, stride);
    } else if (filter != "NONE") {
      fail_invalid(ptr + "/filter: unknown filter '" + filter + "'");
    }
  }
}

}  // namespace rtp::gltf
