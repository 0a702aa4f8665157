#include "table_reader.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <system_error>
#include <utility>

#include "value_text.hpp"

namespace trainer::config::detail {
namespace fs = std::filesystem;

namespace {

std::string with_unit(std::string_view unit) {
  if (unit.empty()) return "";
  return " (" + std::string(unit) + ")";
}

// "integer, microseconds" style detail for missing-key messages.
std::string kind_and_unit(std::string_view kind, std::string_view unit) {
  std::string text(kind);
  if (!unit.empty()) {
    text += ", ";
    text += unit;
  }
  return text;
}

std::uint32_t line_of(const toml::node& node) noexcept {
  return node.source().begin.line;
}

std::size_t edit_distance(std::string_view from, std::string_view to) {
  std::vector<std::size_t> previous(to.size() + 1);
  std::vector<std::size_t> current(to.size() + 1);
  for (std::size_t j = 0; j <= to.size(); ++j) previous[j] = j;
  for (std::size_t i = 1; i <= from.size(); ++i) {
    current[0] = i;
    for (std::size_t j = 1; j <= to.size(); ++j) {
      const std::size_t substitution = previous[j - 1] + (from[i - 1] == to[j - 1] ? 0U : 1U);
      current[j] = std::min({previous[j] + 1, current[j - 1] + 1, substitution});
    }
    std::swap(previous, current);
  }
  return previous[to.size()];
}

std::string join(const std::vector<std::string>& items) {
  std::string text;
  for (const auto& item : items) {
    if (!text.empty()) text += ", ";
    text += item;
  }
  return text;
}

std::string count_range_text(std::size_t min_count, std::size_t max_count) {
  if (min_count == max_count) return std::to_string(min_count);
  return std::to_string(min_count) + " to " + std::to_string(max_count);
}

}  // namespace

// ---------------------------------------------------------------- names

bool is_valid_name(std::string_view name) noexcept {
  const auto is_name_character = [](char character) {
    return (character >= 'a' && character <= 'z') || (character >= 'A' && character <= 'Z') ||
           (character >= '0' && character <= '9') || character == '_' || character == '-';
  };
  return !name.empty() && name.size() <= kMaxNameLength &&
         std::all_of(name.begin(), name.end(), is_name_character);
}

// ---------------------------------------------------------------- parsing

namespace {

SourceFile source_file_of(const fs::path& path) {
  SourceFile file;
  file.display_name = path.lexically_normal().string();
  std::error_code error_code;
  fs::path absolute = fs::absolute(path, error_code);
  if (error_code) absolute = path;
  file.absolute_path = absolute.lexically_normal();
  file.display_directory = path.lexically_normal().parent_path();
  file.absolute_directory = file.absolute_path.parent_path();
  return file;
}

core::Expected<ParsedFile> parse_toml_content(SourceFile file, std::string_view content) {
  ParsedFile parsed;
  parsed.file = std::move(file);
  try {
    parsed.root = toml::parse(content, std::string_view{parsed.file.display_name});
  } catch (const toml::parse_error& error) {
    return core::make_error(parsed.file.display_name + ":" +
                            std::to_string(error.source().begin.line) +
                            ": syntax error: " + std::string(error.description()));
  }
  return parsed;
}

}  // namespace

core::Expected<ParsedFile> parse_toml_file(const fs::path& path) {
  SourceFile file = source_file_of(path);
  std::error_code error_code;
  const auto status = fs::status(file.absolute_path, error_code);
  if (!fs::exists(status)) {
    return core::make_error(file.display_name + ": file not found (resolved to " +
                            file.absolute_path.string() + ")");
  }
  if (!fs::is_regular_file(status)) {
    return core::make_error(file.display_name + ": not a regular file (resolved to " +
                            file.absolute_path.string() + ")");
  }
  // Sized read rather than istreambuf_iterator, which trips GCC 12's -Wnull-dereference.
  const auto size = fs::file_size(file.absolute_path, error_code);
  std::ifstream stream(file.absolute_path, std::ios::binary);
  std::string content(error_code ? 0 : static_cast<std::size_t>(size), '\0');
  stream.read(content.data(), static_cast<std::streamsize>(content.size()));
  if (error_code || !stream.is_open() ||
      stream.gcount() != static_cast<std::streamsize>(content.size())) {
    return core::make_error(file.display_name + ": cannot read the file (resolved to " +
                            file.absolute_path.string() + ")");
  }
  return parse_toml_content(std::move(file), content);
}

core::Expected<ParsedFile> parse_toml_text(std::string_view content, const fs::path& path) {
  return parse_toml_content(source_file_of(path), content);
}

// ---------------------------------------------------------------- errors and ranges

void ErrorSink::report(std::string message) {
  if (!specific_) specific_ = std::move(message);
}

void ErrorSink::report_missing(std::string message) {
  if (!missing_) missing_ = std::move(message);
}

core::Error ErrorSink::error() const {
  if (specific_) return core::make_error(*specific_);
  if (missing_) return core::make_error(*missing_);
  return core::make_error("internal error: configuration error requested but none recorded");
}

bool RealRange::contains(double value) const noexcept {
  const bool above_min = min_exclusive ? value > min : value >= min;
  const bool below_max = max_exclusive ? value < max : value <= max;
  return above_min && below_max;
}

std::string RealRange::describe() const {
  if (!min_exclusive && !max_exclusive) return format_number(min) + " to " + format_number(max);
  const std::string low = (min_exclusive ? "more than " : "at least ") + format_number(min);
  const std::string high = (max_exclusive ? "less than " : "at most ") + format_number(max);
  return low + " and " + high;
}

// ---------------------------------------------------------------- TableReader basics

TableReader::TableReader(const SourceFile& file, ErrorSink& errors, const toml::table* table,
                         std::string prefix)
    : file_(&file), errors_(&errors), table_(table), prefix_(std::move(prefix)) {}

std::string TableReader::qualified(std::string_view key) const {
  if (prefix_.empty()) return std::string(key);
  return prefix_ + "." + std::string(key);
}

std::uint32_t TableReader::line(std::string_view key) const {
  if (table_ == nullptr) return 0;
  if (const toml::node* node = table_->get(key)) return line_of(*node);
  return line_of(*table_);
}

bool TableReader::has(std::string_view key) { return find(key) != nullptr; }

const toml::node* TableReader::find(std::string_view key) {
  if (std::find(known_keys_.begin(), known_keys_.end(), key) == known_keys_.end()) {
    known_keys_.emplace_back(key);
  }
  if (table_ == nullptr) return nullptr;
  return table_->get(key);
}

std::string TableReader::location(std::uint32_t line_number) const {
  if (line_number == 0) return file_->display_name + ": ";
  return file_->display_name + ":" + std::to_string(line_number) + ": ";
}

void TableReader::fail_at_node(std::string_view qualified_key, const toml::node& node,
                               std::string_view text) {
  errors_->report(location(line_of(node)) + std::string(qualified_key) + " = " +
                  format_value(node) + std::string(text));
}

void TableReader::fail_type(std::string_view qualified_key, const toml::node& node,
                            std::string_view expected) {
  fail_at_node(qualified_key, node,
               " has type " + std::string(type_name(node)) + ": expected " + std::string(expected));
}

void TableReader::fail_missing(std::string_view key, std::string_view expected) {
  errors_->report_missing(file_->display_name + ": missing required key '" + qualified(key) +
                          "' (" + std::string(expected) + ")");
}

void TableReader::fail_value(std::string_view key, std::string_view text) {
  if (table_ != nullptr) {
    if (const toml::node* node = table_->get(key)) {
      fail_at_node(qualified(key), *node, text);
      return;
    }
  }
  errors_->report(location(line(key)) + qualified(key) + std::string(text));
}

void TableReader::fail_item(const StringItem& item, std::string_view text) {
  errors_->report(location(item.line) + item.key + " = " + quote(item.value) + std::string(text));
}

// ---------------------------------------------------------------- numbers

std::int64_t TableReader::required_int(std::string_view key, IntRange range,
                                       std::string_view unit) {
  if (find(key) == nullptr) {
    fail_missing(key, kind_and_unit("integer", unit));
    return range.min;
  }
  return optional_int(key, range.min, range, unit);
}

std::int64_t TableReader::optional_int(std::string_view key, std::int64_t fallback, IntRange range,
                                       std::string_view unit) {
  const toml::node* node = find(key);
  if (node == nullptr) return fallback;
  const auto* integer = node->as_integer();
  if (integer == nullptr) {
    fail_type(qualified(key), *node, "integer" + with_unit(unit));
    return fallback;
  }
  const std::int64_t value = integer->get();
  if (value < range.min || value > range.max) {
    fail_at_node(qualified(key), *node,
                 " is out of range: expected " + std::to_string(range.min) + " to " +
                     std::to_string(range.max) + with_unit(unit));
    return fallback;
  }
  return value;
}

std::optional<double> TableReader::check_real(std::string_view qualified_key,
                                              const toml::node& node, RealRange range,
                                              std::string_view unit) {
  double value = 0.0;
  if (const auto* integer = node.as_integer()) {
    value = static_cast<double>(integer->get());
  } else if (const auto* floating = node.as_floating_point()) {
    value = floating->get();
  } else {
    fail_type(qualified_key, node, "number" + with_unit(unit));
    return std::nullopt;
  }
  if (!std::isfinite(value)) {
    fail_at_node(qualified_key, node,
                 " is not a finite number: expected " + range.describe() + with_unit(unit));
    return std::nullopt;
  }
  if (!range.contains(value)) {
    fail_at_node(qualified_key, node,
                 " is out of range: expected " + range.describe() + with_unit(unit));
    return std::nullopt;
  }
  return value;
}

double TableReader::required_double(std::string_view key, RealRange range, std::string_view unit) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, kind_and_unit("number", unit));
    return range.min;
  }
  return check_real(qualified(key), *node, range, unit).value_or(range.min);
}

