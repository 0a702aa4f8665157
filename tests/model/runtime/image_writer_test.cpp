// Model image writer (trainer::model::offline::ImageWriter): refuses values float32 cannot
// carry and sections the format does not allow (naming the section and the element), lays the
// file out as docs/model-image.md says, self-checks with the runtime parser, and writes
// atomically. Compiled into the image test program until model/offline builds it.
#include "trainer/model_offline/image_writer.hpp"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "image_test_support.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model::offline {
namespace {

using test::get;

::testing::AssertionResult refused_with(const core::Expected<void>& result,
                                        const std::string& fragment) {
  if (result) return ::testing::AssertionFailure() << "accepted, expected \"" << fragment << "\"";
  if (result.error().message.find(fragment) == std::string::npos) {
    return ::testing::AssertionFailure()
           << "message lacks \"" << fragment << "\": " << result.error().message;
  }
  return ::testing::AssertionSuccess();
}

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

TEST(ImageWriter, RefusesNonFiniteDoublesNamingSectionAndElement) {
  ImageWriter writer(ModelKind::modal_shell);
  const std::vector<double> values{1.0, kNan};
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::omega_squared, values, 2, 1),
                           "section 'omega_squared' element 1 (row 1, col 0) = nan is not finite"));
  const std::vector<double> infinite{-std::numeric_limits<double>::infinity(), 0.0};
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::modal_damping, infinite, 1, 2),
                           "section 'modal_damping' element 0 (row 0, col 0) = -inf is not "
                           "finite"));
  // A refused add leaves nothing behind: the same id can be added once fixed.
  EXPECT_TRUE(writer.add_f32(SectionId::omega_squared, std::vector<double>{1.0, 2.0}, 2, 1));
}

TEST(ImageWriter, RefusesDoublesOutsideTheFloatRange) {
  ImageWriter writer(ModelKind::modal_shell);
  EXPECT_TRUE(refused_with(
      writer.add_f32(SectionId::omega_squared, std::vector<double>{1.0, 1e39}, 2, 1),
      "section 'omega_squared' element 1 (row 1, col 0) = 1e+39 is outside the float32 range"));
  EXPECT_TRUE(
      refused_with(writer.add_f32(SectionId::omega_squared, std::vector<double>{-1e300, 1.0}, 2, 1),
                   "outside the float32 range"));
  // The largest float itself is representable.
  EXPECT_TRUE(writer.add_f32(
      SectionId::omega_squared,
      std::vector<double>{static_cast<double>(std::numeric_limits<float>::max()), 1.0}, 2, 1));
}

TEST(ImageWriter, RefusesNonFiniteFloats) {
  ImageWriter writer(ModelKind::modal_shell);
  const std::vector<float> values{0.0F, 1.0F, std::numeric_limits<float>::infinity()};
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::rest_positions, values, 1, 3),
                           "section 'rest_positions' element 2 (row 0, col 2) = inf is not "
                           "finite"));
}

TEST(ImageWriter, EigenMatrixErrorsNameRowAndColumn) {
  ImageWriter writer(ModelKind::modal_shell);
  Eigen::MatrixXd modes = Eigen::MatrixXd::Ones(3, 2);
  modes(2, 1) = kNan;
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::mode_shapes, modes),
                           "section 'mode_shapes' element 5 (row 2, col 1) = nan"));
  Eigen::MatrixXi triangles(2, 3);
  triangles << 0, 1, 2, 0, -1, 3;
  EXPECT_TRUE(refused_with(writer.add_u32(SectionId::triangles, triangles),
                           "section 'triangles' element 4 (row 1, col 1) = -1 is negative"));
}

TEST(ImageWriter, RefusesElementTypesTheFormatDoesNotAssign) {
  ImageWriter writer(ModelKind::modal_shell);
  const std::vector<std::uint32_t> indices{1, 2, 3};
  EXPECT_TRUE(refused_with(writer.add_u32(SectionId::mode_shapes, indices, 3, 1),
                           "section 'mode_shapes' holds element type 1 in the format, not 2"));
  const std::vector<float> floats{1.0F, 2.0F, 3.0F};
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::triangles, floats, 1, 3),
                           "section 'triangles' holds element type 2 in the format, not 1"));
  // No version-1 section holds i32 yet: every id refuses it.
  const std::vector<std::int32_t> signed_values{1};
  for (const SectionId id :
       {SectionId::rest_positions, SectionId::triangles, SectionId::fixed_nodes,
        SectionId::surface_nodes, SectionId::mode_shapes, SectionId::omega_squared,
        SectionId::modal_damping, SectionId::residual_compliance}) {
    EXPECT_TRUE(refused_with(writer.add_i32(id, signed_values, 1, 1), "not 3")) << section_name(id);
  }
  const std::vector<std::uint8_t> raw(sizeof(ImageMetadataV1), 0);
  EXPECT_TRUE(refused_with(writer.add_u8(SectionId::metadata, raw, sizeof(ImageMetadataV1), 1),
                           "section 'metadata' is written from set_metadata()"));
  EXPECT_TRUE(refused_with(writer.add_u8(static_cast<SectionId>(77), raw, 256, 1),
                           "section id 77 is not part of format version 1"));
}

