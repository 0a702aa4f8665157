// Private to model/runtime: the pieces every model kind's image checks share — the message
// helpers (error path only: they allocate), reading a record out of the image bytes, and the
// row-count check — so the loader (image_loader.cpp) and the per-kind checks
// (catheter_image_checks.cpp) word their refusals the same way: "<file>: <field> ...".
#pragma once

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "trainer/core/expected.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model::detail {

inline core::Error image_error(std::string_view label, const std::string& what) {
  return core::make_error(std::string(label) + ": " + what);
}

// Shortest text that reads back to the same value ("0.0005", not "0.000500000024"), so a
// float in a message looks like the number that was written.
template <class T>
std::string number(T value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

inline std::string section_label(std::uint32_t id) {
  const SectionDescriptor* descriptor = find_section_descriptor(id);
  return descriptor != nullptr ? std::string("section '") + descriptor->name + "'"
                               : "section id " + std::to_string(id);
}

inline std::string section_label(SectionId id) {
  return section_label(static_cast<std::uint32_t>(id));
}

// A plain record copied out of the image (sections are aligned, records' fields may not be).
template <class T>
T read_record(const std::byte* source) noexcept {
  T value;
  std::memcpy(&value, source, sizeof value);
  return value;
}

inline core::Expected<void> require_rows(const ModelImage& image, SectionId id, std::uint64_t rows,
                                         const char* meaning, std::string_view label) {
  if (image.rows(id) != rows) {
    return image_error(label, section_label(id) + " has " + std::to_string(image.rows(id)) +
                                  " rows, expected " + std::to_string(rows) + " (" + meaning + ")");
  }
  return {};
}

}  // namespace trainer::model::detail
