// A modal-shell image's sections as the runtime modal model's data: views into the loaded
// image (no copy), so what the trainer runs is exactly what modelc wrote.
#pragma once

#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_model.hpp"

namespace trainer::model {

ModalModelData modal_model_data(const ModelImage& image) noexcept;

}  // namespace trainer::model
