// EXT_meshopt_compression: decode compressed bufferViews (meshoptimizer's decoders) into the
// fallback buffer that tinygltf saw only as a placeholder.
#include <meshoptimizer.h>

#include <algorithm>

#include "core/error.h"
#include "core/json_checked.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {

void decode_meshopt(Document& doc) {
  using std::to_string;
  const nlohmann::json& j = doc.json;
  const nlohmann::json* views = jsonc::find(j, "bufferViews");
  if (!views) return;
  // Each fallback buffer gets only the bytes its compressed views decode into (validate_json bounds
  // every view by its compressed size), never its declared byteLength: that is not backed by data.
  std::vector<size_t> fallback_end(doc.model.buffers.size(), 0);
  std::vector<bool> is_fallback(doc.model.buffers.size(), false);
  for (size_t v = 0; v < views->size(); ++v) {
    const nlohmann::json& bv = (*views)[v];
    const nlohmann::json* ext = jsonc::find(bv, "extensions");
    if (!ext || !jsonc::find(*ext, "EXT_meshopt_compression")) continue;
    const std::string ptr = "/bufferViews/" + to_string(v);
    const size_t b = jsonc::get_uint(bv, "buffer", ptr);
    const size_t end = jsonc::get_uint(bv, "byteOffset", 0, ptr) + jsonc::get_uint(bv, "byteLength", ptr);
    if (b >= doc.model.buffers.size()) fail_invalid(ptr + "/buffer: out of range");
    fallback_end[b] = std::max(fallback_end[b], end);
  }
  if (const nlohmann::json* buffers = jsonc::find(j, "buffers"))
    for (size_t b = 0; b < buffers->size() && b < is_fallback.size(); ++b) {
      const std::string bp = "/buffers/" + to_string(b);
      const nlohmann::json* ext = jsonc::find((*buffers)[b], "extensions");
      const nlohmann::json* e = ext ? jsonc::find(*ext, "EXT_meshopt_compression") : nullptr;
      if (e && jsonc::get_bool(*e, "fallback", false, bp + "/extensions/EXT_meshopt_compression"))
        doc.model.buffers[b].data.assign(fallback_end[b], 0);
    }
  for (size_t v = 0; v < views->size(); ++v) {
    const nlohmann::json& bv = (*views)[v];
    const nlohmann::json* ext = jsonc::find(bv, "extensions");
    const nlohmann::json* ep = ext ? jsonc::find(*ext, "EXT_meshopt_compression") : nullptr;
    if (!ep) continue;
    const nlohmann::json& e = *ep;
    const std::string vp = "/bufferViews/" + to_string(v);
    const std::string ptr = vp + "/extensions/EXT_meshopt_compression";
    // Ranges were validated against the declared sizes; re-check against the loaded data.
    const size_t sb = jsonc::get_uint(e, "buffer", ptr), db = jsonc::get_uint(bv, "buffer", vp);
    if (sb >= doc.model.buffers.size() || db >= doc.model.buffers.size()) fail_invalid(ptr + ": buffer out of range");
    const auto& src = doc.model.buffers[sb].data;
    auto& dst = doc.model.buffers[db].data;
    const size_t so = jsonc::get_uint(e, "byteOffset", 0, ptr), sl = jsonc::get_uint(e, "byteLength", ptr);
    const size_t dof = jsonc::get_uint(bv, "byteOffset", 0, vp), dl = jsonc::get_uint(bv, "byteLength", vp);
    const size_t count = jsonc::get_uint(e, "count", ptr), stride = jsonc::get_uint(e, "byteStride", ptr);
    if (so + sl < so || so + sl > src.size() || dof + dl < dof || dof + dl > dst.size() || count * stride > dl)
      fail_invalid(ptr + ": data out of range");
    const std::string mode = jsonc::get_string(e, "mode", ptr);
    const std::string filter = jsonc::get_string(e, "filter", "NONE", ptr);
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
      if (stride % 4) fail_invalid(ptr + "/filter: EXPONENTIAL needs a byteStride that is a multiple of 4");
      meshopt_decodeFilterExp(out, count, stride);
    } else if (filter != "NONE") {
      fail_invalid(ptr + "/filter: unknown filter '" + filter + "'");
    }
  }
}

}  // namespace rtp::gltf
