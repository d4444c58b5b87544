#pragma once
// Checked access to untrusted JSON (glTF documents, package metadata). Every accessor throws the
// malformed-input error (exit 3) naming the JSON pointer of the offending value, never nlohmann's
// type_error / out_of_range (which tools would report as an internal error). Header only: include it
// where nlohmann_json is linked.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "core/error.h"

namespace rtp::jsonc {

using nlohmann::json;

// Deepest nesting of arrays/objects accepted in any JSON text rtpack reads (docs/exit-codes.md).
// Real glTF files nest fewer than 10 levels; the limit keeps every recursive walk (parsers, copies,
// dumps) far from the stack's end.
constexpr int kMaxJsonDepth = 256;

// Rejects text nesting arrays/objects deeper than kMaxJsonDepth, before any parser sees it. One linear
// pass; string contents (with escaped quotes) are skipped, so brackets inside strings do not count.
// `what` starts the message (e.g. the file name or "/bufferViews/0 metadata").
inline void check_depth(std::string_view text, const std::string& what) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;  // the escaped character cannot end the string
      else if (c == '"')
        in_string = false;
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth)
        fail_invalid(what + "JSON nested more than " + std::to_string(kMaxJsonDepth) + " levels deep (at byte " +
                     std::to_string(i) + ")");
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
}

// `ptr` + "/" + `key` with the key escaped per RFC 6901 ("~" -> "~0", "/" -> "~1").
inline std::string child(const std::string& ptr, std::string_view key) {
  std::string out = ptr + "/";
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}
inline std::string child(const std::string& ptr, size_t index) { return ptr + "/" + std::to_string(index); }

// Member `key` of `obj`, or nullptr when `obj` is not an object or has no such member.
inline const json* find(const json& obj, std::string_view key) {
  if (!obj.is_object()) return nullptr;
  auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

// `obj` itself must be an object (`ptr` names it).
inline const json& object(const json& obj, const std::string& ptr) {
  if (!obj.is_object()) fail_invalid(ptr + ": not an object");
  return obj;
}

// A required member (any type).
inline const json& member(const json& obj, std::string_view key, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  if (!v) fail_invalid(child(ptr, key) + ": missing");
  return *v;
}

inline uint64_t as_uint(const json& v, const std::string& ptr) {
  if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
    fail_invalid(ptr + ": not a non-negative integer");
  return v.get<uint64_t>();
}
inline int64_t as_int(const json& v, const std::string& ptr) {
  if (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(INT64_MAX)) fail_invalid(ptr + ": integer out of range");
  if (!v.is_number_integer()) fail_invalid(ptr + ": not an integer");
  return v.get<int64_t>();
}
inline double as_number(const json& v, const std::string& ptr) {
  if (!v.is_number()) fail_invalid(ptr + ": not a number");
  return v.get<double>();
}
inline std::string as_string(const json& v, const std::string& ptr) {
  if (!v.is_string()) fail_invalid(ptr + ": not a string");
  return v.get<std::string>();
}
inline bool as_bool(const json& v, const std::string& ptr) {
  if (!v.is_boolean()) fail_invalid(ptr + ": not a boolean");
  return v.get<bool>();
}

// Required members of a given type.
inline uint64_t get_uint(const json& obj, std::string_view key, const std::string& ptr) {
  return as_uint(member(obj, key, ptr), child(ptr, key));
}
inline int64_t get_int(const json& obj, std::string_view key, const std::string& ptr) {
  return as_int(member(obj, key, ptr), child(ptr, key));
}
inline double get_number(const json& obj, std::string_view key, const std::string& ptr) {
  return as_number(member(obj, key, ptr), child(ptr, key));
}
inline std::string get_string(const json& obj, std::string_view key, const std::string& ptr) {
  return as_string(member(obj, key, ptr), child(ptr, key));
}

// Optional members: `def` when absent, an error when present with the wrong type.
inline uint64_t get_uint(const json& obj, std::string_view key, uint64_t def, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  return v ? as_uint(*v, child(ptr, key)) : def;
}
inline int64_t get_int(const json& obj, std::string_view key, int64_t def, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  return v ? as_int(*v, child(ptr, key)) : def;
}
inline double get_number(const json& obj, std::string_view key, double def, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  return v ? as_number(*v, child(ptr, key)) : def;
}
inline std::string get_string(const json& obj, std::string_view key, const std::string& def, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  return v ? as_string(*v, child(ptr, key)) : def;
}
inline bool get_bool(const json& obj, std::string_view key, bool def, const std::string& ptr) {
  const json* v = find(object(obj, ptr), key);
  return v ? as_bool(*v, child(ptr, key)) : def;
}

}  // namespace rtp::jsonc
