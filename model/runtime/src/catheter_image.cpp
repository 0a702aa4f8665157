// catheter_model_data(): a loaded catheter image's record and rest positions as the runtime
// catheter's data (catheter_image.hpp).
#include "trainer/model/catheter_image.hpp"

#include <cstring>

namespace trainer::model {

CatheterModelData catheter_model_data(const ModelImage& image) noexcept {
  CatheterModelData data;
  const std::span<const std::uint8_t> bytes = image.u8s(SectionId::catheter_parameters);
  if (image.model_kind() != ModelKind::catheter || bytes.size() != sizeof(CatheterParametersV1)) {
    return data;
  }
  CatheterParametersV1 record;
  std::memcpy(&record, bytes.data(), sizeof record);
  const auto vector = [](const float(&values)[3]) {
    return Eigen::Vector3f(values[0], values[1], values[2]);
  };
  data.params.length_m = record.length_m;
  data.params.outer_radius_m = record.radius_m;
  data.params.bending_stiffness_n_m2 = record.bending_stiffness_n_m2;
  data.params.axial_stiffness_n = record.axial_stiffness_n;
  data.params.linear_density_kg_per_m = record.linear_density_kg_per_m;
  data.params.damping_n_s_per_m = record.damping_n_s_per_m;
  data.params.particle_count = record.particle_count;
  data.params.contact_stiffness_n_per_m =
      catheter_contact_stiffness(record.wall_stiffness_n_per_m, record.tool_stiffness_n_per_m);
  data.chain.particle_count = record.particle_count;
  data.chain.rest_length_m = record.rest_length_m;
  data.chain.particle_mass_kg = record.particle_mass_kg;
  data.chain.axial_n_per_m = record.axial_stiffness_n_per_m;
  data.chain.bending_n_m_per_rad = record.bending_stiffness_n_m_per_rad;
  data.chain.radius_m = record.radius_m;
  data.chain.damping_n_s_per_m = record.damping_n_s_per_m;
  data.chain.stable_substep_s = record.stable_substep_s;
  data.max_substeps = record.max_substeps;
  data.rest_positions_m = image.floats(SectionId::catheter_rest_positions);
  data.rest_direction = vector(record.rest_direction);
  data.hold_start = record.hold_start == 1;
  data.gravity_m_per_s2 = vector(record.gravity_m_per_s2);
  data.contact.wall_stiffness_n_per_m = record.wall_stiffness_n_per_m;
  data.contact.wall_damping_n_s_per_m = record.wall_damping_n_s_per_m;
  data.contact.tool_stiffness_n_per_m = record.tool_stiffness_n_per_m;
  data.contact.grasp_stiffness_n_per_m = record.grasp_stiffness_n_per_m;
  data.contact.grasp_friction = record.grasp_friction;
  data.contact.max_contact_force_n = record.max_contact_force_n;
  return data;
}

}  // namespace trainer::model