TEST(ImageWriter, RefusesSectionsOfAnotherModelKind) {
  ImageWriter writer(ModelKind::modal_shell);
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::tensor_force, std::vector<float>{1.0F}, 1, 1),
                           "section 'tensor_force' belongs to tet_tensor images, this writer "
                           "builds a modal_shell image"));
  ImageWriter tensor_writer(ModelKind::tet_tensor);
  EXPECT_TRUE(
      refused_with(tensor_writer.add_f32(SectionId::mode_shapes, std::vector<float>{1.0F}, 1, 1),
                   "section 'mode_shapes' belongs to modal_shell images"));
}

TEST(ImageWriter, RefusesDuplicatesAndShapeMismatches) {
  ImageWriter writer(ModelKind::modal_shell);
  const std::vector<float> values{1.0F, 2.0F, 3.0F};
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::omega_squared, values, 2, 2),
                           "section 'omega_squared': rows × cols = 2 × 2 but 3 values were given"));
  EXPECT_TRUE(writer.add_f32(SectionId::omega_squared, values, 3, 1));
  EXPECT_TRUE(refused_with(writer.add_f32(SectionId::omega_squared, values, 3, 1),
                           "section 'omega_squared' was already added"));
}

TEST(ImageWriter, RequiresMetadata) {
  ImageWriter writer(ModelKind::tet_tensor);
  const auto bytes = writer.serialize();
  ASSERT_FALSE(bytes);
  EXPECT_NE(bytes.error().message.find("set_metadata() was not called"), std::string::npos);
}

TEST(ImageWriter, SelfCheckRefusesAnInconsistentModel) {
  const test::SmallModalShell model;
  ImageWriter writer(ModelKind::modal_shell);
  writer.set_metadata(model.metadata);
  ASSERT_TRUE(writer.add_f32(SectionId::rest_positions, model.rest_positions_m));
  ASSERT_TRUE(writer.add_u32(SectionId::triangles, model.triangles));
  ASSERT_TRUE(writer.add_f32(SectionId::mode_shapes, model.mode_shapes));
  ASSERT_TRUE(writer.add_f32(SectionId::omega_squared, model.omega_squared, 2, 1));
  const auto bytes = writer.serialize();
  ASSERT_FALSE(bytes);
  EXPECT_EQ(bytes.error().message,
            "image being written: a modal_shell image needs section 'modal_damping', which is "
            "missing");

  test::TemporaryDirectory directory;
  const std::filesystem::path path = directory.path() / "bad.img";
  const auto written = writer.write(path);
  ASSERT_FALSE(written);
  EXPECT_EQ(written.error().message.rfind(path.string() + ": not written: ", 0), 0U);
  EXPECT_TRUE(std::filesystem::is_empty(directory.path()));
}

TEST(ImageWriter, SerializeAppliesTheGivenLimits) {
  const test::SmallModalShell model;
  ImageLimits limits = ImageWriter::permissive_limits();
  limits.max_mode_count = 1;
  const auto bytes = model.writer().serialize(limits);
  ASSERT_FALSE(bytes);
  EXPECT_NE(bytes.error().message.find("mode_count 2 exceeds the limit of 1"), std::string::npos);
}

