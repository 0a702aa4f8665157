// The RT self-check (rt/appliance rt_check.hpp) for a scene: what the scene's [loop] and its
// device file ask of the machine, the check run over a root directory, and the results as
// JSON. `trainer --check-rt` prints them; run_trainer runs them before it creates the device
// when it applies RT settings, and refuses to arm on a fatal failure (loop.rt_check_fatal).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "trainer/appliance/rt_check.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::app {

appliance::RtCheckRequest rt_check_request(const config::SceneConfig& scene);

std::vector<appliance::RtCheckResult> run_scene_rt_check(const config::SceneConfig& scene,
                                                         const std::filesystem::path& root);

nlohmann::json rt_check_json(const std::vector<appliance::RtCheckResult>& results);

// An error naming every fatal failure, its fix and the scene key, or success.
core::Expected<void> refuse_on_fatal(const config::SceneConfig& scene,
                                     const std::vector<appliance::RtCheckResult>& results);

}  // namespace trainer::app
