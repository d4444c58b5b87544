// Reading a glTF file: container checks, JSON validation, meshopt fallback buffers, tinygltf + Draco.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>

#include "core/error.h"
#include "core/json_checked.h"
#include "core/input_file.h"
#include "scene/gltf_internal.h"

namespace rtp::gltf {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr uint32_t kChunkJson = 0x4E4F534A;
constexpr uint32_t kChunkBin = 0x004E4942;
constexpr uint64_t k4GiB = 1ull << 32;

uint32_t read_u32(const char* b) {
  uint32_t v;
  std::memcpy(&v, b, 4);
  return v;
}

// An open input file, closed on scope exit.
struct Fd {
  int fd;
  ~Fd() { ::close(fd); }
};

// Extensions whose meaning we implement, or which only concern materials/textures/lights and so
// cannot change the geometry we import.
const std::set<std::string>& known_extensions() {
  static const std::set<std::string> k = {"KHR_draco_mesh_compression",
                                          "KHR_mesh_quantization",
                                          "EXT_meshopt_compression",
                                          "EXT_mesh_gpu_instancing",
                                          "KHR_texture_transform",
                                          "KHR_texture_basisu",
                                          "EXT_texture_webp",
                                          "KHR_lights_punctual",
                                          "KHR_materials_unlit",
                                          "KHR_materials_pbrSpecularGlossiness",
                                          "KHR_materials_clearcoat",
                                          "KHR_materials_transmission",
                                          "KHR_materials_volume",
                                          "KHR_materials_ior",
                                          "KHR_materials_specular",
                                          "KHR_materials_sheen",
                                          "KHR_materials_emissive_strength",
                                          "KHR_materials_iridescence",
                                          "KHR_materials_variants",
                                          "KHR_materials_anisotropy",
                                          "KHR_materials_dispersion"};
  return k;
}

// tinygltf file callbacks: only the external buffers load_document resolved and checked can be
// read — keyed by the exact path tinygltf asks for (its base directory joined with the decoded URI),
// mapped to the checked canonical file and its size — never more than that size, never anything else
// (not the current directory either).
struct Approved {
  std::string canonical;
  uint64_t size;
  std::vector<unsigned char>* memory = nullptr;  // the .glb's BIN chunk, handed over instead of a file
};
using ApprovedMap = std::map<std::string, Approved>;
bool fs_exists(const std::string& p, void* user) { return static_cast<const ApprovedMap*>(user)->count(p) > 0; }
std::string fs_expand(const std::string& p, void*) { return p; }
bool fs_read(std::vector<unsigned char>* out, std::string* err, const std::string& p, void* user) {
  const ApprovedMap& approved = *static_cast<const ApprovedMap*>(user);
  const auto it = approved.find(p);
  if (it == approved.end()) {
    if (err) *err += "refusing to read '" + p + "' (not a checked buffer path)\n";
    return false;
  }
  if (it->second.memory) {  // once: tinygltf swaps it into the buffer, no copy
    out->swap(*it->second.memory);
    if (out->size() != it->second.size) {
      if (err) *err += "the .glb BIN chunk was already handed over\n";
      return false;
    }
    return true;
  }
  try {
    uint64_t size = 0;
    const Fd f{open_input_file(it->second.canonical, "", 0, &size)};
    if (size != it->second.size) {
      if (err) *err += "'" + p + "' changed size while loading\n";
      return false;
    }
    out->resize(size_t(size));
    read_exact(f.fd, 0, out->data(), out->size(), p);
  } catch (const Error& e) {
    if (err) *err += std::string(e.what()) + "\n";
    return false;
  }
  return true;
}
bool fs_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "writing is disabled\n";
  return false;
}
bool no_image_loader(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true;  // images are never decoded
}

bool is_data_uri(const std::string& uri) { return uri.rfind("data:", 0) == 0; }

