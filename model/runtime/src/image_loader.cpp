// Model image loader: file I/O into the arena and the validation of every field of a
// version-1 image (docs/model-image.md lists the checks in the order they run here).
// The order matters for the messages: what is needed to find the bytes (header) is checked
// first, then the checksum, so any later complaint is about what the writer produced, not
// about a damaged file.
#include "trainer/model/image_loader.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <system_error>
#include <utility>

#include "catheter_image_checks.hpp"
#include "image_checks.hpp"

namespace trainer::model {

namespace {

using core::Error;
using core::Expected;
using detail::image_error;
using detail::number;
using detail::read_record;
using detail::require_rows;
using detail::section_label;

// ---- message helpers (error path only: these allocate) ----

std::string hex(std::uint64_t value) {
  char buffer[24];
  std::snprintf(buffer, sizeof buffer, "0x%" PRIx64, value);
  return buffer;
}

const char* element_type_name(std::uint32_t element_type) {
  switch (static_cast<ElementType>(element_type)) {
    case ElementType::f32: return "f32";
    case ElementType::u32: return "u32";
    case ElementType::i32: return "i32";
    case ElementType::u8: return "u8";
  }
  return "unknown";
}

template <class T>
std::span<const T> typed_span(const SectionView* view, ElementType type) noexcept {
  if (view == nullptr || view->element_type != type) return {};
  // The section start is 64-byte aligned (validated), so the cast is aligned.
  return {static_cast<const T*>(static_cast<const void*>(view->data)),
          static_cast<std::size_t>(view->element_count)};
}

// ---- header ----

// Everything needed to locate the sections. Runs on a stack copy of the header before the
// loader reserves arena space, and again inside parse_model_image.
Expected<void> validate_header(const ImageHeaderV1& header, std::uint64_t actual_bytes,
                               std::string_view label, ModelKind expected_kind,
                               const ImageLimits& limits) {
  if (std::memcmp(header.magic, kImageMagic, sizeof kImageMagic) != 0) {
    std::uint64_t magic_value = 0;
    std::memcpy(&magic_value, header.magic, sizeof magic_value);
    return image_error(label, "magic is " + hex(magic_value) +
                                  " (little-endian u64), not \"HTRMODEL\": not a model image");
  }
  if (header.format_version != kImageFormatVersion) {
    return image_error(label, "image format version " + std::to_string(header.format_version) +
                                  ", this build reads " + std::to_string(kImageFormatVersion) +
                                  ": rebuild it with modelc");
  }
  if (header.header_bytes != kImageHeaderBytes) {
    return image_error(label, "header_bytes is " + std::to_string(header.header_bytes) +
                                  ", format version 1 has " + std::to_string(kImageHeaderBytes));
  }
  if (header.byte_order_mark != kImageByteOrderMark) {
    const bool swapped = header.byte_order_mark == 0x04030201U;
    return image_error(label, "byte_order_mark is " + hex(header.byte_order_mark) + ", expected " +
                                  hex(kImageByteOrderMark) +
                                  (swapped ? ": the image was written big-endian; this build "
                                             "reads little-endian images only"
                                           : ": not a valid byte order mark"));
  }
  if (!is_known_model_kind(header.model_kind)) {
    return image_error(label, "model_kind " + std::to_string(header.model_kind) +
                                  " is unknown (1 = modal_shell, 2 = tet_tensor, 3 = catheter)");
  }
  if (header.model_kind != static_cast<std::uint32_t>(expected_kind)) {
    return image_error(label, std::string("model_kind is ") +
                                  model_kind_name(static_cast<ModelKind>(header.model_kind)) +
                                  ", the scene expects " + model_kind_name(expected_kind));
  }
  if (header.file_bytes != actual_bytes) {
    return image_error(label, "header file_bytes is " + std::to_string(header.file_bytes) +
                                  " but the file is " + std::to_string(actual_bytes) +
                                  " bytes (truncated or appended to)");
  }
  if (header.file_bytes > limits.max_file_bytes) {
    return image_error(label, "file_bytes " + std::to_string(header.file_bytes) +
                                  " exceeds the limit of " + std::to_string(limits.max_file_bytes) +
                                  " (ImageLimits::max_file_bytes)");
  }
  if (header.section_count > kImageMaxSections) {
    return image_error(label, "section_count " + std::to_string(header.section_count) +
                                  " exceeds the format maximum of " +
                                  std::to_string(kImageMaxSections));
  }
  if (header.section_count == 0) {
    return image_error(label, "section_count is 0: an image needs at least its metadata section");
  }
  if (header.section_table_offset != kImageHeaderBytes) {
    return image_error(label, "section_table_offset is " +
                                  std::to_string(header.section_table_offset) +
                                  ", format version 1 puts the table at byte " +
                                  std::to_string(kImageHeaderBytes));
  }
  const std::uint64_t table_end = std::uint64_t{header.section_table_offset} +
                                  std::uint64_t{header.section_count} * kImageSectionEntryBytes;
  if (table_end > header.file_bytes) {
    return image_error(label, "section table (" + std::to_string(header.section_count) +
                                  " entries, ending at byte " + std::to_string(table_end) +
                                  ") runs past the end of the file (" +
                                  std::to_string(header.file_bytes) + " bytes)");
  }
  return {};
}

Expected<void> check_too_short(std::uint64_t actual_bytes, std::string_view label) {
  if (actual_bytes < kImageHeaderBytes) {
    return image_error(label, "file is " + std::to_string(actual_bytes) +
                                  " bytes, shorter than the " + std::to_string(kImageHeaderBytes) +
                                  "-byte header (truncated or not a model image)");
  }
  return {};
}

// ---- sections ----

struct SectionSpan {
  std::uint64_t begin = 0;
  std::uint64_t end = 0;
  std::uint32_t id = 0;
};

// Everything one table entry states on its own, plus uniqueness against earlier entries.
Expected<SectionView> validate_entry(const SectionEntryV1& entry, std::uint32_t index,
                                     std::span<const SectionView> earlier,
                                     std::span<const std::byte> file, std::uint64_t table_end,
                                     ModelKind kind, std::string_view label) {
  const SectionDescriptor* descriptor = find_section_descriptor(entry.id);
  if (descriptor == nullptr) {
    return image_error(label, "section table entry " + std::to_string(index) + " has unknown id " +
                                  std::to_string(entry.id));
  }
  // Built only on failure: the success path must not allocate.
  const auto name = [&entry] { return section_label(entry.id); };
  if (!section_belongs_to(*descriptor, kind)) {
    return image_error(label, name() + " does not belong in a " + model_kind_name(kind) +
                                  " image (it is part of " + owners_text(*descriptor) + ")");
  }
  for (std::size_t other = 0; other < earlier.size(); ++other) {
    if (static_cast<std::uint32_t>(earlier[other].id) == entry.id) {
      return image_error(label, name() + " appears twice (section table entries " +
                                    std::to_string(other) + " and " + std::to_string(index) + ")");
    }
  }
  const std::size_t element_bytes = element_type_bytes(entry.element_type);
  if (element_bytes == 0) {
    return image_error(label, name() + " element_type " + std::to_string(entry.element_type) +
                                  " is unknown (1 = f32, 2 = u32, 3 = i32, 4 = u8)");
  }
  if (entry.element_type != static_cast<std::uint32_t>(descriptor->element_type)) {
    return image_error(label,
                       name() + " element_type is " + element_type_name(entry.element_type) +
                           ", the format requires " +
                           element_type_name(static_cast<std::uint32_t>(descriptor->element_type)));
  }
  if (entry.offset % kImageSectionAlignment != 0) {
    return image_error(label, name() + " offset " + std::to_string(entry.offset) + " is not " +
                                  std::to_string(kImageSectionAlignment) + "-byte aligned");
  }
  const std::uint64_t file_bytes = file.size();
  if (entry.offset < table_end) {
    return image_error(label, name() + " offset " + std::to_string(entry.offset) +
                                  " lies inside the header or section table (which end at byte " +
                                  std::to_string(table_end) + ")");
  }
  if (entry.offset > file_bytes) {
    return image_error(label, name() + " offset " + std::to_string(entry.offset) +
                                  " is past the end of the file (" + std::to_string(file_bytes) +
                                  " bytes)");
  }
  // Divide rather than multiply: element_count × element_bytes may overflow 64 bits.
  if (entry.element_count > (file_bytes - entry.offset) / element_bytes) {
    return image_error(label, name() + " element_count " + std::to_string(entry.element_count) +
                                  " (" + std::to_string(element_bytes) +
                                  " bytes each) does not fit between offset " +
                                  std::to_string(entry.offset) + " and the end of the file (" +
                                  std::to_string(file_bytes) + " bytes)");
  }
  // Two u32 factors cannot overflow a u64 product.
  const std::uint64_t shape_count = std::uint64_t{entry.rows} * std::uint64_t{entry.cols};
  if (shape_count != entry.element_count) {
    return image_error(label, name() + " rows × cols = " + std::to_string(entry.rows) + " × " +
                                  std::to_string(entry.cols) + " = " + std::to_string(shape_count) +
                                  " but element_count is " + std::to_string(entry.element_count));
  }
  if (descriptor->required_cols != 0 && entry.cols != descriptor->required_cols) {
    return image_error(label, name() + " has " + std::to_string(entry.cols) +
                                  " columns, the format requires " +
                                  std::to_string(descriptor->required_cols));
  }
  SectionView view;
  view.id = descriptor->id;
  view.element_type = descriptor->element_type;
  view.rows = entry.rows;
  view.cols = entry.cols;
  view.element_count = entry.element_count;
  view.data = file.data() + entry.offset;
  return view;
}

// Non-empty sections must not share a byte, and every byte that is neither header, table nor
// section (alignment padding, trailing bytes) must be zero.
Expected<void> check_layout(std::span<const SectionView> sections, std::span<const std::byte> file,
                            std::uint64_t table_end, std::string_view label) {
  std::array<SectionSpan, kImageMaxSections> spans{};
  std::size_t span_count = 0;
  for (const SectionView& view : sections) {
    if (view.element_count == 0) continue;  // occupies no byte
    SectionSpan span;
    span.begin = static_cast<std::uint64_t>(view.data - file.data());
    span.end = span.begin + view.element_count *
                                element_type_bytes(static_cast<std::uint32_t>(view.element_type));
    span.id = static_cast<std::uint32_t>(view.id);
    // Insertion sort by begin: at most 32 entries.
    std::size_t position = span_count;
    while (position > 0 && spans[position - 1].begin > span.begin) {
      spans[position] = spans[position - 1];
      --position;
    }
    spans[position] = span;
    ++span_count;
  }
  std::uint64_t cursor = table_end;
  for (std::size_t i = 0; i < span_count; ++i) {
    const SectionSpan& span = spans[i];
    if (i > 0 && span.begin < spans[i - 1].end) {
      const SectionSpan& previous = spans[i - 1];
      return image_error(
          label, section_label(previous.id) + " (bytes " + std::to_string(previous.begin) + ".." +
                     std::to_string(previous.end) + ") and " + section_label(span.id) + " (bytes " +
                     std::to_string(span.begin) + ".." + std::to_string(span.end) + ") overlap");
    }
    for (std::uint64_t byte = cursor; byte < span.begin; ++byte) {
      if (file[byte] != std::byte{0}) {
        return image_error(label, "padding byte " + std::to_string(byte) + " before " +
                                      section_label(span.id) + " is not zero");
      }
    }
    cursor = span.end;
  }
  for (std::uint64_t byte = cursor; byte < file.size(); ++byte) {
    if (file[byte] != std::byte{0}) {
      return image_error(
          label, "padding byte " + std::to_string(byte) + " after the last section is not zero");
    }
  }
  return {};
}

// ---- metadata ----

Expected<void> check_metadata_record(const ImageMetadataV1& metadata, ModelKind kind,
                                     std::string_view label) {
  if (metadata.element_type > static_cast<std::uint32_t>(FiniteElementType::tet4)) {
    return image_error(label, "metadata element_type " + std::to_string(metadata.element_type) +
                                  " is unknown (0 = none, 1 = shell_rao, 2 = shell_dkt, 3 = tet4)");
  }
  if (std::memchr(metadata.tool_version, '\0', sizeof metadata.tool_version) == nullptr) {
    return image_error(label, "metadata tool_version is not NUL-terminated within " +
                                  std::to_string(sizeof metadata.tool_version) + " bytes");
  }
  if (metadata.padding0 != 0) return image_error(label, "metadata padding0 is not zero");
  for (std::size_t i = 0; i < sizeof metadata.reserved; ++i) {
    if (metadata.reserved[i] != 0) {
      return image_error(label, "metadata reserved byte " + std::to_string(i) + " is not zero");
    }
  }
  if (metadata.static_correction > 1) {
    return image_error(label, "metadata static_correction is " +
                                  std::to_string(metadata.static_correction) + ", expected 0 or 1");
  }
  struct NamedValue {
    const char* name;
    double value;
  };
  const NamedValue non_negative[] = {
      {"young_modulus_pa", metadata.young_modulus_pa},   {"thickness_m", metadata.thickness_m},
      {"density_kg_per_m3", metadata.density_kg_per_m3}, {"time_step_s", metadata.time_step_s},
      {"damping_ratio", metadata.damping_ratio},
  };
  for (const NamedValue& field : non_negative) {
    if (!std::isfinite(field.value) || field.value < 0.0) {
      return image_error(label, std::string("metadata ") + field.name + " is " +
                                    number(field.value) + ", expected a finite value >= 0");
    }
  }
  if (!std::isfinite(metadata.poisson_ratio)) {
    return image_error(label, "metadata poisson_ratio is " + number(metadata.poisson_ratio) +
                                  ", expected a finite value");
  }
  // NaN means "not measured" / "no budget"; infinity is never meaningful.
  const NamedValue nan_or_non_negative[] = {
      {"error_estimate", metadata.error_estimate},
      {"error_budget", metadata.error_budget},
  };
  for (const NamedValue& field : nan_or_non_negative) {
    if (!std::isnan(field.value) && (std::isinf(field.value) || field.value < 0.0)) {
      return image_error(label, std::string("metadata ") + field.name + " is " +
                                    number(field.value) + ", expected NaN (none) or a value >= 0");
    }
  }
  if (kind == ModelKind::modal_shell) {
    if (!(metadata.young_modulus_pa > 0.0) || !(metadata.thickness_m > 0.0) ||
        !(metadata.density_kg_per_m3 > 0.0)) {
      return image_error(label, "metadata young_modulus_pa " + number(metadata.young_modulus_pa) +
                                    ", thickness_m " + number(metadata.thickness_m) +
                                    ", density_kg_per_m3 " + number(metadata.density_kg_per_m3) +
                                    ": a shell needs all three > 0");
    }
    if (!(metadata.poisson_ratio > -1.0 && metadata.poisson_ratio < 0.5)) {
      return image_error(label, "metadata poisson_ratio is " + number(metadata.poisson_ratio) +
                                    ", expected -1 < nu < 0.5");
    }
  }
  return {};
}

Expected<void> check_limits(const ImageMetadataV1& metadata, const ModelImage& image,
                            const ImageLimits& limits, std::string_view label) {
  struct Count {
    const char* field;
    std::uint64_t value;
    std::uint64_t limit;
    const char* limit_name;
  };
  const Count counts[] = {
      {"metadata node_count", metadata.node_count, limits.max_node_count, "max_node_count"},
      {"metadata mode_count", metadata.mode_count, limits.max_mode_count, "max_mode_count"},
      {"metadata surface_node_count", metadata.surface_node_count, limits.max_surface_node_count,
       "max_surface_node_count"},
      {"section 'triangles' rows", image.rows(SectionId::triangles), limits.max_triangle_count,
       "max_triangle_count"},
  };
  for (const Count& count : counts) {
    if (count.value > count.limit) {
      return image_error(label, std::string(count.field) + " " + std::to_string(count.value) +
                                    " exceeds the limit of " + std::to_string(count.limit) +
                                    " (ImageLimits::" + count.limit_name + ")");
    }
  }
  return {};
}

Expected<void> check_finite(const SectionView& view, std::string_view label) {
  const std::span<const float> values = typed_span<float>(&view, ElementType::f32);
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return image_error(label, section_label(view.id) + " element " + std::to_string(i) +
                                    " (row " + std::to_string(i / view.cols) + ", col " +
                                    std::to_string(i % view.cols) + ") is " + number(values[i]) +
                                    ": float sections must be finite");
    }
  }
  return {};
}

