// The model image loader: reads a version-1 image (image_format.hpp, docs/model-image.md)
// into one 64-byte-aligned arena block, validates every field, and hands out a ModelImage —
// typed read-only views over that block. A ModelImage exists only fully validated (or empty):
// the runtime never sees a half-checked image.
//
// Setup path: returns core::Expected, each failure with its own message naming the file and
// the field. No heap use on the success path (the bytes go into the caller's arena; only
// error messages allocate). A failed load may have consumed arena space; a failed load is a
// setup error, so the caller does not arm and the arena is discarded with it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string_view>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/image_format.hpp"

namespace trainer::model {

// Capacities the runtime accepts. Counts come from the metadata and are cross-checked against
// the section shapes, so a limit bounds everything the runtime later sizes from the image.
struct ImageLimits {
  std::uint64_t max_file_bytes = 256ULL << 20U;  // checked before any arena allocation
  std::uint32_t max_node_count = 65536;
  std::uint32_t max_triangle_count = 131072;
  std::uint32_t max_mode_count = 512;
  std::uint32_t max_surface_node_count = 4096;
};

// One validated section: where its elements are and how they are shaped.
struct SectionView {
  SectionId id{};
  ElementType element_type{};
  std::uint32_t rows = 0;
  std::uint32_t cols = 0;
  std::uint64_t element_count = 0;
  const std::byte* data = nullptr;  // 64-byte aligned, inside the image block
};

class ModelImage {
 public:
  // An empty image: no sections, has() false for every id. Only parse/load produce others.
  ModelImage() noexcept = default;

  bool empty() const noexcept { return section_count_ == 0; }
  ModelKind model_kind() const noexcept { return kind_; }
  // A copy of the metadata section, so its doubles are read aligned.
  const ImageMetadataV1& metadata() const noexcept { return metadata_; }
  std::uint64_t checksum() const noexcept { return checksum_; }
  // The whole image as it was read (header included).
  std::span<const std::byte> bytes() const noexcept { return bytes_; }
  std::span<const SectionView> sections() const noexcept {
    return {sections_.data(), section_count_};
  }

  bool has(SectionId id) const noexcept { return find(id) != nullptr; }
  // 0 when the section is absent.
  std::uint32_t rows(SectionId id) const noexcept;
  std::uint32_t cols(SectionId id) const noexcept;
  // Row-major elements; empty when the section is absent or of another element type.
  std::span<const float> floats(SectionId id) const noexcept;
  std::span<const std::uint32_t> u32s(SectionId id) const noexcept;
  std::span<const std::int32_t> i32s(SectionId id) const noexcept;
  std::span<const std::uint8_t> u8s(SectionId id) const noexcept;

 private:
  friend core::Expected<ModelImage> parse_model_image(std::span<const std::byte> file,
                                                      std::string_view file_label,
                                                      ModelKind expected_kind,
                                                      const ImageLimits& limits);
  const SectionView* find(SectionId id) const noexcept;

  std::array<SectionView, kImageMaxSections> sections_{};
  std::uint32_t section_count_ = 0;
  ModelKind kind_ = ModelKind::modal_shell;
  std::uint64_t checksum_ = 0;
  ImageMetadataV1 metadata_{};
  std::span<const std::byte> bytes_{};
};

// Validates `file` (a complete image already in memory, whose first byte is 64-byte aligned)
// and returns views into it; `file` must outlive the result. `file_label` prefixes every
// message (normally the path). Used by load_model_image and by the offline writer to check
// what it is about to write.
core::Expected<ModelImage> parse_model_image(std::span<const std::byte> file,
                                             std::string_view file_label, ModelKind expected_kind,
                                             const ImageLimits& limits);

// open + fstat + header check (before any allocation, so a bogus header never reserves arena
// space) + one arena block of the file's size + read + parse_model_image.
core::Expected<ModelImage> load_model_image(const std::filesystem::path& path, core::Arena& arena,
                                            const ImageLimits& limits, ModelKind expected_kind);

}  // namespace trainer::model
