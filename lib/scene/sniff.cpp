// Recognizing files that are not glTF by their first bytes, so a user who passes an .obj, .fbx or .ply
// gets told what the file is and how to convert it, not a JSON parse error at byte 1.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>

#include "scene/gltf_internal.h"

namespace rtp::gltf {

namespace {

bool starts_with(std::string_view s, std::string_view p) { return s.substr(0, p.size()) == p; }

// The first line of a text file, for recognizing line-oriented formats (OBJ, OFF, STL, PLY).
std::string_view first_word(std::string_view s) {
  size_t i = 0;
  while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\n')) ++i;
  size_t j = i;
  while (j < s.size() && s[j] != ' ' && s[j] != '\t' && s[j] != '\r' && s[j] != '\n') ++j;
  return s.substr(i, j - i);
}

// Names the format of `head` (a file's first bytes), or "" when it is none that is known.
std::string known_format(std::string_view head) {
  if (starts_with(head, "Kaydara FBX Binary")) return "an FBX file";
  if (starts_with(head, "ply\n") || starts_with(head, "ply\r\n")) return "a PLY file";
  if (starts_with(head, "PXR-USDC")) return "a USD crate (.usdc) file";
  if (starts_with(head, "#usda")) return "a USD text (.usda) file";
  if (starts_with(head, std::string_view("PK\x03\x04", 4))) return "a ZIP archive (.zip, .usdz, .3mf)";
  if (starts_with(head, "\x1f\x8b")) return "a gzip-compressed file";
  if (starts_with(head, std::string_view("\x28\xb5\x2f\xfd", 4))) return "a zstd-compressed file";
  if (starts_with(head, "RTPACK\r\n")) return "an rtpack package (.rtp): it is already converted";
  if (starts_with(head, "<?xml") || starts_with(head, "<COLLADA"))
    return head.find("COLLADA") != std::string_view::npos ? "a COLLADA (.dae) file" : "an XML file";
  if (starts_with(head, "OFF") && (head.size() == 3 || head[3] == '\n' || head[3] == '\r' || head[3] == ' '))
    return "an OFF file";
  if (starts_with(head, "solid ")) return "an ASCII STL file";
  if (head.size() >= 2 && uint8_t(head[0]) == 0x4d && uint8_t(head[1]) == 0x4d) return "a 3DS file";
  const std::string_view w = first_word(head);
  // Wavefront OBJ: comments, vertices, faces, groups, materials.
  if (w == "#" || starts_with(w, "#") || w == "v" || w == "vn" || w == "vt" || w == "f" || w == "o" || w == "g" ||
      w == "mtllib" || w == "usemtl" || w == "s")
    return "a Wavefront OBJ file (or another text file)";
  return "";
}

std::string hex_bytes(std::string_view head, size_t n) {
  std::string out;
  char buf[4];
  for (size_t i = 0; i < std::min(n, head.size()); ++i) {
    std::snprintf(buf, sizeof buf, "%s%02x", i ? " " : "", unsigned(uint8_t(head[i])));
    out += buf;
  }
  return out;
}

}  // namespace

std::string foreign_format_message(std::string_view head) {
  // A glTF JSON document (after optional white space and a UTF-8 byte order mark) starts like any JSON
  // value; such files go to the JSON parser, which reports the byte where they break.
  size_t i = starts_with(head, "\xEF\xBB\xBF") ? 3 : 0;
  while (i < head.size() && (head[i] == ' ' || head[i] == '\t' || head[i] == '\r' || head[i] == '\n')) ++i;
  if (i == head.size()) return "";  // empty or only white space: the parser says so
  const char c = head[i];
  if (c == '{' || c == '[' || c == '"' || c == '-' || (c >= '0' && c <= '9') || c == 't' || c == 'f' || c == 'n') return "";
  const std::string what = known_format(head);
  const std::string hint =
      "rtpack reads glTF 2.0 (.gltf or .glb); convert it first, e.g. `assimp export input.ext output.glb` (Debian "
      "package assimp-utils) or Blender's glTF exporter";
  if (!what.empty()) return "not a glTF file: this looks like " + what + "; " + hint;
  return "not a glTF file: it starts with neither the bytes 'glTF' (.glb) nor a JSON object (.gltf) (first bytes: " +
         hex_bytes(head, 8) + "); " + hint;
}

}  // namespace rtp::gltf
