#include "stages/publish_stage.hpp"

#include <algorithm>
#include <string>

#include "trainer/app/force_command.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"

namespace trainer::app {
namespace {

std::array<float, 3> publish_vec3(const Eigen::Vector3f& v) noexcept { return {v.x(), v.y(), v.z()}; }

// Keeps the `kMaxContacts` largest contact points: appends while there is room, then a
// newcomer larger than the smallest kept replaces it. Squared magnitudes are kept beside the
// points, and the smallest is searched again only after a replacement.
class ContactSelection {
 public:
  explicit ContactSelection(TelemetrySnapshot& snapshot) noexcept : snapshot_(snapshot) {
    snapshot_.contact_count = 0;
    snapshot_.contacts_truncated = false;
  }
  void add(const telemetry::ContactPoint& point, float squared_n) noexcept {
    std::uint32_t& count = snapshot_.contact_count;
    if (count < snapshot_.contacts.size()) {
      squared_n_[count] = squared_n;
      snapshot_.contacts[count++] = point;
      if (count == snapshot_.contacts.size()) find_smallest();
      return;
    }
    snapshot_.contacts_truncated = true;
    if (squared_n <= squared_n_[smallest_]) return;
    snapshot_.contacts[smallest_] = point;
    squared_n_[smallest_] = squared_n;
    find_smallest();
  }

