// The model image writer (offline side of the format in trainer/model/image_format.hpp and
// docs/model-image.md): collects typed sections, converts double precision results to float32
// with a range check, lays the file out (header, section table, 64-byte-aligned sections,
// XXH64 checksum), checks the result with the runtime's own parser, and writes it atomically.
//
// Setup/tool code: every public function returns core::Expected with a message naming the
// section and the value at fault; std::bad_alloc is the only exception that can escape.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model::offline {

// Copies `version` into metadata.tool_version; refuses what does not fit with its NUL.
core::Expected<void> set_tool_version(ImageMetadataV1& metadata, std::string_view version);

// A zero-filled metadata record with error_estimate and error_budget NaN ("not measured",
// "no budget") and created_unix_s set to now.
ImageMetadataV1 make_metadata();

class ImageWriter {
 public:
  explicit ImageWriter(ModelKind kind) : kind_(kind) {}

  ModelKind kind() const noexcept { return kind_; }

  // Becomes the `metadata` section. Required before serialize()/write().
  void set_metadata(const ImageMetadataV1& metadata) { metadata_ = metadata; }

  // Each add_* checks that the id belongs to this writer's model kind, that its format element
  // type matches the call, that it was not added before, and that rows × cols equals the
  // number of values. Values are row-major (element (row, col) at row * cols + col).
  core::Expected<void> add_f32(SectionId id, std::span<const float> values, std::uint32_t rows,
                               std::uint32_t cols);
  // double → float32: every value must be finite and within ±FLT_MAX.
  core::Expected<void> add_f32(SectionId id, std::span<const double> values, std::uint32_t rows,
                               std::uint32_t cols);
  // Eigen matrices of any storage order; written row-major with the matrix's shape.
  core::Expected<void> add_f32(SectionId id, const Eigen::Ref<const Eigen::MatrixXd>& matrix);
  core::Expected<void> add_f32(SectionId id, const Eigen::Ref<const Eigen::MatrixXf>& matrix);
  core::Expected<void> add_u32(SectionId id, std::span<const std::uint32_t> values,
                               std::uint32_t rows, std::uint32_t cols);
  // int → u32: every value must be >= 0 (node indices from the offline mesh).
  core::Expected<void> add_u32(SectionId id, const Eigen::Ref<const Eigen::MatrixXi>& matrix);
  core::Expected<void> add_i32(SectionId id, std::span<const std::int32_t> values,
                               std::uint32_t rows, std::uint32_t cols);
  core::Expected<void> add_u8(SectionId id, std::span<const std::uint8_t> values,
                              std::uint32_t rows, std::uint32_t cols);

  // The complete image, sections in ascending id order (so equal inputs give equal bytes).
  // It is parsed with parse_model_image (under `limits`) before being returned, so the writer
  // never hands out an image the runtime would refuse for its structure or consistency.
  core::Expected<std::vector<std::byte>> serialize(
      const ImageLimits& limits = permissive_limits()) const;

  // serialize(), then write to a temporary file beside `path`, fsync, and rename over `path`:
  // readers see either the old file or the complete new one, never a partial image.
  core::Expected<void> write(const std::filesystem::path& path,
                             const ImageLimits& limits = permissive_limits()) const;

  // Limits that accept any count the format can express (the writer's default: the scene's
  // own limits are the loader's business).
  static ImageLimits permissive_limits() noexcept;

 private:
  struct Section {
    SectionId id;
    ElementType element_type;
    std::uint32_t rows;
    std::uint32_t cols;
    std::vector<std::byte> bytes;  // little-endian elements, row-major
  };

  core::Expected<void> check_new_section(SectionId id, ElementType element_type,
                                         std::uint64_t value_count, std::uint32_t rows,
                                         std::uint32_t cols) const;

  ModelKind kind_;
  std::optional<ImageMetadataV1> metadata_;
  std::vector<Section> sections_;
};

}  // namespace trainer::model::offline
