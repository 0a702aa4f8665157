// The fields every entry of `modelc build --report` starts with: the model's name, its
// definition file, its kind, that it was built, and the image written (path and size).
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "trainer/config/model.hpp"

namespace trainer::tools::modelc {

inline nlohmann::json built_image_entry(const std::string& name,
                                        const config::ModelDefinition& definition,
                                        const char* kind) {
  return {{"name", name},
          {"definition", definition.source_path.string()},
          {"kind", kind},
          {"built", true},
          {"image", definition.image_path.string()},
          {"image_bytes", std::filesystem::file_size(definition.image_path)}};
}

}  // namespace trainer::tools::modelc
