// The recording's side of the haptic app: the state hash and the record's app-filled fields.
#define XXH_STATIC_LINKING_ONLY
#include <xxhash.h>

#include <cmath>
#include <limits>

#include "haptic_stages.hpp"
#include "trainer/app/force_command.hpp"
#include "trainer/app/hal_taps.hpp"
#include "trainer/app/haptic_app.hpp"

namespace trainer::app {
namespace {

template <class T>
void hash_span(XXH3_state_t& state, std::span<const T> values) noexcept {
  if (!values.empty()) (void)XXH3_64bits_update(&state, values.data(), values.size_bytes());
}
template <class T>
void hash_value(XXH3_state_t& state, const T& value) noexcept {
  (void)XXH3_64bits_update(&state, &value, sizeof value);
}

std::array<float, 3> to_array(const Eigen::Vector3f& v) noexcept {
  return {v.x(), v.y(), v.z()};
}

}  // namespace

std::uint64_t HapticApp::state_hash() const noexcept {
  XXH3_state_t state;
  (void)XXH3_64bits_reset(&state);
  for (std::size_t m = 0; m < models_.modal_count; ++m) {
    const ModalModelState& modal = models_.modal[m];
    if (!modal.model) continue;
    hash_span(state, modal.model->modal_displacement());
    hash_span(state, modal.model->modal_velocity());
    hash_span(state, modal.model->modal_acceleration());
    hash_value(state, modal.catheter_load_count);
    for (std::size_t k = 0; k < modal.catheter_load_count; ++k) {
      hash_value(state, modal.catheter_loads[k].node);
      hash_value(state, to_array(modal.catheter_loads[k].force_n));
    }
  }
  for (std::size_t t = 0; t < models_.tensor_count; ++t) {
    const TensorModelState& tensor = models_.tensor[t];
    if (!tensor.model) continue;
    hash_span(state, tensor.model->displacements());
    hash_value(state, tensor.model->contact_count());
    hash_value(state, tensor.was_in_contact);
    hash_value(state, tensor.deformed_is_rest);
  }
  for (std::size_t c = 0; c < models_.catheter_count; ++c) {
    const CatheterModelState& catheter = models_.catheters[c];
    if (!catheter.catheter) continue;
    hash_span(state, catheter.catheter->positions_m());
    hash_span(state, catheter.catheter->velocities_m_per_s());
  }
  for (const InstrumentFrame& instrument : frame_.instruments) {
    hash_value(state, to_array(instrument.previous_tip_m));
    hash_value(state, instrument.has_previous_tip);
    hash_value(state, instrument.joint_position);
  }
  hash_value(state, safety_.latched_faults());
  for (std::size_t i = 0; i < frame_.instruments.size(); ++i)
    hash_value(state, safety_.delivered_energy_j(i));
  return XXH3_64bits_digest(&state);
}

// The scene index of the soft-tissue model (modal or tensor) with the largest total force this
// cycle (tools and catheters on it), -1 when none was loaded. The stats keep each model's sum
// of |total force| over its loaded cycles; the increase since the last record is this cycle's.
std::int32_t HapticApp::largest_force_model() noexcept {
  std::int32_t best = -1;
  double best_force = 0.0;
  std::size_t modal = 0;
  std::size_t tensor = 0;
  for (std::size_t m = 0; m < models_.info.size(); ++m) {
    double sum = 0.0;
    std::size_t slot = 0;
    if (models_.info[m].kind == config::ModelKind::modal_shell && modal < kMaxSceneModels) {
      slot = modal;
      sum = stats_.modal_models[modal++].force_sum_n;
    } else if (models_.info[m].kind == config::ModelKind::tet_tensor && tensor < kMaxSceneModels) {
      slot = kMaxSceneModels + tensor;
      sum = stats_.tensor_models[tensor++].force_sum_n;
    } else {
      continue;
    }
    const double force = sum - recorded_force_sums_[slot];
    recorded_force_sums_[slot] = sum;
    if (force > best_force) {
      best_force = force;
      best = static_cast<std::int32_t>(m);
    }
  }
  return best;
}

void HapticApp::record_cycle() noexcept {
  record::CycleRecord& r = recorder_->pending();
  r.reset_requested = frame_.reset_requested ? 1 : 0;
  r.latched_faults = safety_.latched_faults();
  r.state_hash = state_hash();
  record::DerivedSample& d = r.derived;
  d.time_ns = frame_.timing.wake_ns;
  d.instrument_count = static_cast<std::uint32_t>(frame_.instruments.size());
  d.contact_model = largest_force_model();
  d.insertion_depth_m = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t c = 0; c < models_.catheter_count; ++c) {
    if (models_.catheters[c].has_goal) {
      d.insertion_depth_m = stats_.catheters[c].insertion_depth_m;
      break;
    }
  }
  const std::size_t count = std::min(frame_.instruments.size(), record::kMaxRecordInstruments);
  for (std::size_t i = 0; i < count; ++i) {
    const InstrumentFrame& in = frame_.instruments[i];
    record::DerivedInstrument& out = d.instruments[i];
    Eigen::Vector3f total = in.model_force_n;
    Eigen::Vector3f largest_point = in.pose.tip_m;
    float largest = in.model_force_n.squaredNorm();
    for (const model::ToolForce& force : in.point_forces()) {
      total += force.force_n;
      const float size = force.force_n.squaredNorm();
      if (size > largest) {
        largest = size;
        largest_point = kinematics::TrocarKinematics::position(in.pose, tool_point(force));
      }
    }
    out.tip_m = to_array(in.pose.tip_m);
    out.tissue_force_n = to_array(total);
    out.contact_point_m = to_array(largest_point);
    out.grip_rad = in.joint_position[4];
    out.tissue_contact = (in.model_contact || in.wall_segment_contact || in.catheter_contact ||
                          in.tool_force_count > 0)
                             ? 1
                             : 0;
    out.grasping = in.grasping ? 1 : 0;
  }
}

}  // namespace trainer::app
