#include "trainer/model/modal_image.hpp"

namespace trainer::model {

ModalModelData modal_model_data(const ModelImage& image) noexcept {
  const ImageMetadataV1& metadata = image.metadata();
  ModalModelData data;
  data.node_count = metadata.node_count;
  data.mode_count = metadata.mode_count;
  data.rest_positions = image.floats(SectionId::rest_positions);
  data.mode_shapes = image.floats(SectionId::mode_shapes);
  data.omega_squared = image.floats(SectionId::omega_squared);
  data.modal_damping = image.floats(SectionId::modal_damping);
  data.surface_nodes = image.u32s(SectionId::surface_nodes);
  data.residual_compliance = image.floats(SectionId::residual_compliance);  // empty if absent
  return data;
}

}  // namespace trainer::model
