#pragma once
// File names (any bytes on Linux) in JSON output and package metadata, which must be valid UTF-8.
#include <string>

namespace rtp {

// `s` with every byte that does not start a valid UTF-8 sequence (overlong forms, surrogates and
// code points above U+10FFFF included) replaced by U+FFFD.
std::string utf8_display(const std::string& s);

}  // namespace rtp
