// Catheter images (docs/model-image.md, "Catheter images"): the writer's record is the
// runtime's own derivation, the image loads back field for field without heap use, a catheter
// created from it is the catheter created from the parameters, and every field of the record
// and of the rest shape that the runtime relies on is checked — each semantically bad value,
// written with a valid checksum, refused with the file, the section and the field named.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "image_test_support.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/catheter_image.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model {
namespace {

using test::entry_of;
using test::failed_with;
using test::put;
using test::raw_metadata;
using test::raw_section;
using test::RawSection;
using test::recompute_checksum;

class CatheterImage : public ::testing::Test {
 protected:
  std::filesystem::path file() const { return directory_.path() / "catheter.img"; }
  std::string label() const { return file().string(); }

  core::Expected<ModelImage> load_bytes(const std::vector<std::byte>& bytes,
                                        ModelKind kind = ModelKind::catheter) {
    test::write_file(file(), bytes);
    arena_.reset();
    arena_.emplace(core::Arena::create(256 * 1024).value());
    return load_model_image(file(), *arena_, ImageLimits{}, kind);
  }

  // The small catheter's image with one record field set to `value`, checksum recomputed.
  template <class T>
  core::Expected<ModelImage> load_with_field(std::size_t field_offset, T value) {
    std::vector<std::byte> bytes = catheter_.bytes();
    put<T>(bytes, entry_of(bytes, SectionId::catheter_parameters).offset + field_offset, value);
    recompute_checksum(bytes);
    return load_bytes(bytes);
  }

  // A raw image (the writer refuses to produce broken ones) from a record and rest positions.
  std::vector<std::byte> raw_image(const CatheterParametersV1& record, std::size_t record_bytes,
                                   const std::vector<float>& positions, std::uint32_t rows) const {
    std::vector<std::uint8_t> payload(record_bytes, 0);
    std::memcpy(payload.data(), &record, std::min(record_bytes, sizeof record));
    ImageMetadataV1 metadata = offline::make_metadata();
    metadata.node_count = record.particle_count;
    return test::build_raw_image(
        ModelKind::catheter,
        {raw_metadata(metadata),
         raw_section(SectionId::catheter_parameters, ElementType::u8,
                     static_cast<std::uint32_t>(record_bytes), 1, payload),
         raw_section(SectionId::catheter_rest_positions, ElementType::f32, rows, 3, positions)});
  }

  std::vector<float> rest_positions() const {
    const CatheterParametersV1 record = catheter_.record();
    std::vector<Eigen::Vector3f> rest(record.particle_count);
    place_catheter_rest(catheter_.inputs.start_m,
                        Eigen::Vector3f(record.rest_direction[0], record.rest_direction[1],
                                        record.rest_direction[2]),
                        record.rest_length_m, rest);
    std::vector<float> flat;
    for (const Eigen::Vector3f& p : rest) flat.insert(flat.end(), p.begin(), p.end());
    return flat;
  }

