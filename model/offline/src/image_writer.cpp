// Model image writer: section collection, float32 conversion, layout, checksum, self-check
// with the runtime parser, and the atomic write (image_writer.hpp).
#include "trainer/model_offline/image_writer.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <system_error>
#include <utility>

namespace trainer::model::offline {

namespace {

std::string section_label(SectionId id) {
  return std::string("section '") + section_name(id) + "'";
}

std::string element_position(std::size_t index, std::uint32_t cols) {
  return "element " + std::to_string(index) + " (row " + std::to_string(index / cols) + ", col " +
         std::to_string(index % cols) + ")";
}

// Shortest text that reads back to the same value.
std::string number(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

std::uint64_t round_up(std::uint64_t value, std::uint64_t alignment) {
  return (value + alignment - 1) / alignment * alignment;
}

template <class T>
void append_bytes(std::vector<std::byte>& bytes, std::span<const T> values) {
  const auto* first = reinterpret_cast<const std::byte*>(values.data());
  bytes.insert(bytes.end(), first, first + values.size_bytes());
}

template <class T>
void store_record(std::vector<std::byte>& bytes, std::size_t offset, const T& record) {
  std::memcpy(bytes.data() + offset, &record, sizeof record);
}

std::string errno_text(int error_number) {
  return std::error_code(error_number, std::generic_category()).message();
}

// A 64-byte-aligned copy of the image for parse_model_image (std::vector only guarantees
// the default new alignment).
struct AlignedDelete {
  void operator()(std::byte* pointer) const noexcept {
    ::operator delete[](pointer, std::align_val_t{kImageSectionAlignment});
  }
};
using AlignedBytes = std::unique_ptr<std::byte[], AlignedDelete>;

AlignedBytes aligned_copy(const std::vector<std::byte>& bytes) {
  AlignedBytes copy(static_cast<std::byte*>(
      ::operator new[](bytes.size(), std::align_val_t{kImageSectionAlignment})));
  std::memcpy(copy.get(), bytes.data(), bytes.size());
  return copy;
}

core::Expected<void> write_all(int descriptor, const std::vector<std::byte>& bytes,
                               const std::string& temporary) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t wrote = ::write(descriptor, bytes.data() + done, bytes.size() - done);
    if (wrote < 0) {
      if (errno == EINTR) continue;
      return core::make_error(temporary + ": write failed at byte " + std::to_string(done) + ": " +
                              errno_text(errno));
    }
    done += static_cast<std::size_t>(wrote);
  }
  return {};
}

}  // namespace

core::Expected<void> set_tool_version(ImageMetadataV1& metadata, std::string_view version) {
  if (version.size() >= sizeof metadata.tool_version) {
    return core::make_error("tool_version \"" + std::string(version) + "\" is " +
                            std::to_string(version.size()) + " characters, at most " +
                            std::to_string(sizeof metadata.tool_version - 1) + " fit");
  }
  std::memset(metadata.tool_version, 0, sizeof metadata.tool_version);
  std::memcpy(metadata.tool_version, version.data(), version.size());
  return {};
}

ImageMetadataV1 make_metadata() {
  ImageMetadataV1 metadata{};
  metadata.error_estimate = std::numeric_limits<double>::quiet_NaN();
  metadata.error_budget = std::numeric_limits<double>::quiet_NaN();
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  metadata.created_unix_s =
      static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(now).count());
  return metadata;
}

ImageLimits ImageWriter::permissive_limits() noexcept {
  ImageLimits limits;
  limits.max_file_bytes = std::numeric_limits<std::uint64_t>::max();
  limits.max_node_count = std::numeric_limits<std::uint32_t>::max();
  limits.max_triangle_count = std::numeric_limits<std::uint32_t>::max();
  limits.max_mode_count = std::numeric_limits<std::uint32_t>::max();
  limits.max_surface_node_count = std::numeric_limits<std::uint32_t>::max();
  return limits;
}

