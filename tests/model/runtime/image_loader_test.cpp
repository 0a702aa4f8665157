// Model image loader (trainer::model::load_model_image): a written image loads back bit for
// bit without heap use, and every way an image can be damaged or inconsistent is refused with
// its own message naming the file and the field. Corruptions placed after the checksum field
// get a recomputed checksum so the specific check, not the checksum, is what fires.
#include "trainer/model/image_loader.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

#include "image_test_support.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"

namespace trainer::model {
namespace {

using test::build_raw_image;
using test::entry_of;
using test::entry_position;
using test::failed_with;
using test::get;
using test::put;
using test::put_entry;
using test::raw_metadata;
using test::raw_section;
using test::RawSection;
using test::recompute_checksum;

constexpr std::size_t kArenaBytes = 64 * 1024;

class ModelImageLoad : public ::testing::Test {
 protected:
  std::filesystem::path file() const { return directory_.path() / "duct.img"; }
  std::string label() const { return file().string(); }

  core::Expected<ModelImage> load(ModelKind kind = ModelKind::modal_shell,
                                  const ImageLimits& limits = {},
                                  std::size_t arena_bytes = kArenaBytes) {
    arena_.reset();
    arena_.emplace(core::Arena::create(arena_bytes).value());
    return load_model_image(file(), *arena_, limits, kind);
  }

  core::Expected<ModelImage> load_bytes(const std::vector<std::byte>& bytes,
                                        ModelKind kind = ModelKind::modal_shell,
                                        const ImageLimits& limits = {}) {
    test::write_file(file(), bytes);
    return load(kind, limits);
  }

  // The small model's image with `patch` applied and the checksum recomputed.
  template <class Patch>
  core::Expected<ModelImage> load_patched(Patch patch, ModelKind kind = ModelKind::modal_shell) {
    std::vector<std::byte> bytes = model_.bytes();
    patch(bytes);
    recompute_checksum(bytes);
    return load_bytes(bytes, kind);
  }

  test::TemporaryDirectory directory_;
  std::optional<core::Arena> arena_;
  test::SmallModalShell model_;
};

// The small model's sections as raw sections (for images the writer would refuse to write).
std::vector<RawSection> raw_small_model(const test::SmallModalShell& model) {
  auto row_major = [](const auto& matrix) {
    using Scalar = typename std::decay_t<decltype(matrix)>::Scalar;
    std::vector<Scalar> values;
    for (Eigen::Index row = 0; row < matrix.rows(); ++row) {
      for (Eigen::Index col = 0; col < matrix.cols(); ++col) values.push_back(matrix(row, col));
    }
    return values;
  };
  auto to_float = [](const std::vector<double>& values) {
    std::vector<float> floats;
    for (const double value : values) floats.push_back(static_cast<float>(value));
    return floats;
  };
  std::vector<std::uint32_t> triangles;
  for (const int index : row_major(model.triangles)) {
    triangles.push_back(static_cast<std::uint32_t>(index));
  }
  return {
      raw_metadata(model.metadata),
      raw_section(SectionId::rest_positions, ElementType::f32, 4, 3,
                  to_float(row_major(model.rest_positions_m))),
      raw_section(SectionId::triangles, ElementType::u32, 2, 3, triangles),
      raw_section(SectionId::fixed_nodes, ElementType::u32, 1, 1, model.fixed_nodes),
      raw_section(SectionId::surface_nodes, ElementType::u32, 2, 1, model.surface_nodes),
      raw_section(SectionId::mode_shapes, ElementType::f32, 12, 2,
                  to_float(row_major(model.mode_shapes))),
      raw_section(SectionId::omega_squared, ElementType::f32, 2, 1, to_float(model.omega_squared)),
      raw_section(SectionId::modal_damping, ElementType::f32, 2, 1, to_float(model.modal_damping)),
      raw_section(SectionId::residual_compliance, ElementType::f32, 6, 6,
                  to_float(row_major(model.residual_compliance))),
  };
}

RawSection& raw_find(std::vector<RawSection>& sections, SectionId id) {
  for (RawSection& section : sections) {
    if (section.id == static_cast<std::uint32_t>(id)) return section;
  }
  ADD_FAILURE() << "no raw section " << section_name(id);
  return sections.front();
}

void raw_erase(std::vector<RawSection>& sections, SectionId id) {
  std::erase_if(sections, [id](const RawSection& section) {
    return section.id == static_cast<std::uint32_t>(id);
  });
}

template <class T>
void raw_set(std::vector<RawSection>& sections, SectionId id, std::size_t index, T value) {
  std::memcpy(raw_find(sections, id).payload.data() + index * sizeof(T), &value, sizeof value);
}

// ---------------------------------------------------------------------------------------------
// Success path

TEST_F(ModelImageLoad, RoundTripKeepsEveryValueAndMetadataField) {
  test::write_file(file(), model_.bytes());
  auto loaded = load();
  ASSERT_TRUE(loaded) << loaded.error().message;
  const ModelImage& image = loaded.value();

  EXPECT_FALSE(image.empty());
  EXPECT_EQ(image.model_kind(), ModelKind::modal_shell);
  EXPECT_EQ(image.sections().size(), 9U);

  const std::span<const float> positions = image.floats(SectionId::rest_positions);
  ASSERT_EQ(image.rows(SectionId::rest_positions), 4U);
  ASSERT_EQ(image.cols(SectionId::rest_positions), 3U);
  ASSERT_EQ(positions.size(), 12U);
  for (Eigen::Index row = 0; row < 4; ++row) {
    for (Eigen::Index col = 0; col < 3; ++col) {
      EXPECT_EQ(positions[static_cast<std::size_t>(row * 3 + col)],
                static_cast<float>(model_.rest_positions_m(row, col)));
    }
  }
  const std::span<const std::uint32_t> triangles = image.u32s(SectionId::triangles);
  ASSERT_EQ(triangles.size(), 6U);
  for (Eigen::Index i = 0; i < 6; ++i) {
    EXPECT_EQ(triangles[static_cast<std::size_t>(i)],
              static_cast<std::uint32_t>(model_.triangles(i / 3, i % 3)));
  }
  EXPECT_EQ(std::vector<std::uint32_t>(image.u32s(SectionId::fixed_nodes).begin(),
                                       image.u32s(SectionId::fixed_nodes).end()),
            model_.fixed_nodes);
  EXPECT_EQ(std::vector<std::uint32_t>(image.u32s(SectionId::surface_nodes).begin(),
                                       image.u32s(SectionId::surface_nodes).end()),
            model_.surface_nodes);
  // Mode shapes: row = node*3 + axis, row-major, so one node's 3 rows are contiguous.
  const std::span<const float> modes = image.floats(SectionId::mode_shapes);
  ASSERT_EQ(image.rows(SectionId::mode_shapes), 12U);
  ASSERT_EQ(image.cols(SectionId::mode_shapes), 2U);
  for (Eigen::Index row = 0; row < 12; ++row) {
    for (Eigen::Index col = 0; col < 2; ++col) {
      EXPECT_EQ(modes[static_cast<std::size_t>(row * 2 + col)],
                static_cast<float>(model_.mode_shapes(row, col)));
    }
  }
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(image.floats(SectionId::omega_squared)[i],
              static_cast<float>(model_.omega_squared[i]));
    EXPECT_EQ(image.floats(SectionId::modal_damping)[i],
              static_cast<float>(model_.modal_damping[i]));
  }
  const std::span<const float> compliance = image.floats(SectionId::residual_compliance);
  ASSERT_EQ(compliance.size(), 36U);
  for (Eigen::Index row = 0; row < 6; ++row) {
    for (Eigen::Index col = 0; col < 6; ++col) {
      EXPECT_EQ(compliance[static_cast<std::size_t>(row * 6 + col)],
                static_cast<float>(model_.residual_compliance(row, col)));
    }
  }