double TableReader::optional_double(std::string_view key, double fallback, RealRange range,
                                    std::string_view unit) {
  const toml::node* node = find(key);
  if (node == nullptr) return fallback;
  return check_real(qualified(key), *node, range, unit).value_or(fallback);
}

// ---------------------------------------------------------------- booleans and strings

bool TableReader::required_bool(std::string_view key) {
  if (find(key) == nullptr) {
    fail_missing(key, "boolean, true or false");
    return false;
  }
  return optional_bool(key, false);
}

bool TableReader::optional_bool(std::string_view key, bool fallback) {
  const toml::node* node = find(key);
  if (node == nullptr) return fallback;
  if (const auto* boolean = node->as_boolean()) return boolean->get();
  fail_type(qualified(key), *node, "boolean (true or false)");
  return fallback;
}

std::string TableReader::required_string(std::string_view key, std::string_view meaning) {
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, kind_and_unit("string", meaning));
    return {};
  }
  const auto* text = node->as_string();
  if (text == nullptr) {
    fail_type(qualified(key), *node, "string" + with_unit(meaning));
    return {};
  }
  if (text->get().empty()) {
    fail_at_node(qualified(key), *node, ": expected a non-empty string" + with_unit(meaning));
    return {};
  }
  return text->get();
}

std::optional<std::string> TableReader::optional_string(std::string_view key,
                                                        std::string_view meaning) {
  if (find(key) == nullptr) return std::nullopt;
  return required_string(key, meaning);
}