// Size in bytes of a base64 data URI payload (without decoding it).
int64_t data_uri_size(const std::string& uri) {
  size_t comma = uri.find(',');
  if (comma == std::string::npos || uri.find(";base64", 0) > comma) return -1;
  size_t n = uri.size() - comma - 1;
  size_t pad = 0;
  if (n >= 1 && uri[uri.size() - 1] == '=') ++pad;
  if (n >= 2 && uri[uri.size() - 2] == '=') ++pad;
  return int64_t(n / 4 * 3) - int64_t(pad);
}

// URI decoding exactly as tinygltf does it (dlib::urldecode: '+' is a space, '%' takes the next two
// characters), so the path checked here is the path tinygltf asks to read.
std::string percent_decode(const std::string& s) {
  auto hex = [](unsigned char c) -> unsigned {
    return c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : 0;
  };
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out.push_back(' ');
    } else if (s[i] == '%' && s.size() > i + 2) {
      out.push_back(char(hex((unsigned char)s[i + 1]) << 4 | hex((unsigned char)s[i + 2])));
      i += 2;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

// tinygltf's JoinPath.
std::string join_path(const std::string& dir, const std::string& file) {
  return dir.empty() ? file : dir.back() == '/' ? dir + file : dir + "/" + file;
}

// Where an external buffer's URI lands, refused (exit 3, naming the JSON pointer) when it resolves —
// after percent-decoding, `..` and symbolic links — outside the glTF's directory and every allowed
// directory. Returns the canonical path (the file may not exist).
fs::path confined_path(const std::string& uri, const std::string& ptr, const fs::path& base_dir,
                       const std::vector<fs::path>& roots) {
  const std::string decoded = percent_decode(uri);
  if (decoded.find('\0') != std::string::npos) fail_invalid(ptr + "/uri: contains a NUL byte");
  std::error_code ec;
  const fs::path joined = fs::path(decoded).is_absolute() ? fs::path(decoded) : base_dir / fs::path(decoded);
  fs::path target = fs::weakly_canonical(joined, ec);
  if (!ec)
    for (const fs::path& root : roots) {
      const fs::path rel = target.lexically_relative(root);
      if (!rel.empty() && *rel.begin() != "..") return target;
    }
  std::string allowed;
  for (const fs::path& r : roots) allowed += (allowed.empty() ? "" : ", ") + r.string();
  fail_invalid(ptr + "/uri: '" + uri + "' resolves to " + (ec ? decoded : target.string()) +
               ", outside the glTF's directory (allowed: " + allowed + "; widen with --allow-path DIR)");
}

// The glTF container: .glb (by magic, whatever the extension) or JSON text. A .glb's header and chunk
// headers are checked against the file size before any chunk body is read. Returns whether it is a .glb.
bool read_container(int fd, const std::string& path, uint64_t file_size, std::string& json_text,
                    std::vector<unsigned char>& bin_data, bool& has_bin) {
  char head[12] = {};
  read_exact(fd, 0, head, size_t(std::min<uint64_t>(file_size, 12)), path);
  const bool is_glb = file_size >= 4 && read_u32(head) == kGlbMagic;
  if (is_glb) {
    if (file_size < 20) fail_invalid("truncated file: " + std::to_string(file_size) + " bytes is too short for a .glb header");
    const uint32_t version = read_u32(head + 4), length = read_u32(head + 8);
    if (version != 2) fail_invalid(".glb container version " + std::to_string(version) + " is not supported (need 2)");
    if (length > file_size)
      fail_invalid("truncated file: .glb header declares " + std::to_string(length) + " bytes but the file has " +
                   std::to_string(file_size));
    uint64_t off = 12;
    int chunk = 0;
    while (off < length) {
      if (off + 8 > length)
        fail_invalid("truncated file: chunk " + std::to_string(chunk) + " header at byte " + std::to_string(off) + " is cut off");
      char ch[8];
      read_exact(fd, off, ch, 8, path);
      const uint64_t clen = read_u32(ch), ctype = read_u32(ch + 4);
      if (off + 8 + clen > length)
        fail_invalid("truncated file: chunk " + std::to_string(chunk) + " (" + std::to_string(clen) + " bytes at byte " +
                     std::to_string(off + 8) + ") extends past the end of the data (" + std::to_string(length) + " bytes)");
      if (chunk == 0 && ctype != kChunkJson) fail_invalid(".glb: the first chunk is not JSON");
      // Only the JSON and BIN chunks are read; others are skipped.
      if (chunk == 0) {
        json_text.resize(size_t(clen));
        read_exact(fd, off + 8, json_text.data(), json_text.size(), path);
      } else if (chunk == 1 && ctype == kChunkBin) {
        bin_data.resize(size_t(clen));
        read_exact(fd, off + 8, bin_data.data(), bin_data.size(), path);
        has_bin = true;
      }
      off += 8 + ((clen + 3) & ~uint64_t(3));
      ++chunk;
    }
    if (chunk == 0) fail_invalid(".glb has no JSON chunk");
  } else {
    char text_head[64] = {};
    const size_t n = size_t(std::min<uint64_t>(file_size, sizeof text_head));
    read_exact(fd, 0, text_head, n, path);
    if (const std::string foreign = foreign_format_message(std::string_view(text_head, n)); !foreign.empty())
      fail_invalid(foreign);
    json_text.resize(size_t(file_size));
    read_exact(fd, 0, json_text.data(), json_text.size(), path);
  }
  return is_glb;
}

// /extensionsRequired: every entry a string naming an extension this importer supports.
void check_required_extensions(const json& j) {
  if (!j.contains("extensionsRequired")) return;
  std::string unknown;
  if (!j["extensionsRequired"].is_array()) fail_invalid("/extensionsRequired: not an array");
  for (const auto& e : j["extensionsRequired"])
    if (!e.is_string() || !known_extensions().count(e.get<std::string>()))
      unknown += (unknown.empty() ? "" : ", ") + (e.is_string() ? e.get<std::string>() : e.dump());
  if (!unknown.empty()) fail_invalid("/extensionsRequired: unsupported required extensions: " + unknown);
}

// The folders external buffers may resolve inside: the glTF's own and each --allow-path, canonical.
std::vector<fs::path> buffer_roots(const std::string& base_dir, const std::vector<std::string>& allowed_dirs) {
  std::vector<fs::path> dirs{base_dir};
  dirs.insert(dirs.end(), allowed_dirs.begin(), allowed_dirs.end());
  std::vector<fs::path> roots;
  for (const fs::path& d : dirs) {
    std::error_code ec;
    const fs::path c = fs::weakly_canonical(fs::absolute(d, ec), ec);
    if (!ec) roots.push_back(c);
  }
  return roots;
}

}  // namespace