  const ImageMetadataV1& metadata = image.metadata();
  EXPECT_EQ(metadata.source_mesh_hash, 0x0123456789ABCDEFULL);
  EXPECT_EQ(metadata.young_modulus_pa, 1.2e5);
  EXPECT_EQ(metadata.poisson_ratio, 0.45);
  EXPECT_EQ(metadata.thickness_m, 4e-4);
  EXPECT_EQ(metadata.density_kg_per_m3, 1050.0);
  EXPECT_EQ(metadata.element_type, static_cast<std::uint32_t>(FiniteElementType::shell_dkt));
  EXPECT_EQ(metadata.mode_count, 2U);
  EXPECT_EQ(metadata.node_count, 4U);
  EXPECT_EQ(metadata.surface_node_count, 2U);
  EXPECT_EQ(metadata.time_step_s, 1e-3);
  EXPECT_EQ(metadata.damping_ratio, 0.05);
  EXPECT_EQ(metadata.error_estimate, 0.0123);
  EXPECT_TRUE(std::isnan(metadata.error_budget));  // make_metadata(): no budget
  EXPECT_EQ(metadata.static_correction, 1U);
  EXPECT_EQ(metadata.created_unix_s, 1700000000U);
  EXPECT_STREQ(metadata.tool_version, "modelc test 1.2.3");
  EXPECT_EQ(std::memcmp(&metadata, &model_.metadata, sizeof metadata), 0);

  // Absent sections and wrong-type requests give empty views, not garbage.
  EXPECT_FALSE(image.has(SectionId::tensor_force));
  EXPECT_EQ(image.rows(SectionId::tensor_force), 0U);
  EXPECT_TRUE(image.floats(SectionId::tensor_force).empty());
  EXPECT_TRUE(image.u32s(SectionId::mode_shapes).empty());
  EXPECT_TRUE(image.floats(SectionId::triangles).empty());
  EXPECT_TRUE(image.i32s(SectionId::triangles).empty());
  EXPECT_EQ(image.u8s(SectionId::metadata).size(), sizeof(ImageMetadataV1));

  // The checksum the loader reports is the header's, and the views live in the arena block.
  EXPECT_EQ(image.checksum(), get<std::uint64_t>(model_.bytes(), kImageChecksumOffset));
  EXPECT_EQ(image.bytes().size(), model_.bytes().size());
  for (const SectionView& view : image.sections()) {
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(view.data) % 64, 0U) << section_name(view.id);
    EXPECT_GE(view.data, image.bytes().data());
    EXPECT_LE(view.data, image.bytes().data() + image.bytes().size());
  }
  EXPECT_GE(arena_->used_bytes(), image.bytes().size());
}

TEST_F(ModelImageLoad, SuccessPathAllocatesNothing) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  test::write_file(file(), model_.bytes());
  auto arena = core::Arena::create(kArenaBytes);
  ASSERT_TRUE(arena);
  const ImageLimits limits{};
  const std::filesystem::path path = file();

  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  auto loaded = load_model_image(path, arena.value(), limits, ModelKind::modal_shell);
  core::alloc::end_counting_this_thread();
  const std::uint64_t allocations = core::alloc::counted_allocations() - before;

  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_EQ(allocations, 0U);
  EXPECT_EQ(loaded.value().metadata().mode_count, 2U);
}

TEST_F(ModelImageLoad, CountingDetectsAnAllocatingErrorPath) {
  // Guards the test above: the same measurement does see the error path's message string.
  test::write_file(file(), model_.bytes());
  auto arena = core::Arena::create(kArenaBytes);
  ASSERT_TRUE(arena);
  const std::filesystem::path path = file();
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  auto loaded = load_model_image(path, arena.value(), ImageLimits{}, ModelKind::tet_tensor);
  core::alloc::end_counting_this_thread();
  EXPECT_FALSE(loaded);
  EXPECT_GT(core::alloc::counted_allocations() - before, 0U);
}

