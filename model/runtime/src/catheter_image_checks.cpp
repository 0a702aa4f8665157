// Consistency of a catheter image (docs/model-image.md, "What the loader checks", step 13): the
// catheter_parameters record (its version first, then every field) and the rest positions.
// The checksum has already passed, so everything refused here is what a writer produced (or
// someone edited and re-checksummed): values the runtime would run unstable or misread.
#include "catheter_image_checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "image_checks.hpp"
#include "trainer/model/catheter_chain.hpp"

namespace trainer::model::detail {
namespace {

using core::Expected;

constexpr const char* kRecord = "section 'catheter_parameters' ";

// The chain constants against the physical parameters they were derived from: each is one
// double division or product rounded once to float from float inputs (relative error ~1e-7),
// so 1e-6 holds every honest image and refuses any real inconsistency.
constexpr double kDerivationTolerance = 1e-6;
// |rest_direction| may differ from 1 by float rounding of a normalisation (~1e-7).
constexpr double kUnitTolerance = 1e-5;

struct NamedFloat {
  const char* name;
  float value;
};

Expected<void> field_error(std::string_view label, const char* field, const std::string& what) {
  return image_error(label, std::string(kRecord) + field + " " + what);
}

Expected<CatheterParametersV1> read_parameters(const ModelImage& image, std::string_view label) {
  for (const SectionId id : {SectionId::catheter_parameters, SectionId::catheter_rest_positions}) {
    if (!image.has(id)) {
      return image_error(label,
                         "a catheter image needs " + section_label(id) + ", which is missing");
    }
  }
  const std::span<const std::uint8_t> bytes = image.u8s(SectionId::catheter_parameters);
  if (bytes.size() < sizeof(std::uint32_t)) {
    return image_error(label, std::string(kRecord) + "is " + std::to_string(bytes.size()) +
                                  " bytes: too short to hold its record_version");
  }
  const auto version = read_record<std::uint32_t>(reinterpret_cast<const std::byte*>(bytes.data()));
  if (version != kCatheterRecordVersion) {
    return image_error(label, "catheter record version " + std::to_string(version) +
                                  ", this build reads " + std::to_string(kCatheterRecordVersion) +
                                  ": rebuild it with modelc");
  }
  if (bytes.size() != sizeof(CatheterParametersV1)) {
    return image_error(label, std::string(kRecord) + "is " + std::to_string(bytes.size()) +
                                  " bytes, record version " +
                                  std::to_string(kCatheterRecordVersion) + " has " +
                                  std::to_string(sizeof(CatheterParametersV1)));
  }
  const auto record =
      read_record<CatheterParametersV1>(reinterpret_cast<const std::byte*>(bytes.data()));
  for (std::size_t i = 0; i < sizeof record.reserved; ++i) {
    if (record.reserved[i] != 0) {
      return image_error(
          label, std::string(kRecord) + "reserved byte " + std::to_string(i) + " is not zero");
    }
  }
  return record;
}

// Counts and flags, and the metadata fields a catheter image fixes.
Expected<void> check_counts(const CatheterParametersV1& record, const ImageMetadataV1& metadata,
                            std::string_view label) {
  if (record.particle_count < 3 || record.particle_count > kMaxCatheterParticles) {
    return field_error(label, "particle_count",
                       "is " + std::to_string(record.particle_count) + ", expected 3.." +
                           std::to_string(kMaxCatheterParticles));
  }
  if (metadata.node_count != record.particle_count) {
    return image_error(label, "metadata node_count " + std::to_string(metadata.node_count) +
                                  " differs from " + kRecord + "particle_count " +
                                  std::to_string(record.particle_count));
  }
  if (metadata.element_type != static_cast<std::uint32_t>(FiniteElementType::none) ||
      metadata.mode_count != 0 || metadata.surface_node_count != 0 ||
      metadata.static_correction != 0) {
    return image_error(
        label, "metadata element_type " + std::to_string(metadata.element_type) + ", mode_count " +
                   std::to_string(metadata.mode_count) + ", surface_node_count " +
                   std::to_string(metadata.surface_node_count) + ", static_correction " +
                   std::to_string(metadata.static_correction) +
                   ": a catheter image has no element, modes, surface nodes or "
                   "correction (all 0)");
  }
  if (record.max_substeps < 1 || record.max_substeps > kMaxCatheterSubsteps) {
    return field_error(label, "max_substeps",
                       "is " + std::to_string(record.max_substeps) + ", expected 1.." +
                           std::to_string(kMaxCatheterSubsteps));
  }
  if (record.hold_start > 1) {
    return field_error(label, "hold_start",
                       "is " + std::to_string(record.hold_start) + ", expected 0 or 1");
  }
  return {};
}

Expected<void> check_values(const CatheterParametersV1& r, std::string_view label) {
  const NamedFloat positive[] = {
      {"rest_length_m", r.rest_length_m},
      {"particle_mass_kg", r.particle_mass_kg},
      {"axial_stiffness_n_per_m", r.axial_stiffness_n_per_m},
      {"bending_stiffness_n_m_per_rad", r.bending_stiffness_n_m_per_rad},
      {"radius_m", r.radius_m},
      {"stable_substep_s", r.stable_substep_s},
      {"length_m", r.length_m},
      {"bending_stiffness_n_m2", r.bending_stiffness_n_m2},
      {"axial_stiffness_n", r.axial_stiffness_n},
      {"linear_density_kg_per_m", r.linear_density_kg_per_m},
      {"wall_stiffness_n_per_m", r.wall_stiffness_n_per_m},
      {"tool_stiffness_n_per_m", r.tool_stiffness_n_per_m},
      {"grasp_stiffness_n_per_m", r.grasp_stiffness_n_per_m},
      {"max_contact_force_n", r.max_contact_force_n},
  };
  for (const NamedFloat& field : positive) {
    if (!std::isfinite(field.value) || !(field.value > 0.0F)) {
      return field_error(label, field.name,
                         "is " + number(field.value) + ", expected a finite value > 0");
    }
  }
  const NamedFloat non_negative[] = {
      {"damping_n_s_per_m", r.damping_n_s_per_m},
      {"wall_damping_n_s_per_m", r.wall_damping_n_s_per_m},
      {"grasp_friction", r.grasp_friction},
  };
  for (const NamedFloat& field : non_negative) {
    if (!std::isfinite(field.value) || field.value < 0.0F) {
      return field_error(label, field.name,
                         "is " + number(field.value) + ", expected a finite value >= 0");
    }
  }
  const NamedFloat vectors[] = {
      {"rest_direction[0]", r.rest_direction[0]},
      {"rest_direction[1]", r.rest_direction[1]},
      {"rest_direction[2]", r.rest_direction[2]},
      {"gravity_m_per_s2[0]", r.gravity_m_per_s2[0]},
      {"gravity_m_per_s2[1]", r.gravity_m_per_s2[1]},
      {"gravity_m_per_s2[2]", r.gravity_m_per_s2[2]},
  };
  for (const NamedFloat& field : vectors) {
    if (!std::isfinite(field.value)) {
      return field_error(label, field.name,
                         "is " + number(field.value) + ", expected a finite value");
    }
  }
  const double norm =
      std::hypot(static_cast<double>(r.rest_direction[0]), static_cast<double>(r.rest_direction[1]),
                 static_cast<double>(r.rest_direction[2]));
  if (std::fabs(norm - 1.0) > kUnitTolerance) {
    return field_error(
        label, "rest_direction",
        "has length " + number(static_cast<float>(norm)) + ", expected a unit vector (to 1e-5)");
  }
  return {};
}

// The chain against the beam it was derived from (docs/catheter.md), the stored substep against
// the stability bound of the stored constants, and the contact stiffnesses against the limit
// that substep keeps stable.
Expected<void> check_derivation(const CatheterParametersV1& r, std::string_view label) {
  const auto d = [](float value) { return static_cast<double>(value); };
  const double count = static_cast<double>(r.particle_count);
  struct Relation {
    const char* field;
    float stored;
    double expected;
    const char* rule;
  };
  const Relation relations[] = {
      {"rest_length_m", r.rest_length_m, d(r.length_m) / (count - 1.0),
       "length_m / (particle_count - 1)"},
      {"particle_mass_kg", r.particle_mass_kg, d(r.linear_density_kg_per_m) * d(r.length_m) / count,
       "linear_density_kg_per_m * length_m / particle_count"},
      {"axial_stiffness_n_per_m", r.axial_stiffness_n_per_m,
       d(r.axial_stiffness_n) / d(r.rest_length_m), "axial_stiffness_n / rest_length_m"},
      {"bending_stiffness_n_m_per_rad", r.bending_stiffness_n_m_per_rad,
       d(r.bending_stiffness_n_m2) / d(r.rest_length_m), "bending_stiffness_n_m2 / rest_length_m"},
  };
  for (const Relation& relation : relations) {
    if (!(std::fabs(d(relation.stored) - relation.expected) <=
          kDerivationTolerance * relation.expected)) {
      // Both printed as floats: the precision the record holds.
      return field_error(label, relation.field,
                         "is " + number(relation.stored) + ", but " + relation.rule + " = " +
                             number(static_cast<float>(relation.expected)) +
                             " (to a relative 1e-6)");
    }
  }
  const double bound = catheter_stable_substep_s(
      d(r.particle_mass_kg), d(r.bending_stiffness_n_m_per_rad), d(r.rest_length_m),
      d(catheter_contact_stiffness(r.wall_stiffness_n_per_m, r.tool_stiffness_n_per_m)));
  if (!(d(r.stable_substep_s) <= bound * (1.0 + kDerivationTolerance))) {
    return field_error(
        label, "stable_substep_s",
        "is " + number(r.stable_substep_s) + " s, above the largest substep " +
            number(static_cast<float>(bound)) +
            " s of the record's own mass, bending stiffness and segment"
            ": the chain would be integrated unstably");
  }
  const float limit = contact_stiffness_limit_n_per_m(r.particle_mass_kg, r.stable_substep_s);
  for (const NamedFloat& field : {NamedFloat{"wall_stiffness_n_per_m", r.wall_stiffness_n_per_m},
                                  NamedFloat{"tool_stiffness_n_per_m", r.tool_stiffness_n_per_m}}) {
    if (field.value > limit) {
      return field_error(
          label, field.name,
          "is " + number(field.value) + " N/m, above " + number(limit) +
              " N/m, the stiffest contact accepted (1e5 particle_mass_kg / "
              "stable_substep_s^2)");
    }
  }
  return {};
}

// The straight rest shape: every segment is rest_length_m along rest_direction. Tolerance
// 1e-4 l0 plus 1e-6 of the coordinates' size: float rounding of start + (i l0) d is a few
// 1e-7 of max(|p|, L), and L ≤ 255 l0.
Expected<void> check_rest_positions(const ModelImage& image, const CatheterParametersV1& r,
                                    std::string_view label) {
  if (auto ok = require_rows(image, SectionId::catheter_rest_positions, r.particle_count,
                             "catheter_parameters particle_count", label);
      !ok) {
    return ok;
  }
  const std::span<const float> positions = image.floats(SectionId::catheter_rest_positions);
  const auto at = [&positions](std::size_t particle, int axis) {
    return static_cast<double>(positions[3 * particle + static_cast<std::size_t>(axis)]);
  };
  const double l0 = static_cast<double>(r.rest_length_m);
  for (std::size_t i = 0; i + 1 < r.particle_count; ++i) {
    double deviation = 0.0;
    double size = 0.0;
    for (int axis = 0; axis < 3; ++axis) {
      const double expected = l0 * static_cast<double>(r.rest_direction[axis]);
      deviation = std::max(deviation, std::fabs(at(i + 1, axis) - at(i, axis) - expected));
      size = std::max({size, std::fabs(at(i, axis)), std::fabs(at(i + 1, axis))});
    }
    const double tolerance = 1e-4 * l0 + 1e-6 * size;
    if (!(deviation <= tolerance)) {
      return image_error(label, "section 'catheter_rest_positions' segment " + std::to_string(i) +
                                    " (particles " + std::to_string(i) + " to " +
                                    std::to_string(i + 1) +
                                    ") is off rest_length_m * rest_direction by " +
                                    number(static_cast<float>(deviation)) + " m (tolerance " +
                                    number(static_cast<float>(tolerance)) +
                                    " m): the rest shape is a straight chain of equal segments");
    }
  }
  return {};
}

}  // namespace

Expected<void> check_catheter_image(const ModelImage& image, std::string_view label) {
  auto record = read_parameters(image, label);
  if (!record) return std::move(record).error();
  if (auto ok = check_counts(record.value(), image.metadata(), label); !ok) return ok;
  if (auto ok = check_values(record.value(), label); !ok) return ok;
  if (auto ok = check_derivation(record.value(), label); !ok) return ok;
  return check_rest_positions(image, record.value(), label);
}

}  // namespace trainer::model::detail