TEST(ImageWriter, LayoutFollowsTheSpec) {
  const std::vector<std::byte> bytes = test::SmallModalShell().bytes();
  ASSERT_FALSE(bytes.empty());
  EXPECT_EQ(std::memcmp(bytes.data(), "HTRMODEL", 8), 0);
  EXPECT_EQ(get<std::uint32_t>(bytes, 8), 1U);
  EXPECT_EQ(get<std::uint32_t>(bytes, 12), 128U);
  EXPECT_EQ(get<std::uint32_t>(bytes, 16), 0x01020304U);
  EXPECT_EQ(get<std::uint32_t>(bytes, 20), 1U);
  EXPECT_EQ(get<std::uint64_t>(bytes, 24), bytes.size());
  const auto count = get<std::uint32_t>(bytes, 32);
  EXPECT_EQ(count, 9U);
  EXPECT_EQ(get<std::uint32_t>(bytes, 36), 128U);
  for (std::size_t i = 48; i < 128; ++i) EXPECT_EQ(bytes[i], std::byte{0}) << "reserved " << i;

  // Table sorted by id, metadata first; sections packed at the next 64-byte boundary.
  std::uint32_t previous_id = 0;
  std::uint64_t cursor = 128 + std::uint64_t{count} * 32;
  for (std::uint32_t i = 0; i < count; ++i) {
    const auto entry = get<SectionEntryV1>(bytes, 128 + std::size_t{i} * 32);
    EXPECT_GT(entry.id, previous_id);
    previous_id = entry.id;
    EXPECT_EQ(entry.offset % 64, 0U);
    EXPECT_EQ(entry.offset, (cursor + 63) / 64 * 64)
        << section_name(static_cast<SectionId>(entry.id));
    EXPECT_EQ(entry.element_count, std::uint64_t{entry.rows} * entry.cols);
    cursor = entry.offset + entry.element_count * element_type_bytes(entry.element_type);
  }
  EXPECT_EQ(cursor, bytes.size());
  const auto metadata = get<SectionEntryV1>(bytes, 128);
  EXPECT_EQ(metadata.id, 1U);
  EXPECT_EQ(metadata.element_type, 4U);
  EXPECT_EQ(metadata.rows, 256U);
  EXPECT_EQ(metadata.cols, 1U);
}

TEST(ImageWriter, OutputDoesNotDependOnTheOrderSectionsWereAdded) {
  const test::SmallModalShell model;
  ImageWriter reversed(ModelKind::modal_shell);
  reversed.set_metadata(model.metadata);
  ASSERT_TRUE(reversed.add_f32(SectionId::residual_compliance, model.residual_compliance));
  ASSERT_TRUE(reversed.add_f32(SectionId::modal_damping, model.modal_damping, 2, 1));
  ASSERT_TRUE(reversed.add_f32(SectionId::omega_squared, model.omega_squared, 2, 1));
  ASSERT_TRUE(reversed.add_f32(SectionId::mode_shapes, model.mode_shapes));
  ASSERT_TRUE(reversed.add_u32(SectionId::surface_nodes, model.surface_nodes, 2, 1));
  ASSERT_TRUE(reversed.add_u32(SectionId::fixed_nodes, model.fixed_nodes, 1, 1));
  ASSERT_TRUE(reversed.add_u32(SectionId::triangles, model.triangles));
  ASSERT_TRUE(reversed.add_f32(SectionId::rest_positions, model.rest_positions_m));
  const auto bytes = reversed.serialize();
  ASSERT_TRUE(bytes) << bytes.error().message;
  EXPECT_EQ(bytes.value(), model.bytes());
}

TEST(ImageWriter, EigenInputOfAnyStorageOrderIsWrittenRowMajor) {
  // A complete (smallest) tet_tensor image whose 3 × 9 displacement tensors are given once as a
  // row-major float matrix and once as the transpose of a column-major double matrix.
  const test::SmallTetTensor tet;
  const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> row_major =
      tet.displacement_tensors.cast<float>();
  const Eigen::MatrixXd column_major = tet.displacement_tensors.transpose();  // 9 × 3
  for (int variant = 0; variant < 2; ++variant) {
    ImageWriter writer(ModelKind::tet_tensor);
    writer.set_metadata(tet.metadata);
    ASSERT_TRUE(writer.add_f32(SectionId::rest_positions, tet.rest_positions_m));
    ASSERT_TRUE(writer.add_u32(SectionId::triangles, tet.triangles));
    ASSERT_TRUE(writer.add_u32(SectionId::fixed_nodes, tet.fixed_nodes, 1, 1));
    ASSERT_TRUE(writer.add_u32(SectionId::surface_nodes, tet.contact_nodes, 1, 1));
    ASSERT_TRUE(writer.add_u32(SectionId::tensor_nodes, tet.stored_nodes, 3, 1));
    ASSERT_TRUE(writer.add_f32(SectionId::tensor_force, std::span<const double>(tet.force_tensor), 1, 9));
    const auto added =
        variant == 0 ? writer.add_f32(SectionId::tensor_displacement, row_major)
                     : writer.add_f32(SectionId::tensor_displacement, column_major.transpose());
    ASSERT_TRUE(added) << added.error().message;
    auto bytes = writer.serialize();
    ASSERT_TRUE(bytes) << bytes.error().message;
    const auto entry = test::entry_of(bytes.value(), SectionId::tensor_displacement);
    EXPECT_EQ(entry.rows, 3U);
    EXPECT_EQ(entry.cols, 9U);
    // (row, col) at row * cols + col whatever the input's storage order.
    for (Eigen::Index r = 0; r < 3; ++r) {
      for (Eigen::Index c = 0; c < 9; ++c) {
        EXPECT_EQ(get<float>(bytes.value(), entry.offset + static_cast<std::size_t>(r * 9 + c) *
                                                                sizeof(float)),
                  static_cast<float>(tet.displacement_tensors(r, c)))
            << "variant " << variant << " element " << r << "," << c;
      }
    }
  }
}