TEST_F(ModelImageLoad, MinimalTetTensorImageLoads) {
  const test::SmallTetTensor tet;
  const auto flat = [](const Eigen::MatrixXd& m) {
    std::vector<float> values;
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      for (Eigen::Index c = 0; c < m.cols(); ++c) values.push_back(static_cast<float>(m(r, c)));
    }
    return values;
  };
  std::vector<std::uint32_t> triangles;
  for (Eigen::Index r = 0; r < tet.triangles.rows(); ++r) {
    for (Eigen::Index c = 0; c < 3; ++c) triangles.push_back(static_cast<std::uint32_t>(tet.triangles(r, c)));
  }
  std::vector<float> force(tet.force_tensor.begin(), tet.force_tensor.end());
  std::vector<RawSection> sections{
      raw_metadata(tet.metadata),
      raw_section(SectionId::rest_positions, ElementType::f32, 4, 3, flat(tet.rest_positions_m)),
      raw_section(SectionId::triangles, ElementType::u32, 4, 3, triangles),
      raw_section(SectionId::fixed_nodes, ElementType::u32, 1, 1, tet.fixed_nodes),
      raw_section(SectionId::surface_nodes, ElementType::u32, 1, 1, tet.contact_nodes),
      raw_section(SectionId::tensor_nodes, ElementType::u32, 3, 1, tet.stored_nodes),
      raw_section(SectionId::tensor_displacement, ElementType::f32, 3, 9,
                  flat(tet.displacement_tensors)),
      raw_section(SectionId::tensor_force, ElementType::f32, 1, 9, force)};
  auto loaded = load_bytes(build_raw_image(ModelKind::tet_tensor, sections), ModelKind::tet_tensor);
  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_EQ(loaded.value().model_kind(), ModelKind::tet_tensor);
  EXPECT_EQ(loaded.value().floats(SectionId::tensor_displacement)[3], 0.04F);

  // Each tet_tensor consistency rule, broken one at a time in an otherwise valid image.
  const auto refused = [&](std::vector<RawSection> broken, const std::string& expected) {
    auto result = load_bytes(build_raw_image(ModelKind::tet_tensor, broken), ModelKind::tet_tensor);
    ASSERT_FALSE(result);
    EXPECT_NE(result.error().message.find(expected), std::string::npos) << result.error().message;
  };
  std::vector<RawSection> without_force(sections.begin(), sections.end() - 1);
  refused(without_force, "a tet_tensor image needs section 'tensor_force'");
  std::vector<RawSection> not_stored = sections;
  not_stored[5] = raw_section(SectionId::tensor_nodes, ElementType::u32, 3, 1,
                              std::vector<std::uint32_t>{0, 1, 2});
  refused(not_stored, "surface node 3 (entry 0) is not in section 'tensor_nodes'");
  std::vector<RawSection> asymmetric = sections;
  std::vector<float> skew = force;
  skew[1] = 30.0F;
  asymmetric[7] = raw_section(SectionId::tensor_force, ElementType::f32, 1, 9, skew);
  refused(asymmetric, "'tensor_force' contact 0 is not symmetric");
  std::vector<RawSection> short_tensors = sections;
  short_tensors[6] = raw_section(SectionId::tensor_displacement, ElementType::f32, 2, 9,
                                 std::vector<float>(18, 0.0F));
  refused(short_tensors, "'tensor_displacement' has 2 rows, expected 3");
  std::vector<RawSection> wrong_columns = sections;
  wrong_columns[6] = raw_section(SectionId::tensor_displacement, ElementType::f32, 9, 3,
                                 flat(tet.displacement_tensors));
  refused(wrong_columns, "the format requires 9");
}

TEST_F(ModelImageLoad, EmptySectionsAreAllowed) {
  std::vector<RawSection> sections = raw_small_model(model_);
  raw_find(sections, SectionId::fixed_nodes) =
      raw_section(SectionId::fixed_nodes, ElementType::u32, 0, 1, std::vector<std::uint32_t>{});
  auto loaded = load_bytes(build_raw_image(ModelKind::modal_shell, sections));
  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_TRUE(loaded.value().has(SectionId::fixed_nodes));
  EXPECT_TRUE(loaded.value().u32s(SectionId::fixed_nodes).empty());
}

// ---------------------------------------------------------------------------------------------
// File-level damage

TEST_F(ModelImageLoad, MissingFileIsRefused) {
  EXPECT_TRUE(failed_with(load(), label(), "cannot open"));
}

TEST_F(ModelImageLoad, DirectoryIsRefused) {
  auto arena = core::Arena::create(kArenaBytes);
  ASSERT_TRUE(arena);
  EXPECT_TRUE(failed_with(
      load_model_image(directory_.path(), arena.value(), ImageLimits{}, ModelKind::modal_shell),
      directory_.path().string(), "is not a regular file"));
}

TEST_F(ModelImageLoad, EveryTruncationIsRefused) {
  const std::vector<std::byte> bytes = model_.bytes();
  ASSERT_GT(bytes.size(), 1000U);
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    test::write_file(file(), bytes, length);
    const auto loaded = load();
    if (length < kImageHeaderBytes) {
      EXPECT_TRUE(failed_with(
          loaded, label(),
          "file is " + std::to_string(length) + " bytes, shorter than the 128-byte header"))
          << "length " << length;
    } else {
      EXPECT_TRUE(failed_with(loaded, label(),
                              "header file_bytes is " + std::to_string(bytes.size()) +
                                  " but the file is " + std::to_string(length) + " bytes"))
          << "length " << length;
    }
    // Refused from the header alone: no arena space reserved for a truncated file.
    EXPECT_EQ(arena_->used_bytes(), 0U) << "length " << length;
  }
}

TEST_F(ModelImageLoad, AppendedBytesAreRefused) {
  std::vector<std::byte> bytes = model_.bytes();
  const std::size_t size = bytes.size();
  bytes.push_back(std::byte{0});
  EXPECT_TRUE(failed_with(load_bytes(bytes), label(),
                          "header file_bytes is " + std::to_string(size) + " but the file is " +
                              std::to_string(size + 1) + " bytes"));
}