std::string TableReader::required_name(std::string_view key) {
  const std::string expected_text = "a name of 1 to " + std::to_string(kMaxNameLength) +
                                    " characters from A-Z, a-z, 0-9, '_' and '-'";
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, "string, " + expected_text);
    return {};
  }
  const auto* text = node->as_string();
  if (text == nullptr) {
    fail_type(qualified(key), *node, "string (" + expected_text + ")");
    return {};
  }
  const std::string& name = text->get();
  if (!is_valid_name(name)) {
    fail_at_node(qualified(key), *node, ": expected " + expected_text);
    return {};
  }
  return name;
}

std::optional<std::size_t> TableReader::required_choice(std::string_view key,
                                                        std::span<const std::string_view> choices,
                                                        std::string_view note) {
  std::string choice_list;
  for (const auto choice : choices) {
    if (!choice_list.empty()) choice_list += ", ";
    choice_list += choice;
  }
  const std::string expected_text = "one of: " + choice_list + with_unit(note);
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, "string, " + expected_text);
    return std::nullopt;
  }
  const auto* text = node->as_string();
  if (text == nullptr) {
    fail_type(qualified(key), *node, "string, " + expected_text);
    return std::nullopt;
  }
  const auto found = std::find(choices.begin(), choices.end(), std::string_view{text->get()});
  if (found == choices.end()) {
    fail_at_node(qualified(key), *node, ": expected " + expected_text);
    return std::nullopt;
  }
  return static_cast<std::size_t>(std::distance(choices.begin(), found));
}

// ---------------------------------------------------------------- vectors