  test::TemporaryDirectory directory_;
  std::optional<core::Arena> arena_;
  test::SmallCatheter catheter_;
};

// ---------------------------------------------------------------------------------------------
// Round trip

TEST_F(CatheterImage, TheRecordIsTheRuntimesDerivationAndLoadsBackFieldForField) {
  const offline::CatheterImageInputs& inputs = catheter_.inputs;
  auto chain = derive_catheter_chain(inputs.params);
  ASSERT_TRUE(chain) << chain.error().message;
  auto loaded = load_bytes(catheter_.bytes());
  ASSERT_TRUE(loaded) << loaded.error().message;
  const ModelImage& image = loaded.value();
  EXPECT_EQ(image.sections().size(), 3U);  // metadata, record, rest positions
  EXPECT_EQ(image.metadata().node_count, 5U);
  EXPECT_EQ(image.metadata().element_type, static_cast<std::uint32_t>(FiniteElementType::none));
  EXPECT_STREQ(image.metadata().tool_version, "modelc 0.1.0");

  const CatheterModelData data = catheter_model_data(image);
  EXPECT_EQ(std::memcmp(&data.params, &inputs.params, sizeof data.params), 0);
  EXPECT_EQ(data.chain.particle_count, 5U);
  EXPECT_EQ(data.chain.rest_length_m, chain->rest_length_m);
  EXPECT_EQ(data.chain.particle_mass_kg, chain->particle_mass_kg);
  EXPECT_EQ(data.chain.axial_n_per_m, chain->axial_n_per_m);
  EXPECT_EQ(data.chain.bending_n_m_per_rad, chain->bending_n_m_per_rad);
  EXPECT_EQ(data.chain.radius_m, 1e-3F);
  EXPECT_EQ(data.chain.damping_n_s_per_m, 5e-4F);
  EXPECT_EQ(data.chain.stable_substep_s, chain->stable_substep_s);
  EXPECT_EQ(data.max_substeps, 64U);
  EXPECT_TRUE(data.hold_start);
  EXPECT_EQ(data.rest_direction, catheter_rest_direction(inputs.direction).value());
  EXPECT_EQ(data.gravity_m_per_s2, Eigen::Vector3f(0.0F, 0.0F, -9.81F));
  EXPECT_EQ(data.contact.wall_stiffness_n_per_m, 500.0F);
  EXPECT_EQ(data.contact.wall_damping_n_s_per_m, 0.02F);
  EXPECT_EQ(data.contact.tool_stiffness_n_per_m, 300.0F);
  EXPECT_EQ(data.contact.grasp_stiffness_n_per_m, 3000.0F);
  EXPECT_EQ(data.contact.grasp_friction, 0.6F);
  EXPECT_EQ(data.contact.max_contact_force_n, 4.0F);
  // The rest positions are viewed in place, and are place_catheter_rest's.
  EXPECT_EQ(data.rest_positions_m.data(), image.floats(SectionId::catheter_rest_positions).data());
  EXPECT_EQ(std::vector<float>(data.rest_positions_m.begin(), data.rest_positions_m.end()),
            rest_positions());

  // Not a catheter image: empty data, which create() refuses.
  const CatheterModelData none = catheter_model_data(ModelImage{});
  EXPECT_EQ(none.chain.particle_count, 0U);
  EXPECT_TRUE(none.rest_positions_m.empty());
  core::Arena arena = core::Arena::create(64 * 1024).value();
  EXPECT_FALSE(Catheter::create(none, 1e-3F, 8, arena));
}

TEST_F(CatheterImage, LoadingAllocatesNothing) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  test::write_file(file(), catheter_.bytes());
  core::Arena arena = core::Arena::create(64 * 1024).value();
  const std::filesystem::path path = file();
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  auto loaded = load_model_image(path, arena, ImageLimits{}, ModelKind::catheter);
  core::alloc::end_counting_this_thread();
  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
}