TEST_F(ModelImageLoad, EveryFlippedByteIsRefused) {
  const std::vector<std::byte> original = model_.bytes();
  for (std::size_t position = 0; position < original.size(); ++position) {
    std::vector<std::byte> bytes = original;
    bytes[position] ^= std::byte{0xFF};
    const auto loaded = load_bytes(bytes);
    if (position >= kImageChecksumOffset) {
      // Everything from the checksum field on is only checked after the checksum.
      EXPECT_TRUE(failed_with(loaded, label(), "checksum mismatch")) << "byte " << position;
    } else {
      // Header fields before the checksum are checked first; each flip breaks one of them.
      EXPECT_FALSE(loaded) << "byte " << position;
      if (!loaded) {
        EXPECT_EQ(loaded.error().message.rfind(label() + ": ", 0), 0U);
      }
    }
  }
}

TEST_F(ModelImageLoad, ChecksumMismatchNamesBothValues) {
  std::vector<std::byte> bytes = model_.bytes();
  const auto stored = get<std::uint64_t>(bytes, kImageChecksumOffset);
  put<std::uint64_t>(bytes, kImageChecksumOffset, stored + 1);
  EXPECT_TRUE(failed_with(load_bytes(bytes), label(), "checksum mismatch: header says 0x"));
}

// ---------------------------------------------------------------------------------------------
// Header fields

TEST_F(ModelImageLoad, WrongMagicIsRefused) {
  EXPECT_TRUE(
      failed_with(load_patched([](auto& bytes) { std::memcpy(bytes.data(), "HTRMODEM", 8); }),
                  label(), "not \"HTRMODEL\": not a model image"));
}

TEST_F(ModelImageLoad, OlderAndNewerVersionsAreRefused) {
  for (const std::uint32_t version : {0U, 2U, 0xFFFFFFFFU}) {
    const auto loaded = load_patched([version](auto& bytes) {
      put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, format_version), version);
    });
    ASSERT_FALSE(loaded);
    EXPECT_EQ(loaded.error().message, label() + ": image format version " +
                                          std::to_string(version) +
                                          ", this build reads 1: rebuild it with modelc");
  }
}

TEST_F(ModelImageLoad, WrongHeaderSizeIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) {
                            put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, header_bytes), 256);
                          }),
                          label(), "header_bytes is 256, format version 1 has 128"));
}

TEST_F(ModelImageLoad, BigEndianByteOrderMarkIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) {
                            put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, byte_order_mark),
                                               0x04030201U);
                          }),
                          label(),
                          "byte_order_mark is 0x4030201, expected 0x1020304: the image "
                          "was written big-endian"));
}

TEST_F(ModelImageLoad, GarbageByteOrderMarkIsRefused) {
  EXPECT_TRUE(failed_with(
      load_patched([](auto& bytes) {
        put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, byte_order_mark), 0xDEADBEEFU);
      }),
      label(), "byte_order_mark is 0xdeadbeef, expected 0x1020304: not a valid"));
}

TEST_F(ModelImageLoad, OtherModelKindIsRefusedBeforeReservingArenaSpace) {
  test::write_file(file(), model_.bytes());
  EXPECT_TRUE(failed_with(load(ModelKind::tet_tensor), label(),
                          "model_kind is modal_shell, the scene expects tet_tensor"));
  EXPECT_EQ(arena_->used_bytes(), 0U);
}

TEST_F(ModelImageLoad, UnknownModelKindIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) {
                            put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, model_kind), 7);
                          }),
                          label(), "model_kind 7 is unknown"));
}

TEST_F(ModelImageLoad, FileBytesFieldMismatchIsRefused) {
  const std::size_t size = model_.bytes().size();
  EXPECT_TRUE(failed_with(load_patched([size](auto& bytes) {
                            put<std::uint64_t>(bytes, offsetof(ImageHeaderV1, file_bytes),
                                               size - 64);
                          }),
                          label(),
                          "header file_bytes is " + std::to_string(size - 64) +
                              " but the file is " + std::to_string(size) + " bytes"));
}

TEST_F(ModelImageLoad, HugeSectionCountIsRefused) {
  for (const std::uint32_t count : {33U, 0xFFFFFFFFU}) {
    EXPECT_TRUE(failed_with(
        load_patched([count](auto& bytes) {
          put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_count), count);
        }),
        label(), "section_count " + std::to_string(count) + " exceeds the format maximum of 32"));
  }
}

TEST_F(ModelImageLoad, ZeroSectionCountIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) {
                            put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_count), 0);
                          }),
                          label(), "section_count is 0"));
}

TEST_F(ModelImageLoad, MovedSectionTableIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) {
                            put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_table_offset),
                                               192);
                          }),
                          label(), "section_table_offset is 192"));
}

TEST_F(ModelImageLoad, SectionTablePastTheEndIsRefused) {
  // A metadata-only image is 448 bytes: 32 table entries would end at byte 1152.
  std::vector<std::byte> bytes =
      build_raw_image(ModelKind::tet_tensor, {raw_metadata(model_.metadata)});
  ASSERT_EQ(bytes.size(), 448U);
  put<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_count), 32);
  recompute_checksum(bytes);
  EXPECT_TRUE(failed_with(load_bytes(bytes, ModelKind::tet_tensor), label(),
                          "section table (32 entries, ending at byte 1152) runs past the end of "
                          "the file (448 bytes)"));
}

TEST_F(ModelImageLoad, NonZeroReservedHeaderByteIsRefused) {
  EXPECT_TRUE(failed_with(load_patched([](auto& bytes) { bytes[100] = std::byte{1}; }), label(),
                          "header reserved byte 100 is not zero"));
}

TEST_F(ModelImageLoad, FileAboveTheSizeLimitIsRefusedBeforeAllocation) {
  test::write_file(file(), model_.bytes());
  ImageLimits limits;
  limits.max_file_bytes = 1024;
  EXPECT_TRUE(failed_with(load(ModelKind::modal_shell, limits), label(),
                          "exceeds the limit of 1024 (ImageLimits::max_file_bytes)"));
  EXPECT_EQ(arena_->used_bytes(), 0U);
}

