// A tet_tensor image's sections as the runtime tensor model's data: views into the loaded
// image (no copy), so what the trainer runs is exactly what modelc wrote.
#pragma once

#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_model.hpp"

namespace trainer::model {

TensorModelData tensor_model_data(const ModelImage& image) noexcept;

}  // namespace trainer::model