// ---- modal shell consistency ----

// A node list must be strictly increasing (so it has no duplicates and can be bisected) and
// name existing nodes.
Expected<void> check_node_list(const ModelImage& image, SectionId id, std::uint32_t node_count,
                               std::string_view label) {
  const std::span<const std::uint32_t> nodes = image.u32s(id);
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i] >= node_count) {
      return image_error(label, section_label(id) + " entry " + std::to_string(i) + " is node " +
                                    std::to_string(nodes[i]) + ", but node_count is " +
                                    std::to_string(node_count));
    }
    if (i > 0 && nodes[i] <= nodes[i - 1]) {
      return image_error(label, section_label(id) + " entry " + std::to_string(i) + " (node " +
                                    std::to_string(nodes[i]) +
                                    ") is not greater than the previous entry: node lists are "
                                    "strictly increasing");
    }
  }
  return {};
}

Expected<void> check_triangles(const ModelImage& image, std::uint32_t node_count,
                               std::string_view label) {
  if (image.rows(SectionId::triangles) == 0) {
    return image_error(label, "section 'triangles' is empty");
  }
  const std::span<const std::uint32_t> triangles = image.u32s(SectionId::triangles);
  for (std::size_t row = 0; row < triangles.size() / 3; ++row) {
    const std::uint32_t a = triangles[row * 3];
    const std::uint32_t b = triangles[row * 3 + 1];
    const std::uint32_t c = triangles[row * 3 + 2];
    if (a >= node_count || b >= node_count || c >= node_count || a == b || b == c || a == c) {
      return image_error(
          label, "section 'triangles' row " + std::to_string(row) + " (" + std::to_string(a) +
                     ", " + std::to_string(b) + ", " + std::to_string(c) +
                     ") needs three distinct nodes below node_count " + std::to_string(node_count));
    }
  }
  return {};
}

