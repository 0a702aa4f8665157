// Tests that run a scene with a catheter need its image, as the trainer does: build it where
// the scene's definition names it, exactly as `modelc build --scene` would (the build is
// deterministic but for its time stamp; the writer renames a complete file into place, so tests
// running in parallel never read a partial one). Needs modelc_commands.
#pragma once

#include <filesystem>
#include <string>

#include "catheter_build.hpp"
#include "trainer/config/scene.hpp"

namespace trainer::test {

// Builds the image of every catheter `scene_file` names; returns "" or what went wrong.
inline std::string build_catheter_images(const std::filesystem::path& scene_file) {
  auto scene = config::load_scene(scene_file);
  if (!scene) return scene.error().message;
  try {
    for (const config::SceneModelConfig& entry : scene->models) {
      if (entry.definition.kind != config::ModelKind::catheter) continue;
      (void)tools::modelc::build_catheter_model(entry.name, entry.definition,
                                                static_cast<double>(scene->loop.period_ns) * 1e-9);
    }
  } catch (const std::exception& error) {
    return error.what();
  }
  return {};
}

}  // namespace trainer::test