std::optional<Vec3> TableReader::read_vec3(std::string_view key, RealRange component_range,
                                           std::string_view unit) {
  const std::string expected_text = "an array of 3 numbers" + with_unit(unit);
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, kind_and_unit("array of 3 numbers", unit));
    return std::nullopt;
  }
  const auto* array = node->as_array();
  if (array == nullptr) {
    fail_type(qualified(key), *node, expected_text);
    return std::nullopt;
  }
  if (array->size() != 3) {
    fail_at_node(qualified(key), *node,
                 " has " + std::to_string(array->size()) + " elements: expected " + expected_text);
    return std::nullopt;
  }
  Vec3 vector{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto component = check_real(qualified(key) + "[" + std::to_string(i) + "]",
                                      *array->get(i), component_range, unit);
    if (!component) return std::nullopt;
    vector[i] = *component;
  }
  return vector;
}

Vec3 TableReader::required_vec3(std::string_view key, RealRange component_range,
                                std::string_view unit) {
  return read_vec3(key, component_range, unit).value_or(Vec3{});
}

Vec3 TableReader::optional_vec3(std::string_view key, const Vec3& fallback,
                                RealRange component_range, std::string_view unit) {
  if (find(key) == nullptr) return fallback;
  return read_vec3(key, component_range, unit).value_or(fallback);
}

Vec3 TableReader::required_direction(std::string_view key) {
  // Components are bounded so the length cannot overflow; only the direction matters.
  constexpr RealRange kComponentRange = RealRange::closed(-1e6, 1e6);
  const auto read = read_vec3(key, kComponentRange, "direction, any length, normalised on load");
  if (!read) return {};
  Vec3 vector = *read;
  const double length =
      std::sqrt(vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2]);
  if (length < kMinDirectionLength) {
    fail_value(key, " is a zero vector: expected a direction of length at least " +
                        format_number(kMinDirectionLength) + " (it is normalised on load)");
    return {};
  }
  for (double& component : vector) component /= length;
  return vector;
}

std::vector<double> TableReader::required_double_array(std::string_view key,
                                                      std::size_t min_count,
                                                      std::size_t max_count,
                                                      RealRange element_range,
                                                      std::string_view unit) {
  const std::string expected_text =
      "an array of " + count_range_text(min_count, max_count) + " numbers" + with_unit(unit);
  const toml::node* node = find(key);
  if (node == nullptr) {
    fail_missing(key, expected_text);
    return {};
  }
  const auto* array = node->as_array();
  if (array == nullptr) {
    fail_type(qualified(key), *node, expected_text);
    return {};
  }
  if (array->size() < min_count || array->size() > max_count) {
    fail_at_node(qualified(key), *node,
                 " has " + std::to_string(array->size()) + " elements: expected " + expected_text);
    return {};
  }
  std::vector<double> values;
  for (std::size_t i = 0; i < array->size(); ++i) {
    const auto value = check_real(qualified(key) + "[" + std::to_string(i) + "]", *array->get(i),
                                  element_range, unit);
    if (!value) return {};
    values.push_back(*value);
  }
  return values;
}

std::optional<std::vector<StringItem>> TableReader::optional_string_array(
    std::string_view key, std::size_t min_count, std::size_t max_count, std::string_view meaning) {
  const toml::node* node = find(key);
  if (node == nullptr) return std::nullopt;
  const std::string expected_text =
      "an array of " + count_range_text(min_count, max_count) + " strings" + with_unit(meaning);
  const auto* array = node->as_array();
  if (array == nullptr) {
    fail_type(qualified(key), *node, expected_text);
    return std::vector<StringItem>{};
  }
  if (array->size() < min_count || array->size() > max_count) {
    fail_at_node(qualified(key), *node,
                 " has " + std::to_string(array->size()) + " elements: expected " + expected_text);
    return std::vector<StringItem>{};
  }
  std::vector<StringItem> items;
  for (std::size_t i = 0; i < array->size(); ++i) {
    const toml::node& element = *array->get(i);
    const std::string element_key = qualified(key) + "[" + std::to_string(i) + "]";
    const auto* text = element.as_string();
    if (text == nullptr) {
      fail_type(element_key, element, "string" + with_unit(meaning));
      return std::vector<StringItem>{};
    }
    items.push_back(StringItem{text->get(), element_key, line_of(element)});
  }
  return items;
}

// ---------------------------------------------------------------- paths

fs::path TableReader::resolve(std::string_view written, fs::path* display_path) const {
  const fs::path relative{written};
  if (display_path != nullptr) {
    *display_path = (file_->display_directory / relative).lexically_normal();
  }
  return (file_->absolute_directory / relative).lexically_normal();
}

fs::path TableReader::required_file(std::string_view key, bool must_exist, fs::path* display_path) {
  const std::string written = required_string(key, "path relative to this file's directory");
  if (written.empty()) return {};
  return check_file(key, written, must_exist, display_path);
}