Expected<void> check_modal_shell(const ModelImage& image, std::string_view label) {
  const ImageMetadataV1& metadata = image.metadata();
  constexpr SectionId kRequired[] = {SectionId::rest_positions, SectionId::triangles,
                                     SectionId::mode_shapes, SectionId::omega_squared,
                                     SectionId::modal_damping};
  for (const SectionId id : kRequired) {
    if (!image.has(id)) {
      return image_error(label, std::string("a modal_shell image needs ") + section_label(id) +
                                    ", which is missing");
    }
  }
  const std::uint32_t node_count = metadata.node_count;
  const std::uint32_t mode_count = metadata.mode_count;
  if (node_count == 0 || mode_count == 0) {
    return image_error(label, "metadata node_count " + std::to_string(node_count) +
                                  " and mode_count " + std::to_string(mode_count) +
                                  ": a modal_shell image needs both > 0");
  }
  if (auto ok =
          require_rows(image, SectionId::rest_positions, node_count, "metadata node_count", label);
      !ok) {
    return ok;
  }
  if (auto ok = require_rows(image, SectionId::mode_shapes, 3ULL * node_count,
                             "3 × metadata node_count", label);
      !ok) {
    return ok;
  }
  if (image.cols(SectionId::mode_shapes) != mode_count) {
    return image_error(
        label, "section 'mode_shapes' has " + std::to_string(image.cols(SectionId::mode_shapes)) +
                   " columns, expected " + std::to_string(mode_count) + " (metadata mode_count)");
  }
  for (const SectionId id : {SectionId::omega_squared, SectionId::modal_damping}) {
    if (auto ok = require_rows(image, id, mode_count, "metadata mode_count", label); !ok) return ok;
  }
  const std::span<const float> omega_squared = image.floats(SectionId::omega_squared);
  for (std::size_t i = 0; i < omega_squared.size(); ++i) {
    if (omega_squared[i] < 0.0F || (i > 0 && omega_squared[i] < omega_squared[i - 1])) {
      return image_error(label, "section 'omega_squared' element " + std::to_string(i) + " is " +
                                    number(omega_squared[i]) +
                                    ": values must be >= 0 and ascending");
    }
  }
  const std::span<const float> damping = image.floats(SectionId::modal_damping);
  for (std::size_t i = 0; i < damping.size(); ++i) {
    if (damping[i] < 0.0F) {
      return image_error(label, "section 'modal_damping' element " + std::to_string(i) + " is " +
                                    number(damping[i]) + ": damping must be >= 0");
    }
  }
  if (auto ok = check_triangles(image, node_count, label); !ok) return ok;
  if (auto ok = check_node_list(image, SectionId::fixed_nodes, node_count, label); !ok) return ok;
  const std::uint32_t surface_count = metadata.surface_node_count;
  if (surface_count > 0 && !image.has(SectionId::surface_nodes)) {
    return image_error(label, "metadata surface_node_count is " + std::to_string(surface_count) +
                                  " but section 'surface_nodes' is missing");
  }
  if (image.has(SectionId::surface_nodes)) {
    if (auto ok = require_rows(image, SectionId::surface_nodes, surface_count,
                               "metadata surface_node_count", label);
        !ok) {
      return ok;
    }
    if (auto ok = check_node_list(image, SectionId::surface_nodes, node_count, label); !ok) {
      return ok;
    }
  }
  const bool has_compliance = image.has(SectionId::residual_compliance);
  if (has_compliance != (metadata.static_correction == 1)) {
    return image_error(label, "metadata static_correction is " +
                                  std::to_string(metadata.static_correction) +
                                  " but section 'residual_compliance' is " +
                                  (has_compliance ? "present" : "missing"));
  }
  if (has_compliance) {
    const std::uint64_t size = 3ULL * surface_count;
    if (surface_count == 0 || image.rows(SectionId::residual_compliance) != size ||
        image.cols(SectionId::residual_compliance) != size) {
      return image_error(
          label, "section 'residual_compliance' is " +
                     std::to_string(image.rows(SectionId::residual_compliance)) + " × " +
                     std::to_string(image.cols(SectionId::residual_compliance)) +
                     ", expected 3s × 3s = " + std::to_string(size) + " × " + std::to_string(size) +
                     " for s = " + std::to_string(surface_count) + " surface nodes (> 0)");
    }
    // Symmetric up to float rounding of a symmetric double matrix; 1e-4 of the largest entry
    // is far above rounding (~6e-8) and far below any real asymmetry.
    const std::span<const float> compliance = image.floats(SectionId::residual_compliance);
    float largest = 0.0F;
    for (const float value : compliance) largest = std::fmax(largest, std::fabs(value));
    const float tolerance = 1e-4F * largest;
    const std::size_t n = static_cast<std::size_t>(size);
    for (std::size_t row = 0; row < n; ++row) {
      for (std::size_t col = row + 1; col < n; ++col) {
        const float upper = compliance[row * n + col];
        const float lower = compliance[col * n + row];
        if (std::fabs(upper - lower) > tolerance) {
          return image_error(label, "section 'residual_compliance' is not symmetric: (" +
                                        std::to_string(row) + ", " + std::to_string(col) +
                                        ") = " + number(upper) + " but (" + std::to_string(col) +
                                        ", " + std::to_string(row) + ") = " + number(lower));
        }
      }
    }
  }
  return {};
}