 private:
  void find_smallest() noexcept {
    smallest_ = 0;
    for (std::size_t k = 1; k < squared_n_.size(); ++k)
      if (squared_n_[k] < squared_n_[smallest_]) smallest_ = k;
  }
  TelemetrySnapshot& snapshot_;
  std::array<float, telemetry::kMaxContacts> squared_n_{};
  std::size_t smallest_ = 0;
};

telemetry::ContactKind contact_kind_of(model::ToolSegment segment) noexcept {
  switch (segment) {
    case model::ToolSegment::jaw0: return telemetry::ContactKind::jaw0;
    case model::ToolSegment::jaw1: return telemetry::ContactKind::jaw1;
    case model::ToolSegment::shaft: break;
  }
  return telemetry::ContactKind::shaft;
}

}  // namespace

core::Expected<void> PublishStage::publish_models(const SceneModels& models,
                                                  const std::string& scene_file) {
  std::size_t modal = 0;
  std::size_t tensor = 0;
  std::size_t catheter = 0;
  for (std::size_t m = 0; m < models.info.size(); ++m) {
    const LoadedModelInfo& info = models.info[m];
    const std::string where = scene_file + ": model '" + info.name + "': ";
    const auto scene_index = static_cast<std::uint8_t>(m);
    switch (info.kind) {
      case config::ModelKind::modal_shell: {
        const model::ModalModel& model = *models.modal[modal].model;
        if (model.active_mode_count() > telemetry::kMaxModes) {
          return core::make_error(where + std::to_string(model.active_mode_count()) +
                                  " active modes; the telemetry stream carries at most " +
                                  std::to_string(telemetry::kMaxModes));
        }
        if (model.static_correction() && model.node_count() > telemetry::kMaxNodeIndex + 1) {
          return core::make_error(where + std::to_string(model.node_count()) +
                                  " nodes with static correction; the telemetry stream numbers "
                                  "loaded nodes up to 65,535");
        }
        modal_scene_index_[modal++] = scene_index;
        break;
      }
      case config::ModelKind::tet_tensor: {
        const model::TensorModel& model = *models.tensor[tensor].model;
        if (model.max_contacts() > telemetry::kMaxTensorContacts ||
            model.contact_nodes().empty() ||
            model.contact_nodes().back() > telemetry::kMaxNodeIndex) {
          return core::make_error(where + "contact nodes beyond what the telemetry stream "
                                  "carries (at most " +
                                  std::to_string(telemetry::kMaxTensorContacts) +
                                  " contacts, node indices up to 65,535)");
        }
        tensor_scene_index_[tensor++] = scene_index;
        break;
      }
      case config::ModelKind::catheter: {
        if (models.catheters[catheter].catheter->positions_m().size() > telemetry::kMaxParticles) {
          return core::make_error(where + "more particles than the telemetry stream carries (" +
                                  std::to_string(telemetry::kMaxParticles) + ")");
        }
        catheter_scene_index_[catheter++] = scene_index;
        break;
      }
    }
  }
  if (models.info.size() > telemetry::kMaxModels || modal != models.modal_count ||
      tensor != models.tensor_count || catheter != models.catheter_count) {
    return core::make_error(scene_file + ": the loaded models do not match the scene's list");
  }
  models_ = &models;
  return {};
}

void PublishStage::publish_instruments(const CycleFrame& frame,
                                       TelemetrySnapshot& snapshot) const noexcept {
  ContactSelection contacts(snapshot);
  for (std::size_t i = 0; i < frame.instrument_out.size(); ++i) {
    const InstrumentFrame& instrument = frame.instruments[i];
    const kinematics::InstrumentPose& pose = instrument.pose;
    InstrumentTelemetry& out = snapshot.instruments[i];
    out = frame.instrument_out[i];
    out.hinge_m = publish_vec3(pose.hinge_m);
    out.shaft_start_m = publish_vec3(pose.shaft_start_m);
    out.opening_direction = publish_vec3(pose.opening_direction);
    out.stream_flags = static_cast<std::uint8_t>(
        (instrument.model_contact ? telemetry::kInstrumentTissueContact : 0) |
        (instrument.grasping ? telemetry::kInstrumentGrasping : 0) |
        (instrument.wall_segment_contact ? telemetry::kInstrumentWallContact : 0) |
        (instrument.catheter_contact ? telemetry::kInstrumentCatheterContact : 0));
    const auto index = static_cast<std::uint8_t>(i);
    if (instrument.model_contact) {
      // model_force_n is what the tissue does to the tool; the stream shows the tissue's load.
      const Eigen::Vector3f on_tissue = -instrument.model_force_n;
      contacts.add({index, telemetry::kNoModel, telemetry::ContactKind::tip,
                         publish_vec3(pose.tip_m), publish_vec3(on_tissue)},
                        on_tissue.squaredNorm());
    }
    if (out.object_contact) {  // a rigid object (wall, sphere): not a scene model
      const std::array<float, 3>& f = out.object_force_n;
      contacts.add({index, telemetry::kNoModel, telemetry::ContactKind::tip,
                    publish_vec3(pose.tip_m), {-f[0], -f[1], -f[2]}},
                   f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    }
    for (const model::ToolForce& force : instrument.point_forces()) {
      const Eigen::Vector3f at = kinematics::TrocarKinematics::position(pose, tool_point(force));
      const Eigen::Vector3f on_tissue = -force.force_n;
      contacts.add({index, telemetry::kNoModel, contact_kind_of(force.segment),
                         publish_vec3(at), publish_vec3(on_tissue)},
                        on_tissue.squaredNorm());
    }
  }
}

void PublishStage::publish_model_state(TelemetrySnapshot& snapshot) const noexcept {
  const SceneModels& models = *models_;
  snapshot.model_count = static_cast<std::uint32_t>(models.info.size());
  for (std::size_t k = 0; k < models.modal_count; ++k) {
    const model::ModalModel& model = *models.modal[k].model;
    telemetry::ModelState& out = snapshot.models[modal_scene_index_[k]];
    out.kind = telemetry::ModelKind::modal;
    out.scene_index = modal_scene_index_[k];
    out.image_checksum = models.info[modal_scene_index_[k]].image_checksum;
    const std::span<const double> q = model.modal_displacement();
    out.mode_count = static_cast<std::uint32_t>(q.size());
    for (std::size_t i = 0; i < q.size(); ++i) out.modal_coordinates[i] = static_cast<float>(q[i]);
    out.flags = model.static_correction() ? telemetry::kModalStaticCorrection : 0;
    out.load_count = 0;
    if (model.static_correction()) {
      const std::size_t loads = model.stepped_load_count();
      for (std::size_t l = 0; l < loads && l < out.loads.size(); ++l) {
        out.loads[l].node = model.stepped_load_node(l);
        out.loads[l].force_n = publish_vec3(model.stepped_load_force(l));
      }
      out.load_count = static_cast<std::uint32_t>(std::min(loads, out.loads.size()));
    }
  }
  for (std::size_t k = 0; k < models.tensor_count; ++k) {
    const model::TensorModel& model = *models.tensor[k].model;
    telemetry::ModelState& out = snapshot.models[tensor_scene_index_[k]];
    out.kind = telemetry::ModelKind::tensor;
    out.scene_index = tensor_scene_index_[k];
    out.flags = 0;
    out.image_checksum = models.info[tensor_scene_index_[k]].image_checksum;
    const std::size_t contacts = std::min(model.contact_count(), out.contacts.size());
    for (std::size_t c = 0; c < contacts; ++c) {
      out.contacts[c].node = model.contact_node(c);
      out.contacts[c].displacement_m = publish_vec3(model.imposed_displacement(c));
    }
    out.contact_count = static_cast<std::uint32_t>(contacts);
  }
  for (std::size_t k = 0; k < models.catheter_count; ++k) {
    const std::span<const Eigen::Vector3f> positions = models.catheters[k].catheter->positions_m();
    telemetry::ModelState& out = snapshot.models[catheter_scene_index_[k]];
    out.kind = telemetry::ModelKind::catheter;
    out.scene_index = catheter_scene_index_[k];
    out.flags = 0;
    out.image_checksum = models.info[catheter_scene_index_[k]].image_checksum;
    const std::size_t count = std::min(positions.size(), out.particles_m.size());
    for (std::size_t p = 0; p < count; ++p) out.particles_m[p] = publish_vec3(positions[p]);
    out.particle_count = static_cast<std::uint32_t>(count);
  }
}

void PublishStage::run(CycleFrame& frame) noexcept {
  const loop::CycleTiming& timing = frame.timing;
  if (frame.newly_armed) last_logged_faults_ = 0;
  const std::uint32_t faults = safety_->latched_faults();
  const std::uint32_t new_faults = faults & ~last_logged_faults_;
  if (new_faults != 0) {
    for (std::uint32_t bit = 1; bit != 0; bit <<= 1U) {
      if ((new_faults & bit) != 0 && bit != safety::bit(safety::Fault::not_armed)) {
        log_->write(timing.wake_ns, core::LogLevel::error, "fault latched: {} at cycle {}",
                    safety::to_string(static_cast<safety::Fault>(bit)), timing.cycle_index);
      }
    }
  }
  last_logged_faults_ = faults;
  frame.faults_raised_at_publish = safety_->raised_fault_total();

  TelemetrySnapshot& snapshot = telemetry_->write_slot();
  snapshot.cycle = timing.cycle_index;
  snapshot.time_ns = timing.wake_ns;
  snapshot.latched_faults = faults;
  snapshot.instrument_count = static_cast<std::uint32_t>(frame.instrument_out.size());
  publish_instruments(frame, snapshot);
  if (models_ != nullptr) {
    publish_model_state(snapshot);
  } else {
    snapshot.model_count = 0;
  }
  telemetry_->publish();
}

}  // namespace trainer::app
