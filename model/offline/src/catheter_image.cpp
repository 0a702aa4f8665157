// Catheter image writer: the record from the runtime's derivation, the rest shape, metadata.
#include "trainer/model_offline/catheter_image.hpp"

#include <xxhash.h>

#include <cstring>
#include <span>
#include <utility>

#include "trainer/model_offline/image_writer.hpp"

namespace trainer::model::offline {
namespace {

void copy_vector(const Eigen::Vector3f& vector, float (&out)[3]) noexcept {
  for (int axis = 0; axis < 3; ++axis) out[axis] = vector[axis];
}

core::Expected<ImageWriter> make_catheter_writer(const CatheterImageInputs& inputs) {
  auto record = make_catheter_record(inputs);
  if (!record) return std::move(record).error();
  std::vector<Eigen::Vector3f> rest(record->particle_count);
  place_catheter_rest(inputs.start_m,
                      Eigen::Vector3f(record->rest_direction[0], record->rest_direction[1],
                                      record->rest_direction[2]),
                      record->rest_length_m, rest);
  std::vector<float> rest_positions;
  rest_positions.reserve(3 * rest.size());
  for (const Eigen::Vector3f& position : rest)
    rest_positions.insert(rest_positions.end(), position.begin(), position.end());

  ImageMetadataV1 metadata = make_metadata();
  // The catheter's "source" is its parameter record: equal records, equal hash.
  metadata.source_mesh_hash = XXH64(&record.value(), sizeof(CatheterParametersV1), 0);
  metadata.element_type = static_cast<std::uint32_t>(FiniteElementType::none);
  metadata.node_count = record->particle_count;
  if (auto version = set_tool_version(metadata, "modelc 0.1.0"); !version)
    return std::move(version).error();
  ImageWriter writer(ModelKind::catheter);
  writer.set_metadata(metadata);
  std::vector<std::uint8_t> record_bytes(sizeof(CatheterParametersV1));
  std::memcpy(record_bytes.data(), &record.value(), record_bytes.size());
  if (auto r = writer.add_u8(SectionId::catheter_parameters, record_bytes,
                             static_cast<std::uint32_t>(record_bytes.size()), 1);
      !r) {
    return std::move(r).error();
  }
  if (auto r = writer.add_f32(SectionId::catheter_rest_positions,
                              std::span<const float>(rest_positions), record->particle_count, 3);
      !r) {
    return std::move(r).error();
  }
  return writer;
}

}  // namespace

core::Expected<CatheterParametersV1> make_catheter_record(const CatheterImageInputs& inputs) {
  // The substep keeps the definition's stiffer contact stable (contacts stay explicit), so the
  // chain is derived with it whatever the caller put in params.contact_stiffness_n_per_m.
  CatheterParams params = inputs.params;
  params.contact_stiffness_n_per_m = catheter_contact_stiffness(
      inputs.contact.wall_stiffness_n_per_m, inputs.contact.tool_stiffness_n_per_m);
  auto chain = derive_catheter_chain(params);
  if (!chain) return std::move(chain).error();
  if (!inputs.start_m.allFinite()) return core::make_error("catheter: start_m is not finite");
  auto direction = catheter_rest_direction(inputs.direction);
  if (!direction) return std::move(direction).error();
  CatheterParametersV1 record{};
  record.record_version = kCatheterRecordVersion;
  record.particle_count = chain->particle_count;
  record.max_substeps = inputs.max_substeps;
  record.hold_start = inputs.hold_start ? 1U : 0U;
  record.rest_length_m = chain->rest_length_m;
  record.particle_mass_kg = chain->particle_mass_kg;
  record.axial_stiffness_n_per_m = chain->axial_n_per_m;
  record.bending_stiffness_n_m_per_rad = chain->bending_n_m_per_rad;
  record.radius_m = chain->radius_m;
  record.damping_n_s_per_m = chain->damping_n_s_per_m;
  record.stable_substep_s = chain->stable_substep_s;
  copy_vector(direction.value(), record.rest_direction);
  copy_vector(inputs.gravity_m_per_s2, record.gravity_m_per_s2);
  record.length_m = inputs.params.length_m;
  record.bending_stiffness_n_m2 = inputs.params.bending_stiffness_n_m2;
  record.axial_stiffness_n = inputs.params.axial_stiffness_n;
  record.linear_density_kg_per_m = inputs.params.linear_density_kg_per_m;
  record.wall_stiffness_n_per_m = inputs.contact.wall_stiffness_n_per_m;
  record.wall_damping_n_s_per_m = inputs.contact.wall_damping_n_s_per_m;
  record.tool_stiffness_n_per_m = inputs.contact.tool_stiffness_n_per_m;
  record.grasp_stiffness_n_per_m = inputs.contact.grasp_stiffness_n_per_m;
  record.grasp_friction = inputs.contact.grasp_friction;
  record.max_contact_force_n = inputs.contact.max_contact_force_n;
  return record;
}

core::Expected<std::vector<std::byte>> serialize_catheter_image(const CatheterImageInputs& inputs) {
  auto writer = make_catheter_writer(inputs);
  if (!writer) return std::move(writer).error();
  return writer.value().serialize();
}

core::Expected<void> write_catheter_image(const std::filesystem::path& path,
                                          const CatheterImageInputs& inputs) {
  auto writer = make_catheter_writer(inputs);
  if (!writer) return std::move(writer).error();
  return writer.value().write(path);
}

}  // namespace trainer::model::offline