// ---- tetrahedral tensor consistency ----

Expected<void> check_tet_tensor(const ModelImage& image, std::string_view label) {
  const ImageMetadataV1& metadata = image.metadata();
  constexpr SectionId kRequired[] = {SectionId::rest_positions, SectionId::triangles,
                                     SectionId::surface_nodes,  SectionId::tensor_nodes,
                                     SectionId::tensor_displacement, SectionId::tensor_force};
  for (const SectionId id : kRequired) {
    if (!image.has(id)) {
      return image_error(label, std::string("a tet_tensor image needs ") + section_label(id) +
                                    ", which is missing");
    }
  }
  if (metadata.element_type != static_cast<std::uint32_t>(FiniteElementType::tet4) ||
      metadata.mode_count != 0) {
    return image_error(label, "metadata element_type " + std::to_string(metadata.element_type) +
                                  " and mode_count " + std::to_string(metadata.mode_count) +
                                  ": a tet_tensor image is built from tet4 (3) with no modes (0)");
  }
  if (!(metadata.young_modulus_pa > 0.0) ||
      !(metadata.poisson_ratio > -1.0 && metadata.poisson_ratio < 0.5)) {
    return image_error(label, "metadata young_modulus_pa " + number(metadata.young_modulus_pa) +
                                  ", poisson_ratio " + number(metadata.poisson_ratio) +
                                  ": expected E > 0 and -1 < nu < 0.5");
  }
  const std::uint32_t node_count = metadata.node_count;
  const std::uint32_t contact_count = metadata.surface_node_count;
  if (node_count == 0 || contact_count == 0) {
    return image_error(label, "metadata node_count " + std::to_string(node_count) +
                                  " and surface_node_count " + std::to_string(contact_count) +
                                  ": a tet_tensor image needs both > 0");
  }
  if (auto ok =
          require_rows(image, SectionId::rest_positions, node_count, "metadata node_count", label);
      !ok) {
    return ok;
  }
  if (auto ok = check_triangles(image, node_count, label); !ok) return ok;
  for (const SectionId id :
       {SectionId::fixed_nodes, SectionId::surface_nodes, SectionId::tensor_nodes}) {
    if (auto ok = check_node_list(image, id, node_count, label); !ok) return ok;
  }
  if (auto ok = require_rows(image, SectionId::surface_nodes, contact_count,
                             "metadata surface_node_count", label);
      !ok) {
    return ok;
  }
  const std::span<const std::uint32_t> contacts = image.u32s(SectionId::surface_nodes);
  const std::span<const std::uint32_t> responses = image.u32s(SectionId::tensor_nodes);
  const std::span<const std::uint32_t> fixed = image.u32s(SectionId::fixed_nodes);
  if (responses.empty()) return image_error(label, "section 'tensor_nodes' is empty");
  // Every contact node must have a stored response (its mutual-influence rows) and be free.
  for (std::size_t k = 0; k < contacts.size(); ++k) {
    if (!std::binary_search(responses.begin(), responses.end(), contacts[k])) {
      return image_error(label, "surface node " + std::to_string(contacts[k]) + " (entry " +
                                    std::to_string(k) +
                                    ") is not in section 'tensor_nodes': every contact node "
                                    "needs its stored response");
    }
    if (std::binary_search(fixed.begin(), fixed.end(), contacts[k])) {
      return image_error(label, "surface node " + std::to_string(contacts[k]) +
                                    " is also a fixed node: a fixed node cannot be displaced");
    }
  }
  const std::uint64_t response_count = responses.size();
  if (auto ok = require_rows(image, SectionId::tensor_displacement, contact_count * response_count,
                             "surface_node_count × rows of 'tensor_nodes'", label);
      !ok) {
    return ok;
  }
  if (auto ok = require_rows(image, SectionId::tensor_force, contact_count,
                             "metadata surface_node_count", label);
      !ok) {
    return ok;
  }
  // Structural checks that catch a wrong build or a writer bug (the checksum catches damage):
  // F(k) is symmetric with a positive diagonal, and T(k, k) is the identity — the displacement
  // imposed at k is what k does. Tolerances sit far above float rounding of a double build.
  const std::span<const float> forces = image.floats(SectionId::tensor_force);
  const std::span<const float> tensors = image.floats(SectionId::tensor_displacement);
  for (std::size_t k = 0; k < contact_count; ++k) {
    const float* force = forces.data() + 9 * k;
    float largest = 0.0F;
    for (int i = 0; i < 9; ++i) largest = std::fmax(largest, std::fabs(force[i]));
    for (int row = 0; row < 3; ++row) {
      if (!(force[4 * row] > 0.0F)) {
        return image_error(label, "section 'tensor_force' contact " + std::to_string(k) +
                                      " diagonal " + std::to_string(row) + " is " +
                                      number(force[4 * row]) + ", expected > 0");
      }
      for (int col = row + 1; col < 3; ++col) {
        if (std::fabs(force[3 * row + col] - force[3 * col + row]) > 1e-4F * largest) {
          return image_error(label, "section 'tensor_force' contact " + std::to_string(k) +
                                        " is not symmetric");
        }
      }
    }
    const auto self = static_cast<std::size_t>(
        std::lower_bound(responses.begin(), responses.end(), contacts[k]) - responses.begin());
    const float* tensor = tensors.data() + 9 * (k * response_count + self);
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) {
        const float expected = row == col ? 1.0F : 0.0F;
        if (std::fabs(tensor[3 * row + col] - expected) > 1e-3F) {
          return image_error(label, "section 'tensor_displacement' T(k, k) of contact " +
                                        std::to_string(k) + " (node " +
                                        std::to_string(contacts[k]) + ") element (" +
                                        std::to_string(row) + ", " + std::to_string(col) +
                                        ") is " + number(tensor[3 * row + col]) + ", expected " +
                                        number(expected));
        }
      }
    }
  }
  return {};
}