TEST_F(ModelImageLoad, ArenaTooSmallIsRefused) {
  test::write_file(file(), model_.bytes());
  EXPECT_TRUE(failed_with(load(ModelKind::modal_shell, ImageLimits{}, 512), label(),
                          "cannot place the " + std::to_string(model_.bytes().size()) +
                              "-byte image in the arena: arena exhausted"));
}

// ---------------------------------------------------------------------------------------------
// Section table entries

TEST_F(ModelImageLoad, UnknownSectionIdIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    put<std::uint32_t>(bytes, entry_position(bytes, SectionId::modal_damping), 99);
  });
  EXPECT_TRUE(failed_with(loaded, label(), "has unknown id 99"));
}

TEST_F(ModelImageLoad, DuplicateSectionIdIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    put<std::uint32_t>(bytes, entry_position(bytes, SectionId::modal_damping),
                       static_cast<std::uint32_t>(SectionId::omega_squared));
  });
  EXPECT_TRUE(failed_with(loaded, label(), "section 'omega_squared' appears twice"));
}

TEST_F(ModelImageLoad, SectionOfAnotherModelKindIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    put<std::uint32_t>(bytes, entry_position(bytes, SectionId::fixed_nodes),
                       static_cast<std::uint32_t>(SectionId::tensor_nodes));
  });
  EXPECT_TRUE(failed_with(loaded, label(),
                          "section 'tensor_nodes' does not belong in a modal_shell image"));
}

TEST_F(ModelImageLoad, WrongElementTypeForTheIdIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    put<std::uint32_t>(bytes, entry_position(bytes, SectionId::mode_shapes) + 4,
                       static_cast<std::uint32_t>(ElementType::u32));
  });
  EXPECT_TRUE(failed_with(loaded, label(),
                          "section 'mode_shapes' element_type is u32, the format requires f32"));
}

TEST_F(ModelImageLoad, UnknownElementTypeIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    put<std::uint32_t>(bytes, entry_position(bytes, SectionId::mode_shapes) + 4, 9);
  });
  EXPECT_TRUE(failed_with(loaded, label(), "section 'mode_shapes' element_type 9 is unknown"));
}

TEST_F(ModelImageLoad, MisalignedOffsetIsRefused) {
  std::uint64_t misaligned = 0;
  const auto loaded = load_patched([&misaligned](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::mode_shapes);
    entry.offset += 4;
    misaligned = entry.offset;
    put_entry(bytes, SectionId::mode_shapes, entry);
  });
  EXPECT_TRUE(failed_with(
      loaded, label(),
      "section 'mode_shapes' offset " + std::to_string(misaligned) + " is not 64-byte aligned"));
}

TEST_F(ModelImageLoad, OffsetInsideTheTableIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::omega_squared);
    entry.offset = 128;
    put_entry(bytes, SectionId::omega_squared, entry);
  });
  EXPECT_TRUE(failed_with(loaded, label(),
                          "section 'omega_squared' offset 128 lies inside the header or section "
                          "table"));
}

TEST_F(ModelImageLoad, OffsetPastTheEndIsRefused) {
  const std::size_t size = model_.bytes().size();
  const std::uint64_t beyond = (size + 64) / 64 * 64;
  const auto loaded = load_patched([beyond](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::omega_squared);
    entry.offset = beyond;
    put_entry(bytes, SectionId::omega_squared, entry);
  });
  EXPECT_TRUE(failed_with(
      loaded, label(),
      "section 'omega_squared' offset " + std::to_string(beyond) + " is past the end of the file"));
}

TEST_F(ModelImageLoad, HugeElementCountNeitherOverflowsNorAllocates) {
  // 2^31 × 2^31 = 2^62 floats: the byte size (2^64) overflows 64 bits. And the maximum count.
  struct Shape {
    std::uint64_t count;
    std::uint32_t rows;
    std::uint32_t cols;
  };
  for (const Shape shape : {Shape{1ULL << 62U, 1U << 31U, 1U << 31U},
                            Shape{std::numeric_limits<std::uint64_t>::max(), 0xFFFFFFFFU, 1U},
                            Shape{(1ULL << 62U) + 1, 3U, 5U}}) {
    const auto loaded = load_patched([shape](auto& bytes) {
      SectionEntryV1 entry = entry_of(bytes, SectionId::mode_shapes);
      entry.element_count = shape.count;
      entry.rows = shape.rows;
      entry.cols = shape.cols;
      put_entry(bytes, SectionId::mode_shapes, entry);
    });
    EXPECT_TRUE(failed_with(loaded, label(),
                            "section 'mode_shapes' element_count " + std::to_string(shape.count) +
                                " (4 bytes each) does not fit between offset"));
    // Only the file itself was placed in the arena.
    EXPECT_EQ(arena_->used_bytes(), model_.bytes().size());
  }
}

TEST_F(ModelImageLoad, RowsTimesColsMismatchIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::mode_shapes);
    entry.rows = 11;
    put_entry(bytes, SectionId::mode_shapes, entry);
  });
  EXPECT_TRUE(failed_with(
      loaded, label(), "section 'mode_shapes' rows × cols = 11 × 2 = 22 but element_count is 24"));
}

TEST_F(ModelImageLoad, WrongColumnCountForTheIdIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::triangles);
    entry.rows = 6;
    entry.cols = 1;
    put_entry(bytes, SectionId::triangles, entry);
  });
  EXPECT_TRUE(
      failed_with(loaded, label(), "section 'triangles' has 1 columns, the format requires 3"));
}

TEST_F(ModelImageLoad, OverlappingSectionsAreRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 damping = entry_of(bytes, SectionId::modal_damping);
    damping.offset = entry_of(bytes, SectionId::omega_squared).offset;
    put_entry(bytes, SectionId::modal_damping, damping);
  });
  EXPECT_TRUE(failed_with(loaded, label(), "overlap"));
  ASSERT_FALSE(loaded);
  EXPECT_NE(loaded.error().message.find("omega_squared"), std::string::npos);
  EXPECT_NE(loaded.error().message.find("modal_damping"), std::string::npos);
}

