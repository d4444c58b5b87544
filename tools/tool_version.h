#pragma once
// What every tool shares at its edges: `--version` (the rtpack release and the package format version it
// writes and reads, formats/SPEC.md §1), the fields every `--json` object carries (docs/json.md), and
// failures reported as JSON on stdout too when `--json` was asked for.
#include <CLI/CLI.hpp>
#include <iostream>
#include <nlohmann/json.hpp>
#include <cctype>
#include <functional>
#include <new>
#include <stdexcept>
#include <string>

#include "core/error.h"
#include "core/utf8.h"
#include "formats/package.h"

namespace rtp::tools {

// Bumped when a key of any tool's --json output changes meaning or disappears (adding keys does not).
inline constexpr int kJsonSchemaVersion =
    3;  // 2: package_bytes everywhere, snake_case section keys; 3: preparation.nonmanifold_faces/_vertices null unless --topology

inline std::string version_line(const char* tool) {
  return std::string(tool) + " " RTP_VERSION " (package format " + std::to_string(fmt::kVersionMajor) + "." +
         std::to_string(fmt::kVersionMinor) + ")";
}

inline void add_version_flag(CLI::App& app, const char* tool) {
  app.set_version_flag("--version", version_line(tool), "print the rtpack and package format versions, exit 0");
}

// The first keys of every --json object (or of every record of a JSON array).
// A JSON key from a display name, snake_case (docs/json.md): "top-level BVH" -> "top_level_bvh".
inline std::string json_key(const std::string& name) {
  std::string k;
  for (const char c : name) {
    if (std::isalnum(static_cast<unsigned char>(c)))
      k += char(std::tolower(static_cast<unsigned char>(c)));
    else if (!k.empty() && k.back() != '_')
      k += '_';
  }
  while (!k.empty() && k.back() == '_') k.pop_back();
  return k;
}

inline nlohmann::json json_stamp(const char* tool) {
  return {{"schema_version", kJsonSchemaVersion}, {"tool_version", version_line(tool)}};
}

// A failure: "error: INPUT: MESSAGE" on stderr, and with --json also on stdout as
// {"schema_version", "tool_version", "error": {"code", "input", "pointer", "message"}} where pointer is the
// JSON pointer that starts the message (glTF errors, e.g. "/nodes/0/mesh") or null. Returns the exit code.
inline nlohmann::json error_json(const char* tool, const std::string& input, ExitCode code, const std::string& message) {
  nlohmann::json pointer = nullptr;
  if (!message.empty() && message[0] == '/') {
    const size_t colon = message.find(": ");
    if (colon != std::string::npos) pointer = utf8_display(message.substr(0, colon));
  }
  nlohmann::json j = json_stamp(tool);
  j["error"] = {{"code", int(code)}, {"input", utf8_display(input)}, {"pointer", pointer}, {"message", utf8_display(message)}};
  return j;
}

inline int report_error(const char* tool, bool json, const std::string& input, ExitCode code, const std::string& message) {
  std::cerr << "error: " << input << ": " << message << "\n";
  if (json) std::cout << error_json(tool, input, code, message).dump(2) << "\n";
  return int(code);
}

// A tool's work, with every failure reported as above: an rtp::Error with its own exit code, out of
// memory and any other exception as internal errors (ExitCode::kInternal). on_error runs first (e.g. ends a progress
// line). Returns body()'s exit code.
template <class Body>
int run_reporting_errors(const char* tool, bool json, const std::string& input, Body&& body,
                         const std::function<void()>& on_error = {}) {
  try {
    return body();
  } catch (const Error& e) {
    if (on_error) on_error();
    return report_error(tool, json, input, e.code(), e.what());
  } catch (const std::bad_alloc&) {
    if (on_error) on_error();
    return report_error(tool, json, input, ExitCode::kInternal, "out of memory");
  } catch (const std::exception& e) {
    if (on_error) on_error();
    return report_error(tool, json, input, ExitCode::kInternal, std::string("internal error: ") + e.what());
  }
}

// A command line CLI11 refused (an unknown option, a missing or invalid value): CLI11's text on stderr as
// always, exit 1; and when --json is among the arguments, the error envelope on stdout too (docs/json.md),
// with "input" empty since no input was accepted. --help and --version exit 0 and print no envelope.
inline int parse_error_exit(CLI::App& app, const CLI::ParseError& e, const char* tool, int argc, const char* const* argv) {
  if (app.exit(e) == 0) return 0;
  bool json = false;
  for (int i = 1; i < argc; ++i) json = json || std::string(argv[i]) == "--json";
  if (json) std::cout << error_json(tool, "", ExitCode::kUsage, e.what()).dump(2) << "\n";
  return int(ExitCode::kUsage);
}

}  // namespace rtp::tools