// ---- file I/O ----

class FileDescriptor {
 public:
  explicit FileDescriptor(int descriptor) noexcept : descriptor_(descriptor) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() {
    if (descriptor_ >= 0) ::close(descriptor_);
  }
  int get() const noexcept { return descriptor_; }

 private:
  int descriptor_;
};

std::string errno_text(int error_number) {
  return std::error_code(error_number, std::generic_category()).message();
}

// Reads exactly `bytes` from `offset`, retrying on EINTR and short reads.
Expected<void> read_exactly(int descriptor, std::byte* destination, std::size_t bytes,
                            std::uint64_t offset, std::string_view label) {
  std::size_t done = 0;
  while (done < bytes) {
    const ssize_t got =
        ::pread(descriptor, destination + done, bytes - done, static_cast<off_t>(offset + done));
    if (got < 0) {
      if (errno == EINTR) continue;
      return image_error(
          label, "read failed at byte " + std::to_string(offset + done) + ": " + errno_text(errno));
    }
    if (got == 0) {
      return image_error(label, "file ended at byte " + std::to_string(offset + done) +
                                    " while reading (it shrank during the load)");
    }
    done += static_cast<std::size_t>(got);
  }
  return {};
}

}  // namespace

// ---- ModelImage ----

const SectionView* ModelImage::find(SectionId id) const noexcept {
  for (std::uint32_t i = 0; i < section_count_; ++i) {
    if (sections_[i].id == id) return &sections_[i];
  }
  return nullptr;
}