core::Expected<void> ImageWriter::check_new_section(SectionId id, ElementType element_type,
                                                    std::uint64_t value_count, std::uint32_t rows,
                                                    std::uint32_t cols) const {
  const SectionDescriptor* descriptor = find_section_descriptor(static_cast<std::uint32_t>(id));
  if (descriptor == nullptr) {
    return core::make_error("section id " + std::to_string(static_cast<std::uint32_t>(id)) +
                            " is not part of format version 1");
  }
  const std::string name = section_label(id);
  if (id == SectionId::metadata) {
    return core::make_error(name + " is written from set_metadata(), not added as raw bytes");
  }
  if (!section_belongs_to(*descriptor, kind_)) {
    return core::make_error(name + " belongs to " + owners_text(*descriptor) +
                            " images, this writer builds a " + model_kind_name(kind_) + " image");
  }
  if (descriptor->element_type != element_type) {
    return core::make_error(name + " holds element type " +
                            std::to_string(static_cast<std::uint32_t>(descriptor->element_type)) +
                            " in the format, not " +
                            std::to_string(static_cast<std::uint32_t>(element_type)) +
                            " (1 = f32, 2 = u32, 3 = i32, 4 = u8)");
  }
  for (const Section& section : sections_) {
    if (section.id == id) return core::make_error(name + " was already added");
  }
  if (std::uint64_t{rows} * std::uint64_t{cols} != value_count) {
    return core::make_error(name + ": rows × cols = " + std::to_string(rows) + " × " +
                            std::to_string(cols) + " but " + std::to_string(value_count) +
                            " values were given");
  }
  return {};
}

core::Expected<void> ImageWriter::add_f32(SectionId id, std::span<const float> values,
                                          std::uint32_t rows, std::uint32_t cols) {
  if (auto ok = check_new_section(id, ElementType::f32, values.size(), rows, cols); !ok) return ok;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return core::make_error(section_label(id) + " " + element_position(i, cols) + " = " +
                              number(static_cast<double>(values[i])) + " is not finite");
    }
  }
  Section section{id, ElementType::f32, rows, cols, {}};
  append_bytes(section.bytes, values);
  sections_.push_back(std::move(section));
  return {};
}

core::Expected<void> ImageWriter::add_f32(SectionId id, std::span<const double> values,
                                          std::uint32_t rows, std::uint32_t cols) {
  if (auto ok = check_new_section(id, ElementType::f32, values.size(), rows, cols); !ok) return ok;
  constexpr double kLargestFloat = static_cast<double>(std::numeric_limits<float>::max());
  std::vector<float> converted(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double value = values[i];
    if (!std::isfinite(value)) {
      return core::make_error(section_label(id) + " " + element_position(i, cols) + " = " +
                              number(value) + " is not finite");
    }
    if (std::fabs(value) > kLargestFloat) {
      return core::make_error(section_label(id) + " " + element_position(i, cols) + " = " +
                              number(value) + " is outside the float32 range (±" +
                              number(kLargestFloat) + ")");
    }
    converted[i] = static_cast<float>(value);
  }
  Section section{id, ElementType::f32, rows, cols, {}};
  append_bytes(section.bytes, std::span<const float>(converted));
  sections_.push_back(std::move(section));
  return {};
}

namespace {

// Row-major copy of an Eigen matrix with its shape, refusing shapes a u32 cannot carry.
template <class Scalar>
core::Expected<std::vector<Scalar>> row_major_values(
    SectionId id,
    const Eigen::Ref<const Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>>& matrix) {
  constexpr auto kMaxDimension =
      static_cast<Eigen::Index>(std::numeric_limits<std::uint32_t>::max());
  if (matrix.rows() > kMaxDimension || matrix.cols() > kMaxDimension) {
    return core::make_error(section_label(id) + ": a " + std::to_string(matrix.rows()) + " × " +
                            std::to_string(matrix.cols()) +
                            " matrix does not fit the u32 rows/cols fields");
  }
  std::vector<Scalar> values(static_cast<std::size_t>(matrix.size()));
  std::size_t next = 0;
  for (Eigen::Index row = 0; row < matrix.rows(); ++row) {
    for (Eigen::Index col = 0; col < matrix.cols(); ++col) values[next++] = matrix(row, col);
  }
  return values;
}

}  // namespace

