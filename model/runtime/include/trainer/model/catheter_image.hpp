// A catheter image's sections as the runtime catheter's data: the parameter record copied out
// (its floats exactly as modelc wrote them) and a view of the rest positions in the loaded
// image, so what the trainer runs is exactly what modelc wrote. Then
// Catheter::create(data, haptic_period_s, max_contact_planes, arena).
#pragma once

#include "trainer/model/catheter_chain.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model {

// `image` must be a loaded catheter image (load_model_image(..., ModelKind::catheter)), which
// must outlive the result; for any other image the result is empty (particle_count 0), and
// Catheter::create refuses it.
CatheterModelData catheter_model_data(const ModelImage& image) noexcept;

}  // namespace trainer::model