std::uint32_t ModelImage::rows(SectionId id) const noexcept {
  const SectionView* view = find(id);
  return view != nullptr ? view->rows : 0;
}

std::uint32_t ModelImage::cols(SectionId id) const noexcept {
  const SectionView* view = find(id);
  return view != nullptr ? view->cols : 0;
}

std::span<const float> ModelImage::floats(SectionId id) const noexcept {
  return typed_span<float>(find(id), ElementType::f32);
}

std::span<const std::uint32_t> ModelImage::u32s(SectionId id) const noexcept {
  return typed_span<std::uint32_t>(find(id), ElementType::u32);
}

std::span<const std::int32_t> ModelImage::i32s(SectionId id) const noexcept {
  return typed_span<std::int32_t>(find(id), ElementType::i32);
}

std::span<const std::uint8_t> ModelImage::u8s(SectionId id) const noexcept {
  return typed_span<std::uint8_t>(find(id), ElementType::u8);
}

// ---- parse and load ----

core::Expected<ModelImage> parse_model_image(std::span<const std::byte> file,
                                             std::string_view file_label, ModelKind expected_kind,
                                             const ImageLimits& limits) {
  if (auto ok = check_too_short(file.size(), file_label); !ok) return std::move(ok).error();
  if (reinterpret_cast<std::uintptr_t>(file.data()) % kImageSectionAlignment != 0) {
    return image_error(file_label, "image bytes are not " + std::to_string(kImageSectionAlignment) +
                                       "-byte aligned in memory (caller bug)");
  }
  const auto header = read_record<ImageHeaderV1>(file.data());
  if (auto ok = validate_header(header, file.size(), file_label, expected_kind, limits); !ok) {
    return std::move(ok).error();
  }
  const std::uint64_t computed = compute_image_checksum(file);
  if (computed != header.checksum) {
    return image_error(file_label, "checksum mismatch: header says " + hex(header.checksum) +
                                       ", the contents hash to " + hex(computed) +
                                       " (the file is damaged or was modified)");
  }
  for (std::size_t i = 0; i < sizeof header.reserved; ++i) {
    if (header.reserved[i] != 0) {
      return image_error(file_label, "header reserved byte " +
                                         std::to_string(offsetof(ImageHeaderV1, reserved) + i) +
                                         " is not zero");
    }
  }

  ModelImage image;
  image.kind_ = expected_kind;
  image.checksum_ = header.checksum;
  image.bytes_ = file;
  const std::uint64_t table_end = std::uint64_t{kImageHeaderBytes} +
                                  std::uint64_t{header.section_count} * kImageSectionEntryBytes;
  for (std::uint32_t index = 0; index < header.section_count; ++index) {
    const auto entry = read_record<SectionEntryV1>(file.data() + kImageHeaderBytes +
                                                   std::size_t{index} * kImageSectionEntryBytes);
    auto view = validate_entry(entry, index, {image.sections_.data(), image.section_count_}, file,
                               table_end, expected_kind, file_label);
    if (!view) return std::move(view).error();
    image.sections_[image.section_count_++] = view.value();
  }
  if (auto ok = check_layout(image.sections(), file, table_end, file_label); !ok) {
    return std::move(ok).error();
  }

  const std::span<const std::uint8_t> metadata_bytes = image.u8s(SectionId::metadata);
  if (!image.has(SectionId::metadata)) {
    return image_error(file_label, "section 'metadata' is missing");
  }
  if (metadata_bytes.size() != sizeof(ImageMetadataV1)) {
    return image_error(
        file_label, "section 'metadata' is " + std::to_string(metadata_bytes.size()) +
                        " bytes, format version 1 has " + std::to_string(sizeof(ImageMetadataV1)));
  }
  std::memcpy(&image.metadata_, metadata_bytes.data(), sizeof(ImageMetadataV1));
  if (auto ok = check_metadata_record(image.metadata_, expected_kind, file_label); !ok) {
    return std::move(ok).error();
  }
  if (auto ok = check_limits(image.metadata_, image, limits, file_label); !ok) {
    return std::move(ok).error();
  }
  for (const SectionView& view : image.sections()) {
    if (auto ok = check_finite(view, file_label); !ok) return std::move(ok).error();
  }
  Expected<void> consistent;
  switch (expected_kind) {
    case ModelKind::modal_shell: consistent = check_modal_shell(image, file_label); break;
    case ModelKind::tet_tensor: consistent = check_tet_tensor(image, file_label); break;
    case ModelKind::catheter: consistent = detail::check_catheter_image(image, file_label); break;
  }
  if (!consistent) return std::move(consistent).error();
  return image;
}

