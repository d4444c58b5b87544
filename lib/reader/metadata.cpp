// Reading the metadata chunk (SPEC §4.1 kind 1): UTF-8 JSON, depth-checked before parsing.
#include "reader/metadata.h"

#include "core/error.h"
#include "core/json_checked.h"
#include "layout/chunk_io.h"

namespace rtp {

nlohmann::json read_metadata(const PackageReader& r, std::string* label) {
  const int64_t mi = r.find(fmt::ChunkKind::kMetadata, 0);
  if (mi < 0) return nlohmann::json::object();
  const AlignedBytes b = r.read(size_t(mi));
  ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kMetadata), chunk_label(r.toc()[size_t(mi)], size_t(mi)));
  if (label) *label = v.label();
  const auto text = v.copy<uint8_t>(fmt::SectionType::kJson);
  jsonc::check_depth(std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), v.label() + ": metadata ");
  auto meta = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
  if (meta.is_discarded() || !meta.is_object()) fail_invalid(v.label() + ": metadata is not a JSON object");
  return meta;
}

}  // namespace rtp
