#include "trainer/app/rt_self_check.hpp"

namespace trainer::app {

appliance::RtCheckRequest rt_check_request(const config::SceneConfig& scene) {
  appliance::RtCheckRequest request;
  request.cpu = scene.loop.cpu;
  request.priority = scene.loop.priority;
  request.lock_memory = scene.loop.lock_memory;
  request.cpu_dma_latency_us = scene.loop.cpu_dma_latency_us;
  if (scene.device.backend == "canopen")
    request.can_interfaces.push_back(scene.device.canopen.interface);
  request.usb = scene.device.backend == "usb";
  for (const std::string& name : scene.loop.rt_check_fatal) {
    // The loader accepted only known names.
    if (auto id = appliance::rt_check_from_name(name)) request.fatal.push_back(*id);
  }
  return request;
}

std::vector<appliance::RtCheckResult> run_scene_rt_check(const config::SceneConfig& scene,
                                                         const std::filesystem::path& root) {
  return appliance::run_rt_check(appliance::SystemFiles(root), rt_check_request(scene));
}

nlohmann::json rt_check_json(const std::vector<appliance::RtCheckResult>& results) {
  nlohmann::json checks = nlohmann::json::array();
  for (const appliance::RtCheckResult& result : results) {
    checks.push_back({{"check", std::string(appliance::to_string(result.id))},
                      {"outcome", std::string(appliance::to_string(result.outcome))},
                      {"fatal", result.fatal},
                      {"detail", result.detail},
                      {"fix", result.fix}});
  }
  return {{"passed", !appliance::rt_check_failed(results)}, {"checks", checks}};
}

core::Expected<void> refuse_on_fatal(const config::SceneConfig& scene,
                                     const std::vector<appliance::RtCheckResult>& results) {
  if (!appliance::rt_check_failed(results)) return {};
  std::string message = "RT self-check failed; not arming (" + scene.source_path.string() +
                        ": loop.rt_check_fatal lists these):";
  for (const appliance::RtCheckResult& result : results) {
    if (!result.fatal) continue;
    message += "\n  " + std::string(appliance::to_string(result.id)) + ": " + result.detail +
               "\n    fix: " + result.fix;
  }
  message += "\n(trainer --check-rt --scene " + scene.source_path.string() + " shows every check)";
  return core::make_error(message);
}

}  // namespace trainer::app
