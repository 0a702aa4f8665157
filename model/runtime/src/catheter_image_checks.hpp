// Private to model/runtime: the consistency checks of a catheter image (docs/model-image.md,
// "What the loader checks", the catheter step), run by parse_model_image after the checks
// every kind shares (header, checksum, table, layout, metadata record, limits, finite floats).
#pragma once

#include <string_view>

#include "trainer/core/expected.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model::detail {

// Every field of the catheter_parameters record and the rest positions; each refusal names the
// file (`label`), the section and the field.
core::Expected<void> check_catheter_image(const ModelImage& image, std::string_view label);

}  // namespace trainer::model::detail