TEST_F(ModelImageLoad, PartlyOverlappingSectionsAreRefused) {
  // mode_shapes is 96 bytes: a section starting 64 bytes in shares its last 32.
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 omega = entry_of(bytes, SectionId::omega_squared);
    omega.offset = entry_of(bytes, SectionId::mode_shapes).offset + 64;
    put_entry(bytes, SectionId::omega_squared, omega);
  });
  EXPECT_TRUE(failed_with(loaded, label(), "overlap"));
}

TEST_F(ModelImageLoad, NonZeroPaddingIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    // omega_squared is 8 bytes followed by padding up to the next 64-byte boundary.
    const SectionEntryV1 omega = entry_of(bytes, SectionId::omega_squared);
    bytes[omega.offset + 8] = std::byte{7};
  });
  EXPECT_TRUE(failed_with(loaded, label(), "padding byte"));
}

// ---------------------------------------------------------------------------------------------
// Float contents

TEST_F(ModelImageLoad, NanInAFloatSectionIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    const SectionEntryV1 modes = entry_of(bytes, SectionId::mode_shapes);
    put<float>(bytes, modes.offset + 5 * sizeof(float), std::numeric_limits<float>::quiet_NaN());
  });
  EXPECT_TRUE(failed_with(loaded, label(),
                          "section 'mode_shapes' element 5 (row 2, col 1) is nan: float sections "
                          "must be finite"));
}

TEST_F(ModelImageLoad, InfinityInAFloatSectionIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    const SectionEntryV1 positions = entry_of(bytes, SectionId::rest_positions);
    put<float>(bytes, positions.offset + 11 * sizeof(float),
               -std::numeric_limits<float>::infinity());
  });
  EXPECT_TRUE(
      failed_with(loaded, label(), "section 'rest_positions' element 11 (row 3, col 2) is -inf"));
}

// ---------------------------------------------------------------------------------------------
// Metadata

TEST_F(ModelImageLoad, MissingMetadataIsRefused) {
  std::vector<RawSection> sections = raw_small_model(model_);
  raw_erase(sections, SectionId::metadata);
  EXPECT_TRUE(failed_with(load_bytes(build_raw_image(ModelKind::modal_shell, sections)), label(),
                          "section 'metadata' is missing"));
}

TEST_F(ModelImageLoad, WrongMetadataSizeIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    SectionEntryV1 entry = entry_of(bytes, SectionId::metadata);
    entry.rows = 255;
    entry.element_count = 255;
    put_entry(bytes, SectionId::metadata, entry);
    bytes[entry.offset + 255] = std::byte{0};  // now padding: keep it zero
  });
  EXPECT_TRUE(
      failed_with(loaded, label(), "section 'metadata' is 255 bytes, format version 1 has 256"));
}

// Patches one metadata field (at `offset` inside the record) in the written image.
template <class T>
auto patch_metadata(std::size_t field_offset, T value) {
  return [field_offset, value](std::vector<std::byte>& bytes) {
    put<T>(bytes, entry_of(bytes, SectionId::metadata).offset + field_offset, value);
  };
}

TEST_F(ModelImageLoad, InvalidMetadataFieldsAreRefusedOneByOne) {
  constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<std::uint32_t>(offsetof(ImageMetadataV1, element_type), 4)),
      label(), "metadata element_type 4 is unknown"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<std::uint32_t>(offsetof(ImageMetadataV1, static_correction), 2)),
      label(), "metadata static_correction is 2, expected 0 or 1"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<std::uint32_t>(offsetof(ImageMetadataV1, padding0), 1)), label(),
      "metadata padding0 is not zero"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<std::uint8_t>(offsetof(ImageMetadataV1, reserved) + 7, 1)),
      label(), "metadata reserved byte 7 is not zero"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, young_modulus_pa), -1.0)),
      label(), "metadata young_modulus_pa is -1, expected a finite value >= 0"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, time_step_s), kNan)), label(),
      "metadata time_step_s is nan"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, poisson_ratio), kInf)), label(),
      "metadata poisson_ratio is inf, expected a finite value"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, poisson_ratio), 0.5)), label(),
      "metadata poisson_ratio is 0.5, expected -1 < nu < 0.5"));
  EXPECT_TRUE(
      failed_with(load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, thickness_m), 0.0)),
                  label(), "a shell needs all three > 0"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, error_estimate), kInf)),
      label(), "metadata error_estimate is inf, expected NaN (none) or a value >= 0"));
  EXPECT_TRUE(failed_with(
      load_patched(patch_metadata<double>(offsetof(ImageMetadataV1, error_budget), -0.1)), label(),
      "metadata error_budget is -0.1"));
}

TEST_F(ModelImageLoad, UnterminatedToolVersionIsRefused) {
  const auto loaded = load_patched([](auto& bytes) {
    const std::size_t start =
        entry_of(bytes, SectionId::metadata).offset + offsetof(ImageMetadataV1, tool_version);
    for (std::size_t i = 0; i < 32; ++i) bytes[start + i] = std::byte{'x'};
  });
  EXPECT_TRUE(
      failed_with(loaded, label(), "metadata tool_version is not NUL-terminated within 32 bytes"));
}

// ---------------------------------------------------------------------------------------------
// Limits

