// The catheter image writer (`modelc build` for a kind = "catheter" definition): derives the
// chain with the runtime's own derive_catheter_chain() and place_catheter_rest() — the
// functions Catheter::create(params, setup) uses — and stores the result in the model image
// container (docs/model-image.md, "Catheter images"), so a catheter created from the image is
// bit-identical to one created from the same parameters. Tool code: returns core::Expected.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model/catheter_chain.hpp"
#include "trainer/model/image_format.hpp"

namespace trainer::model::offline {

// Everything a catheter image records, in the runtime's precision, as the trainer hands a
// definition to Catheter::create(params, setup), plus the trainer's own settings.
struct CatheterImageInputs {
  CatheterParams params;
  Eigen::Vector3f start_m = Eigen::Vector3f::Zero();     // particle 0 ([pose] start_m)
  Eigen::Vector3f direction = Eigen::Vector3f::UnitX();  // rest tangent, any length (normalised)
  std::uint32_t max_substeps = 0;                        // 1..kMaxCatheterSubsteps
  bool hold_start = false;
  Eigen::Vector3f gravity_m_per_s2 = Eigen::Vector3f::Zero();
  CatheterContactSettings contact;
};

// The parameter record of `inputs` (derivation refused as Catheter::create would refuse it).
core::Expected<CatheterParametersV1> make_catheter_record(const CatheterImageInputs& inputs);

// Serialises (and checks with the runtime parser) a catheter image, or writes it atomically.
core::Expected<std::vector<std::byte>> serialize_catheter_image(const CatheterImageInputs& inputs);
core::Expected<void> write_catheter_image(const std::filesystem::path& path,
                                          const CatheterImageInputs& inputs);

}  // namespace trainer::model::offline