TEST(ImageWriter, ToolVersionMustFitWithItsTerminator) {
  ImageMetadataV1 metadata{};
  EXPECT_TRUE(set_tool_version(metadata, std::string(31, 'v')));
  EXPECT_EQ(std::string(metadata.tool_version), std::string(31, 'v'));
  EXPECT_TRUE(refused_with(set_tool_version(metadata, std::string(32, 'v')),
                           "is 32 characters, at most 31 fit"));
  EXPECT_TRUE(set_tool_version(metadata, "short"));
  EXPECT_STREQ(metadata.tool_version, "short");  // earlier, longer contents cleared
}

TEST(ImageWriter, MakeMetadataMarksUnmeasuredErrorsAndStampsTheTime) {
  const auto now_s =
      static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                     std::chrono::system_clock::now().time_since_epoch())
                                     .count());
  const ImageMetadataV1 metadata = make_metadata();
  EXPECT_TRUE(std::isnan(metadata.error_estimate));
  EXPECT_TRUE(std::isnan(metadata.error_budget));
  EXPECT_GE(metadata.created_unix_s + 5, now_s);
  EXPECT_LE(metadata.created_unix_s, now_s + 5);
  EXPECT_EQ(metadata.mode_count, 0U);
}

TEST(ImageWriter, WriteReplacesTheFileAtomicallyAndLeavesNoTemporary) {
  test::TemporaryDirectory directory;
  const std::filesystem::path path = directory.path() / "duct.img";
  test::write_file(path, std::vector<std::byte>(10, std::byte{0x55}));  // an older file

  const test::SmallModalShell model;
  const auto written = model.writer().write(path);
  ASSERT_TRUE(written) << written.error().message;
  EXPECT_EQ(test::read_file(path), model.bytes());
  std::size_t entries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(directory.path())) {
    EXPECT_EQ(entry.path().filename(), "duct.img");
    ++entries;
  }
  EXPECT_EQ(entries, 1U);

  auto arena = core::Arena::create(64 * 1024);
  ASSERT_TRUE(arena);
  const auto loaded = load_model_image(path, arena.value(), ImageLimits{}, ModelKind::modal_shell);
  EXPECT_TRUE(loaded) << loaded.error().message;
}

TEST(ImageWriter, WriteIntoAMissingDirectoryFails) {
  test::TemporaryDirectory directory;
  const std::filesystem::path path = directory.path() / "missing" / "duct.img";
  const auto written = test::SmallModalShell().writer().write(path);
  ASSERT_FALSE(written);
  EXPECT_NE(written.error().message.find("cannot create the temporary file"), std::string::npos)
      << written.error().message;
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(ImageWriter, FailedRenameRemovesTheTemporary) {
  test::TemporaryDirectory directory;
  // A non-empty directory where the image should go: rename(2) cannot replace it.
  const std::filesystem::path path = directory.path() / "duct.img";
  std::filesystem::create_directories(path / "occupied");
  const auto written = test::SmallModalShell().writer().write(path);
  ASSERT_FALSE(written);
  EXPECT_NE(written.error().message.find("cannot rename"), std::string::npos)
      << written.error().message;
  std::size_t entries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(directory.path())) {
    EXPECT_EQ(entry.path().filename(), "duct.img");
    ++entries;
  }
  EXPECT_EQ(entries, 1U);
}

}  // namespace
}  // namespace trainer::model::offline