TEST_F(ModelImageLoad, CountsAboveTheLimitsAreRefused) {
  test::write_file(file(), model_.bytes());
  struct Case {
    ImageLimits limits;
    std::string message;
  };
  std::vector<Case> cases(4);
  cases[0].limits.max_node_count = 3;
  cases[0].message = "metadata node_count 4 exceeds the limit of 3 (ImageLimits::max_node_count)";
  cases[1].limits.max_mode_count = 1;
  cases[1].message = "metadata mode_count 2 exceeds the limit of 1 (ImageLimits::max_mode_count)";
  cases[2].limits.max_surface_node_count = 1;
  cases[2].message =
      "metadata surface_node_count 2 exceeds the limit of 1 (ImageLimits::max_surface_node_count)";
  cases[3].limits.max_triangle_count = 1;
  cases[3].message =
      "section 'triangles' rows 2 exceeds the limit of 1 (ImageLimits::max_triangle_count)";
  for (const Case& limit_case : cases) {
    EXPECT_TRUE(
        failed_with(load(ModelKind::modal_shell, limit_case.limits), label(), limit_case.message));
  }
  // At the limits exactly, the image loads.
  ImageLimits exact;
  exact.max_node_count = 4;
  exact.max_mode_count = 2;
  exact.max_surface_node_count = 2;
  exact.max_triangle_count = 2;
  exact.max_file_bytes = model_.bytes().size();
  const auto loaded = load(ModelKind::modal_shell, exact);
  EXPECT_TRUE(loaded) << loaded.error().message;
}

// ---------------------------------------------------------------------------------------------
// Modal shell consistency (raw images: the writer refuses to produce these)

class ModalShellConsistency : public ModelImageLoad {
 protected:
  core::Expected<ModelImage> load_raw(const std::vector<RawSection>& sections) {
    return load_bytes(build_raw_image(ModelKind::modal_shell, sections));
  }
  std::vector<RawSection> sections_ = raw_small_model(model_);
};

TEST_F(ModalShellConsistency, RawSmallModelLoads) {
  const auto loaded = load_raw(sections_);
  EXPECT_TRUE(loaded) << loaded.error().message;
}

TEST_F(ModalShellConsistency, MissingRequiredSectionIsRefused) {
  for (const SectionId id :
       {SectionId::rest_positions, SectionId::triangles, SectionId::mode_shapes,
        SectionId::omega_squared, SectionId::modal_damping}) {
    std::vector<RawSection> sections = sections_;
    raw_erase(sections, id);
    EXPECT_TRUE(failed_with(load_raw(sections), label(),
                            std::string("a modal_shell image needs section '") + section_name(id) +
                                "', which is missing"));
  }
}

TEST_F(ModalShellConsistency, RowCountsMustMatchTheMetadata) {
  std::vector<RawSection> sections = sections_;
  raw_find(sections, SectionId::omega_squared) = raw_section(
      SectionId::omega_squared, ElementType::f32, 3, 1, std::vector<float>{1.0F, 2.0F, 3.0F});
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'omega_squared' has 3 rows, expected 2 (metadata mode_count)"));

  sections = sections_;
  ImageMetadataV1 metadata = model_.metadata;
  metadata.node_count = 5;
  raw_find(sections, SectionId::metadata) = raw_metadata(metadata);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'rest_positions' has 4 rows, expected 5 (metadata node_count)"));

  sections = sections_;
  metadata = model_.metadata;
  metadata.mode_count = 1;
  raw_find(sections, SectionId::metadata) = raw_metadata(metadata);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'mode_shapes' has 2 columns, expected 1 (metadata mode_count)"));
}

TEST_F(ModalShellConsistency, ModeShapeRowsAreThreePerNode) {
  std::vector<RawSection> sections = sections_;
  raw_find(sections, SectionId::mode_shapes) =
      raw_section(SectionId::mode_shapes, ElementType::f32, 8, 2, std::vector<float>(16, 0.5F));
  EXPECT_TRUE(
      failed_with(load_raw(sections), label(),
                  "section 'mode_shapes' has 8 rows, expected 12 (3 × metadata node_count)"));
}

TEST_F(ModalShellConsistency, TriangleIndicesMustBeDistinctExistingNodes) {
  std::vector<RawSection> sections = sections_;
  raw_set<std::uint32_t>(sections, SectionId::triangles, 4, 4);  // row 1 = (0, 4, 3)
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'triangles' row 1 (0, 4, 3) needs three distinct nodes below "
                          "node_count 4"));
  sections = sections_;
  raw_set<std::uint32_t>(sections, SectionId::triangles, 2, 1);  // row 0 = (0, 1, 1)
  EXPECT_TRUE(failed_with(load_raw(sections), label(), "section 'triangles' row 0 (0, 1, 1)"));
}

TEST_F(ModalShellConsistency, NodeListsMustBeStrictlyIncreasingExistingNodes) {
  std::vector<RawSection> sections = sections_;
  raw_set<std::uint32_t>(sections, SectionId::surface_nodes, 1, 1);  // (1, 1)
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'surface_nodes' entry 1 (node 1) is not greater than the "
                          "previous entry"));
  sections = sections_;
  raw_set<std::uint32_t>(sections, SectionId::fixed_nodes, 0, 9);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'fixed_nodes' entry 0 is node 9, but node_count is 4"));
}

TEST_F(ModalShellConsistency, EigenvaluesMustBeNonNegativeAndAscending) {
  std::vector<RawSection> sections = sections_;
  raw_set<float>(sections, SectionId::omega_squared, 0, 3000.0F);  // 3000 > 2500.25
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "section 'omega_squared' element 1 is 2500.25: values must be >= 0 and "
                          "ascending"));
  sections = sections_;
  raw_set<float>(sections, SectionId::omega_squared, 0, -1.0F);
  EXPECT_TRUE(failed_with(load_raw(sections), label(), "section 'omega_squared' element 0 is -1"));
}

TEST_F(ModalShellConsistency, NegativeDampingIsRefused) {
  raw_set<float>(sections_, SectionId::modal_damping, 1, -0.5F);
  EXPECT_TRUE(failed_with(load_raw(sections_), label(),
                          "section 'modal_damping' element 1 is -0.5: damping must be >= 0"));
}

TEST_F(ModalShellConsistency, SurfaceNodesMustMatchTheirCount) {
  std::vector<RawSection> sections = sections_;
  raw_erase(sections, SectionId::surface_nodes);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "metadata surface_node_count is 2 but section 'surface_nodes' is "
                          "missing"));
}