core::Expected<void> ImageWriter::add_f32(SectionId id,
                                          const Eigen::Ref<const Eigen::MatrixXd>& matrix) {
  auto values = row_major_values<double>(id, matrix);
  if (!values) return std::move(values).error();
  return add_f32(id, std::span<const double>(values.value()),
                 static_cast<std::uint32_t>(matrix.rows()),
                 static_cast<std::uint32_t>(matrix.cols()));
}

core::Expected<void> ImageWriter::add_f32(SectionId id,
                                          const Eigen::Ref<const Eigen::MatrixXf>& matrix) {
  auto values = row_major_values<float>(id, matrix);
  if (!values) return std::move(values).error();
  return add_f32(id, std::span<const float>(values.value()),
                 static_cast<std::uint32_t>(matrix.rows()),
                 static_cast<std::uint32_t>(matrix.cols()));
}

core::Expected<void> ImageWriter::add_u32(SectionId id, std::span<const std::uint32_t> values,
                                          std::uint32_t rows, std::uint32_t cols) {
  if (auto ok = check_new_section(id, ElementType::u32, values.size(), rows, cols); !ok) return ok;
  Section section{id, ElementType::u32, rows, cols, {}};
  append_bytes(section.bytes, values);
  sections_.push_back(std::move(section));
  return {};
}

core::Expected<void> ImageWriter::add_u32(SectionId id,
                                          const Eigen::Ref<const Eigen::MatrixXi>& matrix) {
  auto values = row_major_values<int>(id, matrix);
  if (!values) return std::move(values).error();
  const auto cols = static_cast<std::uint32_t>(matrix.cols());
  std::vector<std::uint32_t> unsigned_values(values.value().size());
  for (std::size_t i = 0; i < unsigned_values.size(); ++i) {
    const int value = values.value()[i];
    if (value < 0) {
      return core::make_error(section_label(id) + " " + element_position(i, cols) + " = " +
                              std::to_string(value) + " is negative, the section holds u32");
    }
    unsigned_values[i] = static_cast<std::uint32_t>(value);
  }
  return add_u32(id, std::span<const std::uint32_t>(unsigned_values),
                 static_cast<std::uint32_t>(matrix.rows()), cols);
}

core::Expected<void> ImageWriter::add_i32(SectionId id, std::span<const std::int32_t> values,
                                          std::uint32_t rows, std::uint32_t cols) {
  if (auto ok = check_new_section(id, ElementType::i32, values.size(), rows, cols); !ok) return ok;
  Section section{id, ElementType::i32, rows, cols, {}};
  append_bytes(section.bytes, values);
  sections_.push_back(std::move(section));
  return {};
}

core::Expected<void> ImageWriter::add_u8(SectionId id, std::span<const std::uint8_t> values,
                                         std::uint32_t rows, std::uint32_t cols) {
  if (auto ok = check_new_section(id, ElementType::u8, values.size(), rows, cols); !ok) return ok;
  Section section{id, ElementType::u8, rows, cols, {}};
  append_bytes(section.bytes, values);
  sections_.push_back(std::move(section));
  return {};
}