Document load_document(const std::string& path, const std::vector<std::string>& allowed_dirs) {
  Document doc;
  doc.path = path;
  std::error_code ec;
  uint64_t file_size = 0;
  const Fd in{open_input_file(path, "", 0, &file_size)};  // regular files only; a FIFO never blocks
  const fs::path abs = fs::absolute(path, ec);
  doc.base_dir = abs.parent_path().string();
  doc.input.gltf_bytes = file_size;
  if (file_size >= k4GiB)
    fail_invalid("file is " + std::to_string(file_size) +
                 " bytes: glTF/.glb files of 4 GiB or more are not supported (the .glb length field is 32-bit)");

  std::string json_text;
  std::vector<unsigned char> bin_data;
  bool has_bin = false;
  const bool is_glb = read_container(in.fd, path, file_size, json_text, bin_data, has_bin);
  const unsigned char* bin = has_bin ? bin_data.data() : nullptr;
  const size_t bin_size = bin_data.size();

  jsonc::check_depth(json_text, "");
  try {
    doc.json = json::parse(json_text);
  } catch (const json::parse_error& e) {
    fail_invalid(std::string("invalid JSON (truncated file?) at byte ") + std::to_string(e.byte) + ": " + e.what());
  } catch (const json::exception& e) {  // e.g. a number too large for a double
    fail_invalid(std::string("invalid JSON: ") + e.what());
  }
  if (!doc.json.is_object()) fail_invalid("/: the glTF document is not a JSON object");
  const json& j = doc.json;
  if (!j.contains("asset") || !j["asset"].is_object() || !j["asset"].contains("version") || !j["asset"]["version"].is_string() ||
      j["asset"]["version"].get<std::string>().rfind("2.", 0) != 0)
    fail_invalid("/asset/version: not a glTF 2.x file");

  check_required_extensions(j);

  // Real sizes of the buffers' data, and which are meshopt fallback buffers (no data in the file).
  std::vector<int64_t> sizes;
  std::vector<int> fallback;
  const std::vector<fs::path> roots = buffer_roots(doc.base_dir, allowed_dirs);  // external buffers resolve inside one
  ApprovedMap approved;
  uint64_t bin_buffer_bytes = UINT64_MAX;  // byteLength of buffer 0 when it is the .glb BIN chunk
  if (j.contains("buffers")) {
    if (!j["buffers"].is_array()) fail_invalid("/buffers: not an array");
    for (size_t i = 0; i < j["buffers"].size(); ++i) {
      const json& b = j["buffers"][i];
      const std::string ptr = "/buffers/" + std::to_string(i);
      if (!b.is_object() || !b.contains("byteLength") || !b["byteLength"].is_number_unsigned())
        fail_invalid(ptr + "/byteLength: missing or not a non-negative integer");
      const uint64_t declared = b["byteLength"].get<uint64_t>();
      const json* ext = jsonc::find(b, "extensions");
      const json* mo = ext ? jsonc::find(*ext, "EXT_meshopt_compression") : nullptr;
      const bool is_fallback = mo && jsonc::get_bool(*mo, "fallback", false, ptr + "/extensions/EXT_meshopt_compression");
      if (b.contains("uri") && !b["uri"].is_string()) fail_invalid(ptr + "/uri: not a string");
      const std::string uri = b.value("uri", std::string());
      int64_t real = -1;
      if (uri.empty()) {
        if (is_fallback) {
          fallback.push_back(int(i));
          real = int64_t(declared);
        } else if (is_glb && i == 0) {
          if (!bin) fail_invalid(ptr + ": refers to the .glb BIN chunk, but the file has none");
          real = int64_t(bin_size);
          bin_buffer_bytes = declared;
        } else {
          fail_invalid(ptr + ": no uri (only the first buffer of a .glb may omit it)");
        }
      } else if (is_data_uri(uri)) {
        real = data_uri_size(uri);
        if (real < 0) fail_invalid(ptr + "/uri: data URI is not base64");
      } else {
        const fs::path p = confined_path(uri, ptr, doc.base_dir, roots);
        struct stat st {};
        if (::stat(p.c_str(), &st) != 0)
          throw Error(ExitCode::kInputIo, ptr + "/uri: cannot open '" + uri + "' (looked in " + doc.base_dir + ")");
        if (!S_ISREG(st.st_mode))
          throw Error(ExitCode::kInputIo, ptr + "/uri: cannot open '" + uri +
                                              "': " + (S_ISDIR(st.st_mode) ? "is a directory" : "is not a regular file"));
        real = int64_t(st.st_size);
        // Size checked before reading: the file is read only when it is exactly byteLength bytes.
        if (uint64_t(real) > declared)
          fail_invalid(ptr + ": byteLength is " + std::to_string(declared) + " but '" + uri + "' has " + std::to_string(real) +
                       " bytes (the file must be exactly byteLength bytes)");
        approved[join_path(doc.base_dir, percent_decode(uri))] = Approved{p.string(), uint64_t(real)};
        doc.input.buffer_bytes += uint64_t(real);  // tinygltf reads each buffer's file (fs_read)
        ++doc.input.buffer_files;
        doc.input.buffer_paths.push_back(p.string());
      }
      if (real >= 0 && uint64_t(real) < declared)
        fail_invalid(ptr + ": byteLength is " + std::to_string(declared) + " but only " + std::to_string(real) +
                     " bytes are there (truncated file?)");
      sizes.push_back(int64_t(declared));
    }
  }
  validate_json(j, sizes);
  // Images are never read; counted (and external files sized with stat) so the summary can say so.
  if (const json* images = jsonc::find(j, "images"); images && images->is_array()) {
    doc.input.images = uint32_t(images->size());
    for (const json& im : *images) {
      if (!im.is_object() || !im.contains("uri") || !im["uri"].is_string()) continue;
      const std::string uri = im["uri"].get<std::string>();
      if (is_data_uri(uri)) continue;
      // Only files the buffers could be read from are sized: a URI reaching outside the allowed
      // directories is counted, never stat-ed (its size would tell what exists there).
      fs::path p;
      try {
        p = confined_path(uri, "/images", doc.base_dir, roots);
      } catch (const Error&) {
        continue;
      }
      struct stat st {};
      if (::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode)) doc.input.image_file_bytes += uint64_t(st.st_size);
    }
  }

  // tinygltf does not know EXT_meshopt_compression: give each fallback buffer a 1-byte placeholder,
  // decode the compressed views into it afterwards.
  // Images are never decoded and a missing texture is not an error: tinygltf does not see them.
  json patched = j;
  patched.erase("images");
  patched.erase("textures");
  patched.erase("samplers");
  strip_draco(patched);
  for (int i : fallback) {
    patched["buffers"][i]["uri"] = "data:application/octet-stream;base64,AA==";
    patched["buffers"][i]["byteLength"] = 1;
  }
  // The .glb's BIN chunk reaches tinygltf as buffer 0's "file", moved in by fs_read: re-assembled into
  // the container it was copied twice (into the container, then into the buffer), 3x the file in memory
  // at once. Only when no other buffer already resolves to that name (then the container holds it).
  bool bin_by_name = false;
  if (bin && bin_buffer_bytes != UINT64_MAX) {
    const char* kBinUri = "rtpack-glb-bin-chunk";
    const std::string key = join_path(doc.base_dir, kBinUri);
    if (!approved.count(key)) {
      bin_data.resize(size_t(bin_buffer_bytes));  // the chunk's padding is not the buffer's (checked: >= byteLength)
      approved[key] = Approved{std::string(), bin_buffer_bytes, &bin_data};
      patched["buffers"][0]["uri"] = kBinUri;
      bin_by_name = true;
    }
  }

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(no_image_loader, nullptr);
  loader.SetFsCallbacks(tinygltf::FsCallbacks{fs_exists, fs_expand, fs_read, fs_write, &approved});
  std::string err, warn;
  bool ok;
  const std::string text = patched.dump();
  if (is_glb) {
    // Re-assemble the container with the (possibly patched) JSON and the original BIN chunk.
    std::string glb(12, '\0');
    auto put = [&](uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
    std::string jt = text;
    while (jt.size() % 4) jt.push_back(' ');
    put(uint32_t(jt.size()));
    put(kChunkJson);
    glb += jt;
    if (bin && !bin_by_name) {
      put(uint32_t((bin_size + 3) & ~size_t(3)));
      put(kChunkBin);
      glb.append(reinterpret_cast<const char*>(bin), bin_size);
      while (glb.size() % 4) glb.push_back('\0');
    }
    if (glb.size() >= k4GiB) fail_invalid("re-assembled .glb would exceed 4 GiB");
    uint32_t hdr[3] = {kGlbMagic, 2, uint32_t(glb.size())};
    std::memcpy(glb.data(), hdr, 12);
    ok = loader.LoadBinaryFromMemory(&doc.model, &err, &warn, reinterpret_cast<const unsigned char*>(glb.data()),
                                     unsigned(glb.size()), doc.base_dir, tinygltf::REQUIRE_VERSION);
  } else {
    ok = loader.LoadASCIIFromString(&doc.model, &err, &warn, text.data(), unsigned(text.size()), doc.base_dir,
                                    tinygltf::REQUIRE_VERSION);
  }
  if (!ok) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    fail_invalid("glTF parse failed: " + err);
  }
  decode_meshopt(doc);  // also sizes the fallback buffers
  decode_draco(doc);
  return doc;
}

}  // namespace rtp::gltf