TEST_F(ModalShellConsistency, StaticCorrectionFlagMustMatchTheCompliance) {
  std::vector<RawSection> sections = sections_;
  raw_erase(sections, SectionId::residual_compliance);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "metadata static_correction is 1 but section 'residual_compliance' is "
                          "missing"));
  sections = sections_;
  ImageMetadataV1 metadata = model_.metadata;
  metadata.static_correction = 0;
  raw_find(sections, SectionId::metadata) = raw_metadata(metadata);
  EXPECT_TRUE(failed_with(load_raw(sections), label(),
                          "metadata static_correction is 0 but section 'residual_compliance' is "
                          "present"));
}

TEST_F(ModalShellConsistency, ComplianceMustBeThreeSByThreeS) {
  raw_find(sections_, SectionId::residual_compliance) = raw_section(
      SectionId::residual_compliance, ElementType::f32, 3, 3, std::vector<float>(9, 1e-3F));
  EXPECT_TRUE(failed_with(load_raw(sections_), label(),
                          "section 'residual_compliance' is 3 × 3, expected 3s × 3s = 6 × 6"));
}

TEST_F(ModalShellConsistency, AsymmetricComplianceIsRefused) {
  raw_set<float>(sections_, SectionId::residual_compliance, 1 * 6 + 4, 5e-4F);
  EXPECT_TRUE(failed_with(load_raw(sections_), label(),
                          "section 'residual_compliance' is not symmetric: (1, 4) = 5e-04 but "
                          "(4, 1)"));
}

TEST_F(ModalShellConsistency, ComplianceSymmetricToRoundingLoads) {
  // One float ulp of asymmetry, as float rounding of a computed double matrix can leave.
  const float value = test::get<float>(raw_find(sections_, SectionId::residual_compliance).payload,
                                       (1 * 6 + 4) * sizeof(float));
  raw_set<float>(sections_, SectionId::residual_compliance, 1 * 6 + 4, std::nextafter(value, 1.0F));
  const auto loaded = load_raw(sections_);
  EXPECT_TRUE(loaded) << loaded.error().message;
}

TEST_F(ModalShellConsistency, ZeroNodesOrModesAreRefused) {
  ImageMetadataV1 metadata = model_.metadata;
  metadata.mode_count = 0;
  raw_find(sections_, SectionId::metadata) = raw_metadata(metadata);
  EXPECT_TRUE(failed_with(load_raw(sections_), label(),
                          "metadata node_count 4 and mode_count 0: a modal_shell image needs both "
                          "> 0"));
}

// ---------------------------------------------------------------------------------------------
// parse_model_image directly

TEST(ParseModelImage, RefusesMisalignedMemory) {
  const std::vector<std::byte> bytes = test::SmallModalShell().bytes();
  auto arena = core::Arena::create(8192);
  ASSERT_TRUE(arena);
  auto block = arena.value().allocate_bytes(bytes.size() + 8, 64, "test");
  ASSERT_TRUE(block);
  auto* shifted = static_cast<std::byte*>(block.value()) + 8;
  std::memcpy(shifted, bytes.data(), bytes.size());
  EXPECT_TRUE(failed_with(parse_model_image({shifted, bytes.size()}, "memory image",
                                            ModelKind::modal_shell, ImageLimits{}),
                          "memory image", "image bytes are not 64-byte aligned in memory"));
  std::memcpy(shifted - 8, bytes.data(), bytes.size());
  const auto parsed = parse_model_image({shifted - 8, bytes.size()}, "memory image",
                                        ModelKind::modal_shell, ImageLimits{});
  EXPECT_TRUE(parsed) << parsed.error().message;
}

TEST(ParseModelImage, DefaultImageIsEmpty) {
  const ModelImage image;
  EXPECT_TRUE(image.empty());
  EXPECT_TRUE(image.sections().empty());
  EXPECT_FALSE(image.has(SectionId::metadata));
  EXPECT_TRUE(image.floats(SectionId::mode_shapes).empty());
}

TEST(ImageFormat, ChecksumSkipsItsOwnFieldAndCoversEverythingElse) {
  std::vector<std::byte> bytes = test::SmallModalShell().bytes();
  const std::uint64_t stored = get<std::uint64_t>(bytes, kImageChecksumOffset);
  EXPECT_EQ(compute_image_checksum(bytes), stored);
  put<std::uint64_t>(bytes, kImageChecksumOffset, 0x1234);
  EXPECT_EQ(compute_image_checksum(bytes), stored);  // the field itself is not hashed
  bytes.back() ^= std::byte{1};
  EXPECT_NE(compute_image_checksum(bytes), stored);
}

TEST(ImageFormat, SectionDescriptorsMatchTheSpec) {
  struct SpecEntry {
    std::uint32_t id;
    const char* name;
    ElementType type;
  };
  const SpecEntry expected[] = {
      {1, "metadata", ElementType::u8},
      {10, "rest_positions", ElementType::f32},
      {11, "triangles", ElementType::u32},
      {12, "fixed_nodes", ElementType::u32},
      {13, "surface_nodes", ElementType::u32},
      {20, "mode_shapes", ElementType::f32},
      {21, "omega_squared", ElementType::f32},
      {22, "modal_damping", ElementType::f32},
      {23, "residual_compliance", ElementType::f32},
      {30, "tensor_displacement", ElementType::f32},
      {31, "tensor_force", ElementType::f32},
      {32, "tensor_nodes", ElementType::u32},
  };
  for (const SpecEntry& entry : expected) {
    const SectionDescriptor* descriptor = find_section_descriptor(entry.id);
    ASSERT_NE(descriptor, nullptr) << entry.id;
    EXPECT_STREQ(descriptor->name, entry.name);
    EXPECT_EQ(descriptor->element_type, entry.type) << entry.name;
  }
  EXPECT_EQ(find_section_descriptor(0), nullptr);
  EXPECT_EQ(find_section_descriptor(24), nullptr);
  EXPECT_STREQ(section_name(static_cast<SectionId>(99)), "unknown");
}

}  // namespace
}  // namespace trainer::model