fs::path TableReader::check_file(std::string_view key, std::string_view written, bool must_exist,
                                 fs::path* display_path) {
  fs::path absolute = resolve(written, display_path);
  if (!must_exist) return absolute;
  std::error_code error_code;
  const auto status = fs::status(absolute, error_code);
  const std::string where =
      location(line(key)) + qualified(key) + ": file '" + std::string(written) + "' ";
  if (!fs::exists(status)) {
    errors_->report(where + "not found (resolved to " + absolute.string() + ")");
    return {};
  }
  if (!fs::is_regular_file(status)) {
    errors_->report(where + "is not a regular file (resolved to " + absolute.string() + ")");
    return {};
  }
  return absolute;
}

// ---------------------------------------------------------------- tables

TableReader TableReader::required_table(std::string_view key) {
  if (find(key) == nullptr) {
    fail_missing(key, "table [" + qualified(key) + "]");
    return TableReader(*file_, *errors_, nullptr, qualified(key));
  }
  return optional_table(key);
}

TableReader TableReader::optional_table(std::string_view key) {
  const toml::node* node = find(key);
  if (node == nullptr) return TableReader(*file_, *errors_, nullptr, qualified(key));
  const auto* table = node->as_table();
  if (table == nullptr) {
    fail_type(qualified(key), *node, "table [" + qualified(key) + "]");
  }
  return TableReader(*file_, *errors_, table, qualified(key));
}

std::vector<TableReader> TableReader::array_of_tables(std::string_view key, std::size_t min_count,
                                                      std::size_t max_count,
                                                      std::string_view meaning) {
  const std::string count_text =
      count_range_text(min_count, max_count) + " " + std::string(meaning);
  const std::string expected_text = "array of tables [[" + qualified(key) + "]], " + count_text;
  std::vector<TableReader> readers;
  const toml::node* node = find(key);
  if (node == nullptr) {
    if (min_count > 0) fail_missing(key, expected_text);
    return readers;
  }
  const auto* array = node->as_array();
  if (array == nullptr) {
    fail_type(qualified(key), *node, expected_text);
    return readers;
  }
  for (std::size_t i = 0; i < array->size(); ++i) {
    const toml::node& element = *array->get(i);
    const std::string element_key = qualified(key) + "[" + std::to_string(i) + "]";
    if (i == max_count) {
      errors_->report(location(line_of(element)) + element_key + ": too many " +
                      std::string(meaning) + " (" + std::to_string(array->size()) + "): expected " +
                      count_text);
      return {};
    }
    const auto* table = element.as_table();
    if (table == nullptr) {
      fail_type(element_key, element, "table (an entry of " + expected_text + ")");
      return {};
    }
    readers.emplace_back(*file_, *errors_, table, element_key);
  }
  if (readers.size() < min_count) {
    fail_at_node(qualified(key), *node,
                 " has " + std::to_string(readers.size()) + " elements: expected " + count_text);
    return {};
  }
  return readers;
}

// ---------------------------------------------------------------- unknown keys

void TableReader::finish() {
  if (table_ == nullptr) return;
  const toml::key* first_unknown = nullptr;
  for (auto&& [key, node] : *table_) {
    (void)node;
    const bool known =
        std::find(known_keys_.begin(), known_keys_.end(), key.str()) != known_keys_.end();
    if (known) continue;
    if (first_unknown == nullptr || key.source().begin.line < first_unknown->source().begin.line) {
      first_unknown = &key;
    }
  }
  if (first_unknown == nullptr) return;

  std::string message = location(first_unknown->source().begin.line) + "unknown key '" +
                        qualified(first_unknown->str()) + "' (known: " + join(known_keys_) + ")";
  // Suggest the closest known key when it is plausibly a typo of it.
  const std::string_view unknown = first_unknown->str();
  const std::string* closest = nullptr;
  std::size_t closest_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& known : known_keys_) {
    const std::size_t distance = edit_distance(unknown, known);
    if (distance < closest_distance) {
      closest_distance = distance;
      closest = &known;
    }
  }
  const std::size_t typo_limit =
      std::max<std::size_t>(1, std::min<std::size_t>(3, unknown.size() / 3));
  if (closest != nullptr && closest_distance <= typo_limit) {
    message += "; did you mean '" + *closest + "'?";
  }
  errors_->report(std::move(message));
}

}  // namespace trainer::config::detail