core::Expected<std::vector<std::byte>> ImageWriter::serialize(const ImageLimits& limits) const {
  if (!metadata_) {
    return core::make_error(
        "image writer: set_metadata() was not called (the metadata section "
        "is required)");
  }
  // The metadata record becomes section 1; the rest follow in ascending id order.
  std::vector<const Section*> ordered;
  Section metadata_section{SectionId::metadata,
                           ElementType::u8,
                           static_cast<std::uint32_t>(sizeof(ImageMetadataV1)),
                           1,
                           {}};
  metadata_section.bytes.resize(sizeof(ImageMetadataV1));
  std::memcpy(metadata_section.bytes.data(), &*metadata_, sizeof(ImageMetadataV1));
  ordered.push_back(&metadata_section);
  for (const Section& section : sections_) ordered.push_back(&section);
  std::sort(ordered.begin(), ordered.end(),
            [](const Section* a, const Section* b) { return a->id < b->id; });
  if (ordered.size() > kImageMaxSections) {
    return core::make_error("image writer: " + std::to_string(ordered.size()) +
                            " sections, the format holds at most " +
                            std::to_string(kImageMaxSections));
  }

  const auto section_count = static_cast<std::uint32_t>(ordered.size());
  const std::uint64_t table_end =
      std::uint64_t{kImageHeaderBytes} + std::uint64_t{section_count} * kImageSectionEntryBytes;
  std::vector<SectionEntryV1> entries;
  std::uint64_t cursor = table_end;
  std::uint64_t file_bytes = table_end;
  for (const Section* section : ordered) {
    SectionEntryV1 entry{};
    entry.id = static_cast<std::uint32_t>(section->id);
    entry.element_type = static_cast<std::uint32_t>(section->element_type);
    entry.offset = round_up(cursor, kImageSectionAlignment);
    entry.element_count = std::uint64_t{section->rows} * std::uint64_t{section->cols};
    entry.rows = section->rows;
    entry.cols = section->cols;
    cursor = entry.offset + section->bytes.size();
    file_bytes = std::max(file_bytes, cursor);
    entries.push_back(entry);
  }

  std::vector<std::byte> bytes(static_cast<std::size_t>(file_bytes), std::byte{0});
  ImageHeaderV1 header{};
  std::memcpy(header.magic, kImageMagic, sizeof kImageMagic);
  header.format_version = kImageFormatVersion;
  header.header_bytes = kImageHeaderBytes;
  header.byte_order_mark = kImageByteOrderMark;
  header.model_kind = static_cast<std::uint32_t>(kind_);
  header.file_bytes = file_bytes;
  header.section_count = section_count;
  header.section_table_offset = kImageHeaderBytes;
  header.checksum = 0;
  store_record(bytes, 0, header);
  for (std::size_t i = 0; i < ordered.size(); ++i) {
    store_record(bytes, kImageHeaderBytes + i * kImageSectionEntryBytes, entries[i]);
    if (!ordered[i]->bytes.empty()) {
      std::memcpy(bytes.data() + entries[i].offset, ordered[i]->bytes.data(),
                  ordered[i]->bytes.size());
    }
  }
  header.checksum = compute_image_checksum(bytes);
  store_record(bytes, 0, header);

  // Self-check with the runtime's parser: a consistency error (say, omega_squared shorter
  // than mode_count) surfaces here, at build time, instead of on the trainer.
  const AlignedBytes aligned = aligned_copy(bytes);
  auto parsed =
      parse_model_image({aligned.get(), bytes.size()}, "image being written", kind_, limits);
  if (!parsed) return std::move(parsed).error();
  return bytes;
}

core::Expected<void> ImageWriter::write(const std::filesystem::path& path,
                                        const ImageLimits& limits) const {
  auto bytes = serialize(limits);
  if (!bytes) {
    return core::make_error(path.string() + ": not written: " + bytes.error().message);
  }
  // Same directory as the target so rename() stays within one filesystem (atomic).
  const std::string temporary = path.string() + ".tmp." + std::to_string(::getpid());
  const int descriptor = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (descriptor < 0) {
    return core::make_error(temporary + ": cannot create the temporary file: " + errno_text(errno));
  }
  auto fail = [&](core::Error error) -> core::Expected<void> {
    ::close(descriptor);
    ::unlink(temporary.c_str());
    return error;
  };
  if (auto ok = write_all(descriptor, bytes.value(), temporary); !ok) {
    return fail(std::move(ok).error());
  }
  if (::fsync(descriptor) != 0) {
    return fail(core::make_error(temporary + ": fsync failed: " + errno_text(errno)));
  }
  if (::close(descriptor) != 0) {
    const int close_errno = errno;
    ::unlink(temporary.c_str());
    return core::make_error(temporary + ": close failed: " + errno_text(close_errno));
  }
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int rename_errno = errno;
    ::unlink(temporary.c_str());
    return core::make_error(path.string() + ": cannot rename " + temporary +
                            " over it: " + errno_text(rename_errno));
  }
  // Make the rename itself durable.
  const std::filesystem::path directory =
      path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const int directory_descriptor = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (directory_descriptor >= 0) {
    ::fsync(directory_descriptor);
    ::close(directory_descriptor);
  }
  return {};
}

}  // namespace trainer::model::offline
