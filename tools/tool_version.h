#pragma once
// `--version` for every tool: the rtpack release and the package format version it writes and reads
// (formats/SPEC.md §1: a reader refuses another major version).
#include <CLI/CLI.hpp>
#include <string>
#include "formats/package.h"

namespace rtp::tools {

inline std::string version_line(const char* tool) {
  return std::string(tool) + " " RTP_VERSION " (package format " + std::to_string(fmt::kVersionMajor) + "." +
         std::to_string(fmt::kVersionMinor) + ")";
}

inline void add_version_flag(CLI::App& app, const char* tool) {
  app.set_version_flag("--version", version_line(tool), "print the rtpack and package format versions, exit 0");
}

}  // namespace rtp::tools
