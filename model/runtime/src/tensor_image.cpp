#include "trainer/model/tensor_image.hpp"

namespace trainer::model {

TensorModelData tensor_model_data(const ModelImage& image) noexcept {
  TensorModelData data;
  data.node_count = image.metadata().node_count;
  data.rest_positions = image.floats(SectionId::rest_positions);
  data.contact_nodes = image.u32s(SectionId::surface_nodes);
  data.response_nodes = image.u32s(SectionId::tensor_nodes);
  data.displacement_tensors = image.floats(SectionId::tensor_displacement);
  data.force_tensors = image.floats(SectionId::tensor_force);
  return data;
}

}  // namespace trainer::model