TEST_F(CatheterImage, TheCatheterFromTheImageIsTheCatheterFromItsParameters) {
  auto loaded = load_bytes(catheter_.bytes());
  ASSERT_TRUE(loaded) << loaded.error().message;
  const CatheterModelData data = catheter_model_data(loaded.value());
  CatheterSetup setup;
  setup.start_position_m = catheter_.inputs.start_m;
  setup.direction = catheter_.inputs.direction;
  setup.max_substeps = catheter_.inputs.max_substeps;
  setup.max_contact_planes = 4;
  core::Arena arena = core::Arena::create(64 * 1024).value();
  auto from_params = Catheter::create(catheter_.inputs.params, setup, arena);
  auto from_image = Catheter::create(data, setup.haptic_period_s, 4, arena);
  ASSERT_TRUE(from_params) << from_params.error().message;
  ASSERT_TRUE(from_image) << from_image.error().message;
  EXPECT_EQ(from_image->substeps_per_period(), from_params->substeps_per_period());
  EXPECT_EQ(from_image->max_substeps(), 64U);
  EXPECT_EQ(from_image->max_contact_planes(), 4U);
  EXPECT_EQ(from_image->rest_direction(), from_params->rest_direction());
  for (std::uint32_t i = 0; i < 5; ++i) {
    EXPECT_EQ(from_image->rest_positions_m()[i], from_params->rest_positions_m()[i]) << i;
    EXPECT_EQ(from_image->positions_m()[i], from_params->positions_m()[i]) << i;
  }
  // The budget is checked against the period at create, as from parameters.
  const float long_period_s = 100.0F * data.chain.stable_substep_s;  // 100 substeps
  auto refused = Catheter::create(data, long_period_s, 4, arena);
  ASSERT_FALSE(refused);
  const std::uint64_t needed = catheter_substeps_for(static_cast<double>(long_period_s),
                                                     static_cast<double>(data.chain.stable_substep_s));
  EXPECT_GT(needed, 64U);
  EXPECT_NE(refused.error().message.find("needs " + std::to_string(needed) + " substeps"),
            std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("max_substeps = 64"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("EA = 157 N"), std::string::npos)
      << refused.error().message;
}

// ---------------------------------------------------------------------------------------------
// Sections and kinds

TEST_F(CatheterImage, SectionsOfOtherKindsAreRefusedBothWays) {
  std::vector<std::byte> bytes = catheter_.bytes();
  put<std::uint32_t>(bytes, test::entry_position(bytes, SectionId::catheter_rest_positions),
                     static_cast<std::uint32_t>(SectionId::rest_positions));
  recompute_checksum(bytes);
  EXPECT_TRUE(
      failed_with(load_bytes(bytes), label(),
                  "section 'rest_positions' does not belong in a catheter image (it is part of "
                  "modal_shell and tet_tensor)"));
  std::vector<std::byte> modal = test::SmallModalShell().bytes();
  put<std::uint32_t>(modal, test::entry_position(modal, SectionId::fixed_nodes),
                     static_cast<std::uint32_t>(SectionId::catheter_parameters));
  recompute_checksum(modal);
  EXPECT_TRUE(
      failed_with(load_bytes(modal, ModelKind::modal_shell), label(),
                  "section 'catheter_parameters' does not belong in a modal_shell image (it is "
                  "part of catheter)"));
  EXPECT_TRUE(failed_with(load_bytes(catheter_.bytes(), ModelKind::tet_tensor), label(),
                          "model_kind is catheter, the scene expects tet_tensor"));
}

TEST_F(CatheterImage, MissingSectionsAndWrongShapesAreRefused) {
  const CatheterParametersV1 record = catheter_.record();
  const std::vector<float> positions = rest_positions();
  ASSERT_TRUE(load_bytes(raw_image(record, sizeof record, positions, 5)));

  std::vector<RawSection> without_positions = {raw_metadata(offline::make_metadata())};
  EXPECT_TRUE(failed_with(
      load_bytes(test::build_raw_image(ModelKind::catheter, without_positions)), label(),
      "a catheter image needs section 'catheter_parameters', which is missing"));
  const std::vector<float> four(positions.begin(), positions.end() - 3);
  EXPECT_TRUE(
      failed_with(load_bytes(raw_image(record, sizeof record, four, 4)), label(),
                  "section 'catheter_rest_positions' has 4 rows, expected 5 (catheter_parameters "
                  "particle_count)"));
  EXPECT_TRUE(failed_with(load_bytes(raw_image(record, 124, positions, 5)), label(),
                          "section 'catheter_parameters' is 124 bytes, record version 3 has 128"));
  EXPECT_TRUE(failed_with(
      load_bytes(raw_image(record, 3, positions, 5)), label(),
      "section 'catheter_parameters' is 3 bytes: too short to hold its record_version"));
  // Another record version is refused before its size or any field is read.
  CatheterParametersV1 newer = record;
  newer.record_version = 4;
  EXPECT_TRUE(failed_with(load_bytes(raw_image(newer, 160, positions, 5)), label(),
                          "catheter record version 4, this build reads 3: rebuild it with modelc"));
  // Rest positions: a NaN is caught by the finite check of every float section.
  std::vector<float> with_nan = positions;
  with_nan[7] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(failed_with(load_bytes(raw_image(record, sizeof record, with_nan, 5)), label(),
                          "section 'catheter_rest_positions' element 7 (row 2, col 1) is nan"));
}

TEST_F(CatheterImage, MetadataMustDescribeAChain) {
  const auto metadata_field = [this](std::size_t offset, std::uint32_t value) {
    std::vector<std::byte> bytes = catheter_.bytes();
    put<std::uint32_t>(bytes, entry_of(bytes, SectionId::metadata).offset + offset, value);
    recompute_checksum(bytes);
    return load_bytes(bytes);
  };
  EXPECT_TRUE(failed_with(
      metadata_field(offsetof(ImageMetadataV1, node_count), 6), label(),
      "metadata node_count 6 differs from section 'catheter_parameters' particle_count 5"));
  EXPECT_TRUE(failed_with(metadata_field(offsetof(ImageMetadataV1, mode_count), 2), label(),
                          "a catheter image has no element, modes, surface nodes or correction"));
  EXPECT_TRUE(failed_with(metadata_field(offsetof(ImageMetadataV1, element_type), 3), label(),
                          "metadata element_type 3"));
}

// ---------------------------------------------------------------------------------------------
// The record, field by field (valid checksum: the field check is what refuses)

// Found by fuzz_model_image (docs/fuzzing.md): a record whose stable substep is a tiny positive
// float (a denormal passes "finite, > 0, at most the stability bound") loads, and counting the
// substeps of a haptic period converted ~1e40 to uint64_t — undefined behaviour, caught by
// UBSan. The count now saturates and the catheter is refused with the budget message.
TEST_F(CatheterImage, ATinyStableSubstepIsRefusedByTheBudgetNotConvertedOutOfRange) {
  EXPECT_EQ(catheter_substeps_for(1e-3, 1e-45), std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(catheter_substeps_for(1e-3, std::numeric_limits<double>::denorm_min()),
            std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(catheter_substeps_for(1e-3, 1e-23), std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(catheter_substeps_for(1e-3, 1e-12), 1000000000U);
  constexpr float kTiny = 1e-44F;  // a float denormal
  auto loaded = load_with_field(offsetof(CatheterParametersV1, stable_substep_s), kTiny);
  ASSERT_TRUE(loaded) << loaded.error().message;
  const CatheterModelData data = catheter_model_data(loaded.value());
  EXPECT_EQ(data.chain.stable_substep_s, kTiny);
  core::Arena arena = core::Arena::create(64 * 1024).value();
  auto refused = Catheter::create(data, 1e-3F, 4, arena);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("needs 18446744073709551615 substeps"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("max_substeps = 64"), std::string::npos)
      << refused.error().message;
}

TEST_F(CatheterImage, EveryRecordFieldIsChecked) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const CatheterParametersV1 good = catheter_.record();
  struct FloatCase {
    std::size_t offset;
    float value;
    const char* fragment;
  };
  const FloatCase floats[] = {
      {offsetof(CatheterParametersV1, particle_mass_kg), 0.0F,
       "section 'catheter_parameters' particle_mass_kg is 0, expected a finite value > 0"},
      {offsetof(CatheterParametersV1, particle_mass_kg), kNan, "particle_mass_kg is nan"},
      {offsetof(CatheterParametersV1, rest_length_m), -0.015F, "rest_length_m is -0.015"},
      {offsetof(CatheterParametersV1, axial_stiffness_n_per_m), kInf,
       "axial_stiffness_n_per_m is inf"},
      {offsetof(CatheterParametersV1, bending_stiffness_n_m_per_rad), 0.0F,
       "bending_stiffness_n_m_per_rad is 0"},
      {offsetof(CatheterParametersV1, radius_m), 0.0F, "radius_m is 0"},
      {offsetof(CatheterParametersV1, stable_substep_s), 0.0F, "stable_substep_s is 0"},
      {offsetof(CatheterParametersV1, length_m), kNan, "length_m is nan"},
      {offsetof(CatheterParametersV1, linear_density_kg_per_m), -1.0F,
       "linear_density_kg_per_m is -1"},
      {offsetof(CatheterParametersV1, max_contact_force_n), 0.0F, "max_contact_force_n is 0"},
      {offsetof(CatheterParametersV1, grasp_stiffness_n_per_m), kInf,
       "grasp_stiffness_n_per_m is inf"},
      {offsetof(CatheterParametersV1, damping_n_s_per_m), -5e-4F,
       "damping_n_s_per_m is -5e-04, expected a finite value >= 0"},
      {offsetof(CatheterParametersV1, grasp_friction), kNan, "grasp_friction is nan"},
      {offsetof(CatheterParametersV1, wall_damping_n_s_per_m), -1.0F,
       "wall_damping_n_s_per_m is -1"},
      {offsetof(CatheterParametersV1, gravity_m_per_s2) + 8, kInf, "gravity_m_per_s2[2] is inf"},
      {offsetof(CatheterParametersV1, rest_direction) + 4, kNan, "rest_direction[1] is nan"},
      // Unit rest tangent.
      {offsetof(CatheterParametersV1, rest_direction) + 4, 0.7F, "rest_direction has length"},
      // The chain against the beam it names: each constant off by a factor.
      {offsetof(CatheterParametersV1, length_m), 2.0F * good.length_m,
       "rest_length_m is 0.015, but length_m / (particle_count - 1) = 0.03"},
      {offsetof(CatheterParametersV1, particle_mass_kg), 1.01F * good.particle_mass_kg,
       ", but linear_density_kg_per_m * length_m / particle_count = 1.98e-05"},
      {offsetof(CatheterParametersV1, axial_stiffness_n), 100.0F,
       ", but axial_stiffness_n / rest_length_m"},
      {offsetof(CatheterParametersV1, bending_stiffness_n_m2), 1e-4F,
       "bending_stiffness_n_m_per_rad is"},
      // A substep above the stability bound of the record's own constants.
      {offsetof(CatheterParametersV1, stable_substep_s), 1.5F * good.stable_substep_s,
       "the chain would be integrated unstably"},
      // Contacts stiffer than the stiffest accepted one (1e5 m / h²: contacts are linearly
      // implicit and no longer shorten the substep).
      {offsetof(CatheterParametersV1, wall_stiffness_n_per_m), 1e9F,
       "wall_stiffness_n_per_m is 1e+09 N/m, above "},
      {offsetof(CatheterParametersV1, tool_stiffness_n_per_m), 1e9F,
       "the stiffest contact accepted"},
  };
  for (const FloatCase& c : floats) {
    EXPECT_TRUE(failed_with(load_with_field(c.offset, c.value), label(), c.fragment)) << c.fragment;
  }
  struct CountCase {
    std::size_t offset;
    std::uint32_t value;
    const char* fragment;
  };
  const CountCase counts[] = {
      {offsetof(CatheterParametersV1, record_version), 0,
       "catheter record version 0, this build reads 3: rebuild it with modelc"},
      {offsetof(CatheterParametersV1, record_version), 2,
       "catheter record version 2, this build reads 3"},
      {offsetof(CatheterParametersV1, record_version), 4,
       "catheter record version 4, this build reads 3"},
      {offsetof(CatheterParametersV1, particle_count), 2,
       "section 'catheter_parameters' particle_count is 2, expected 3..256"},
      {offsetof(CatheterParametersV1, particle_count), 257,
       "particle_count is 257, expected 3..256"},
      {offsetof(CatheterParametersV1, particle_count), 6, "metadata node_count 5 differs"},
      {offsetof(CatheterParametersV1, max_substeps), 0, "max_substeps is 0, expected 1..10000"},
      {offsetof(CatheterParametersV1, max_substeps), 10001,
       "max_substeps is 10001, expected 1..10000"},
      {offsetof(CatheterParametersV1, hold_start), 2, "hold_start is 2, expected 0 or 1"},
  };
  for (const CountCase& c : counts) {
    EXPECT_TRUE(failed_with(load_with_field(c.offset, c.value), label(), c.fragment)) << c.fragment;
  }
  EXPECT_TRUE(
      failed_with(load_with_field<std::uint8_t>(offsetof(CatheterParametersV1, reserved) + 19, 1),
                  label(), "section 'catheter_parameters' reserved byte 19 is not zero"));
}

TEST_F(CatheterImage, RestPositionsMustBeAStraightChainOfEqualSegments) {
  const CatheterParametersV1 record = catheter_.record();
  const std::vector<float> positions = rest_positions();
  // A particle 1 mm off the line breaks its two segments: the first is named.
  std::vector<float> bent = positions;
  bent[3 * 3] += 1e-3F;
  EXPECT_TRUE(failed_with(load_bytes(raw_image(record, sizeof record, bent, 5)), label(),
                          "section 'catheter_rest_positions' segment 2 (particles 2 to 3) is off "
                          "rest_length_m * rest_direction by 0.001"));
  // Segments 1 % long: the chain would start stretched.
  std::vector<float> stretched = positions;
  for (std::size_t i = 3; i < stretched.size(); ++i) {
    stretched[i] = positions[i % 3] + 1.01F * (positions[i] - positions[i % 3]);
  }
  EXPECT_TRUE(failed_with(load_bytes(raw_image(record, sizeof record, stretched, 5)), label(),
                          "segment 0 (particles 0 to 1) is off"));
  // Float rounding of a rest shape far from the origin stays within the tolerance.
  test::SmallCatheter far;
  far.inputs.start_m = Eigen::Vector3f(9.5F, -9.75F, 9.9F);
  EXPECT_TRUE(load_bytes(far.bytes()));
}

}  // namespace
}  // namespace trainer::model
