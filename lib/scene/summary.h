#pragma once
// Human and JSON summaries of a Scene (rtpack-convert --dry-run).
#include <nlohmann/json.hpp>
#include <string>

#include "scene/scene.h"

namespace rtp {

nlohmann::json scene_summary_json(const Scene& scene);
std::string scene_summary_text(const Scene& scene);

}  // namespace rtp
