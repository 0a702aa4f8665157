#include "value_text.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <sstream>
#include <system_error>

namespace trainer::config::detail {
namespace {

// Arrays longer than this are shown as "[a, b, c, d, ...]" in messages.
constexpr std::size_t kMaxArrayElementsShown = 4;

// Integral doubles below this magnitude are printed without exponent; above it the
// shortest form is clearer than a run of digits.
constexpr double kLargestPlainInteger = 1e15;

std::string shortest(double value) {
  std::array<char, 64> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  if (result.ec != std::errc{}) return "?";
  return std::string(buffer.data(), result.ptr);
}

std::string format_float(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::string text = shortest(value);
  // TOML spells a float with a fraction or an exponent; keep it visibly a float so a message
  // like "has type float: expected integer" makes sense next to the value.
  if (text.find_first_of(".e") == std::string::npos) text += ".0";
  return text;
}

}  // namespace

std::string format_number(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  if (std::trunc(value) == value && std::fabs(value) < kLargestPlainInteger) {
    return std::to_string(static_cast<long long>(value));
  }
  return shortest(value);
}

std::string format_significant(double value) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.3g", value);
  return buffer.data();
}

std::string quote(std::string_view text) {
  std::string quoted = "\"";
  for (const char character : text) {
    switch (character) {
      case '"': quoted += "\\\""; break;
      case '\\': quoted += "\\\\"; break;
      case '\n': quoted += "\\n"; break;
      case '\t': quoted += "\\t"; break;
      default:
        if (static_cast<unsigned char>(character) < 0x20U) {
          std::array<char, 8> escaped{};
          std::snprintf(escaped.data(), escaped.size(), "\\u%04x",
                        static_cast<unsigned>(static_cast<unsigned char>(character)));
          quoted += escaped.data();
        } else {
          quoted += character;
        }
    }
  }
  quoted += '"';
  return quoted;
}

std::string_view type_name(const toml::node& node) noexcept {
  switch (node.type()) {
    case toml::node_type::table: return "table";
    case toml::node_type::array: return "array";
    case toml::node_type::string: return "string";
    case toml::node_type::integer: return "integer";
    case toml::node_type::floating_point: return "float";
    case toml::node_type::boolean: return "boolean";
    case toml::node_type::date: return "date";
    case toml::node_type::time: return "time";
    case toml::node_type::date_time: return "date-time";
    case toml::node_type::none: break;
  }
  return "none";
}

std::string format_value(const toml::node& node) {
  if (const auto* integer = node.as_integer()) return std::to_string(integer->get());
  if (const auto* floating = node.as_floating_point()) return format_float(floating->get());
  if (const auto* text = node.as_string()) return quote(text->get());
  if (const auto* boolean = node.as_boolean()) return boolean->get() ? "true" : "false";
  if (node.is_table()) return "{...}";
  if (const auto* array = node.as_array()) {
    std::string text = "[";
    for (std::size_t i = 0; i < array->size(); ++i) {
      if (i > 0) text += ", ";
      if (i == kMaxArrayElementsShown) {
        text += "...";
        break;
      }
      text += format_value(*array->get(i));
    }
    return text + "]";
  }
  // Dates and times: let toml++ spell them as they appear in a file.
  std::ostringstream stream;
  if (const auto* date = node.as_date()) stream << date->get();
  if (const auto* time = node.as_time()) stream << time->get();
  if (const auto* date_time = node.as_date_time()) stream << date_time->get();
  return stream.str();
}

}  // namespace trainer::config::detail