core::Expected<ModelImage> load_model_image(const std::filesystem::path& path, core::Arena& arena,
                                            const ImageLimits& limits, ModelKind expected_kind) {
  // path.native() is the std::string the path already owns: no copy on the success path.
  const std::string_view label = path.native();
  const FileDescriptor file(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (file.get() < 0) return image_error(label, "cannot open: " + errno_text(errno));
  struct stat status {};
  if (::fstat(file.get(), &status) != 0) {
    return image_error(label, "cannot stat: " + errno_text(errno));
  }
  if (!S_ISREG(status.st_mode)) return image_error(label, "is not a regular file");
  const auto actual_bytes = static_cast<std::uint64_t>(status.st_size);
  if (auto ok = check_too_short(actual_bytes, label); !ok) return std::move(ok).error();

  ImageHeaderV1 header{};
  if (auto ok =
          read_exactly(file.get(), reinterpret_cast<std::byte*>(&header), sizeof header, 0, label);
      !ok) {
    return std::move(ok).error();
  }
  // Refuse a bogus header (wrong kind, size mismatch, above the size limit) before reserving
  // arena space for it.
  if (auto ok = validate_header(header, actual_bytes, label, expected_kind, limits); !ok) {
    return std::move(ok).error();
  }
  auto block = arena.allocate_bytes(static_cast<std::size_t>(actual_bytes), core::Arena::kAlignment,
                                    "model image");
  if (!block) {
    return image_error(label, "cannot place the " + std::to_string(actual_bytes) +
                                  "-byte image in the arena: " + block.error().message);
  }
  auto* bytes = static_cast<std::byte*>(block.value());
  std::memcpy(bytes, &header, sizeof header);
  if (auto ok = read_exactly(file.get(), bytes + sizeof header,
                             static_cast<std::size_t>(actual_bytes) - sizeof header, sizeof header,
                             label);
      !ok) {
    return std::move(ok).error();
  }
  return parse_model_image({bytes, static_cast<std::size_t>(actual_bytes)}, label, expected_kind,
                           limits);
}

}  // namespace trainer::model
