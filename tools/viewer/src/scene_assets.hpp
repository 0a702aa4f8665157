// The viewer's copy of what the appliance runs: the scene file (models, placements, instruments
// and their trocars from the device file) and the same model images, loaded and validated by the
// runtime's image loader, so surfaces are rebuilt from exactly the data the appliance used. A
// stream is accepted only when its image checksums equal these images' (check_checksums).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "trainer/app/rigid_transform.hpp"
#include "trainer/config/model.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_model.hpp"

namespace trainer::viewer {

struct ModelAssets {
  std::string name;
  config::ModelKind kind = config::ModelKind::modal_shell;
  std::filesystem::path image_path;
  std::uint64_t checksum = 0;  // the image header's XXH64
  std::size_t image_bytes = 0;
  app::RigidTransform placement;   // model frame -> trainer frame (identity for catheters)
  std::uint32_t node_count = 0;    // nodes (modal, tensor) or particles (catheter)
  std::uint32_t mode_count = 0;    // modal: stored modes
  bool static_correction = false;  // modal: the image has a residual compliance
  // Views into the image (the arena holds the bytes).
  std::span<const float> rest_positions;         // 3n, model frame (catheter: trainer frame)
  std::span<const std::uint32_t> triangles;      // 3m
  std::span<const float> mode_shapes;            // modal: 3n × r row-major
  std::span<const float> omega_squared;          // modal: r
  std::span<const std::uint32_t> surface_nodes;  // modal: s; tensor: contact nodes
  std::span<const float> residual_compliance;    // modal: 3s × 3s, empty without static correction
  std::vector<std::int32_t> surface_index;       // modal: per node, index in surface_nodes or -1
  std::optional<model::TensorModel> tensor;      // tensor: the runtime model, rebuilt per frame
};

struct InstrumentAssets {
  std::string name;
  kinematics::TrocarKinematics kinematics;
};

class SceneAssets {
 public:
  // Loads `scene_file` (as the trainer does, script not required) and every image it names.
  // Errors name the file and what is wrong; a missing image says how to build it.
  static core::Expected<std::unique_ptr<SceneAssets>> load(const std::filesystem::path& scene_file);

  const std::string& scene_name() const noexcept { return scene_name_; }
  const std::filesystem::path& scene_path() const noexcept { return scene_path_; }
  double period_s() const noexcept { return period_s_; }  // the haptic loop's period
  std::span<ModelAssets> models() noexcept { return models_; }
  std::span<const ModelAssets> models() const noexcept { return models_; }
  std::span<const InstrumentAssets> instruments() const noexcept { return instruments_; }

  // Refuses a stream whose models are not these images: the count, then each checksum in
  // scene order. The message names the model, the image file and both checksums in hex.
  core::Expected<void> check_checksums(std::span<const std::uint64_t> stream_checksums) const;

 private:
  SceneAssets() = default;
  std::string scene_name_;
  std::filesystem::path scene_path_;
  double period_s_ = 0.0;
  std::optional<core::Arena> arena_;
  std::vector<ModelAssets> models_;
  std::vector<InstrumentAssets> instruments_;
};

std::string checksum_hex(std::uint64_t checksum);

}  // namespace trainer::viewer
