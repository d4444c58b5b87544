#pragma once
// The package's metadata chunk (kind 1, SPEC §4.1) as JSON: cameras, the converter's options, names.
#include <nlohmann/json.hpp>
#include <string>

#include "reader/reader.h"

namespace rtp {

// The metadata object ({} when the package has no metadata chunk). Throws Error(kInputInvalid) naming
// the chunk when it is not a JSON object (or nests too deep). `label` (optional) receives the chunk's name.
nlohmann::json read_metadata(const PackageReader& reader, std::string* label = nullptr);

}  // namespace rtp
