// The schema reader every configuration loader is written with. A TableReader wraps one TOML
// table of one file and reads typed keys from it, each with its range and unit text; every
// key it is asked for becomes "known", and finish() reports any other key as a typo. Errors go
// to an ErrorSink that keeps the most specific first error, so a loader reads a whole table
// without checking after every key and still reports one precise message:
//
//   TableReader loop = root.required_table("loop");
//   config.loop.period_ns = loop.required_int("period_us", {50, 100000}, "microseconds") * 1000;
//   config.loop.lock_memory = loop.optional_bool("lock_memory", false);
//   loop.finish();
//
// A read that fails returns a harmless default (0, "", an empty vector) and records the error;
// checks across keys should run only while errors.ok(), so a value that defaulted after a
// failure never produces a second, misleading message.
//
// Setup path: allocates, may see toml++ exceptions only inside parse_toml_file()/parse_toml_text().
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "trainer/config/device.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::config::detail {

// Names that other keys refer to (instruments, objects, builtin scripts): 1..kMaxNameLength
// characters from [A-Za-z0-9_-], so they can also serve in signal paths and file names.
inline constexpr std::size_t kMaxNameLength = 32;
bool is_valid_name(std::string_view name) noexcept;

// The file being read: how messages name it and where its relative paths start.
struct SourceFile {
  std::string display_name;                  // the path as the caller gave it, lexically normal
  std::filesystem::path absolute_path;       // absolute, lexically normal
  std::filesystem::path display_directory;   // parent of the display path (for display of paths)
  std::filesystem::path absolute_directory;  // relative paths inside the file start here
};

struct ParsedFile {
  SourceFile file;
  toml::table root;
};

// Reads and parses a TOML file. Errors: "<file>: file not found (resolved to <abs>)",
// "<file>: cannot read ...", "<file>:<line>: syntax error: <toml++ description>".
core::Expected<ParsedFile> parse_toml_file(const std::filesystem::path& path);
// The same for text already in memory, read as if it were the file `path` (which names it in
// messages and anchors its relative paths; it need not exist). parse_toml_file reads the file
// and ends here, so both parse alike.
core::Expected<ParsedFile> parse_toml_text(std::string_view content,
                                           const std::filesystem::path& path);

// Keeps the first error, except that a missing required key yields to any later error at a
// specific value or key: a typo such as `perod_us` makes `period_us` missing first, and the
// message worth showing is the unknown key at its line.
class ErrorSink {
 public:
  void report(std::string message);
  void report_missing(std::string message);
  bool ok() const noexcept { return !specific_ && !missing_; }
  // The error to show; call only when !ok().
  core::Error error() const;

 private:
  std::optional<std::string> specific_;
  std::optional<std::string> missing_;
};

// A real interval with open or closed ends, and how it is spelled in messages.
struct RealRange {
  double min = 0.0;
  double max = 0.0;
  bool min_exclusive = false;
  bool max_exclusive = false;

  static constexpr RealRange closed(double low, double high) { return {low, high, false, false}; }
  // (low, high]: for quantities that must be positive, e.g. a stiffness or a length.
  static constexpr RealRange left_open(double low, double high) { return {low, high, true, false}; }

  bool contains(double value) const noexcept;
  std::string describe() const;  // "50 to 100000", "more than 0 and at most 100"
};

struct IntRange {  // inclusive
  std::int64_t min = 0;
  std::int64_t max = 0;
};

// One string of a string array, with where it came from, for checks made after reading.
struct StringItem {
  std::string value;
  std::string key;  // qualified, e.g. "object[1].touched_by[0]"
  std::uint32_t line = 0;
};

class TableReader {
 public:
  // `table` may be null (an absent optional table): optional keys then give their defaults and
  // required keys report themselves missing. `prefix` is the qualified name of this table
  // ("loop", "instrument[0].pitch"); "" for the root.
  TableReader(const SourceFile& file, ErrorSink& errors, const toml::table* table,
              std::string prefix);

  const std::string& prefix() const noexcept { return prefix_; }
  bool present() const noexcept { return table_ != nullptr; }
  // Whether `key` is written in this table (it then counts as known for finish()).
  bool has(std::string_view key);
  // "prefix.key" (or "key" at the root): how messages name a key of this table.
  std::string qualified(std::string_view key) const;
  // Line of the key's value, of this table when the key is absent, 0 when unknown.
  std::uint32_t line(std::string_view key) const;

  // Numbers. Integer keys refuse floats; real keys accept integers. Non-finite reals (TOML
  // nan/inf) are refused. `unit` is spelled out in messages: "(microseconds)".
  std::int64_t required_int(std::string_view key, IntRange range, std::string_view unit);
  std::int64_t optional_int(std::string_view key, std::int64_t fallback, IntRange range,
                            std::string_view unit);
  double required_double(std::string_view key, RealRange range, std::string_view unit);
  double optional_double(std::string_view key, double fallback, RealRange range,
                         std::string_view unit);

  bool required_bool(std::string_view key);
  bool optional_bool(std::string_view key, bool fallback);

  // A non-empty string; `meaning` says what it is in the missing-key message.
  std::string required_string(std::string_view key, std::string_view meaning);
  // nullopt when absent; otherwise as required_string ("" after an error).
  std::optional<std::string> optional_string(std::string_view key, std::string_view meaning);
  // A name that others refer to: 1..32 characters from [A-Za-z0-9_-].
  std::string required_name(std::string_view key);
  // One of `choices`; returns its index. `note` is appended to the "expected one of" text.
  std::optional<std::size_t> required_choice(std::string_view key,
                                             std::span<const std::string_view> choices,
                                             std::string_view note = {});

  // Three numbers, each finite and within `component_range`.
  Vec3 required_vec3(std::string_view key, RealRange component_range, std::string_view unit);
  // The same, or `fallback` when the key is absent.
  Vec3 optional_vec3(std::string_view key, const Vec3& fallback, RealRange component_range,
                     std::string_view unit);
  // Three numbers with length >= kMinDirectionLength, returned normalised to unit length.
  Vec3 required_direction(std::string_view key);
  // An array of min_count..max_count numbers, each in `element_range`.
  std::vector<double> required_double_array(std::string_view key, std::size_t min_count,
                                            std::size_t max_count, RealRange element_range,
                                            std::string_view unit);
  static constexpr double kMinDirectionLength = 1e-9;

  // An array of non-empty strings, at most `max_count`; nullopt when the key is absent.
  std::optional<std::vector<StringItem>> optional_string_array(std::string_view key,
                                                               std::size_t min_count,
                                                               std::size_t max_count,
                                                               std::string_view meaning);

  // A file path written relative to this file's directory (or absolute). `must_exist` makes a
  // missing file an error: "<key>: file '<as written>' not found (resolved to <abs>)".
  // Returns the absolute, lexically normal path; *display_path (if given) gets the path
  // relative to the caller's working directory as used for messages about that file.
  std::filesystem::path required_file(std::string_view key, bool must_exist,
                                      std::filesystem::path* display_path = nullptr);
  // The same check for a path string the caller has already read from `key`.
  std::filesystem::path check_file(std::string_view key, std::string_view written, bool must_exist,
                                   std::filesystem::path* display_path = nullptr);
  std::filesystem::path resolve(std::string_view written,
                                std::filesystem::path* display_path) const;

  // Sub-tables. An absent required table is reported missing; an absent optional one gives a
  // reader with no table. A key that is present but not a table is a type error.
  TableReader required_table(std::string_view key);
  TableReader optional_table(std::string_view key);
  // [[key]] entries, min_count..max_count of them; each reader is prefixed "key[i]".
  // `meaning` names the entries in messages ("instruments").
  std::vector<TableReader> array_of_tables(std::string_view key, std::size_t min_count,
                                           std::size_t max_count, std::string_view meaning);

  // Reports "<file>:<line>: <prefix.key> = <value> <text>" for a key of this table (for checks
  // across keys made after reading; the key must be present).
  void fail_value(std::string_view key, std::string_view text);
  // Reports "<file>:<line>: <item.key> = \"<item.value>\"<text>".
  void fail_item(const StringItem& item, std::string_view text);

  // Reports the first (by line) key of this table that no read asked for, listing the known
  // ones and the closest match. Call once after reading every key of the table.
  void finish();

 private:
  const toml::node* find(std::string_view key);    // marks the key known
  std::string location(std::uint32_t line) const;  // "<file>:<line>: " or "<file>: "
  void fail_at_node(std::string_view qualified_key, const toml::node& node, std::string_view text);
  void fail_type(std::string_view qualified_key, const toml::node& node, std::string_view expected);
  void fail_missing(std::string_view key, std::string_view expected);
  std::optional<Vec3> read_vec3(std::string_view key, RealRange component_range,
                                std::string_view unit);
  std::optional<double> check_real(std::string_view qualified_key, const toml::node& node,
                                   RealRange range, std::string_view unit);

  const SourceFile* file_;
  ErrorSink* errors_;
  const toml::table* table_;
  std::string prefix_;
  std::vector<std::string> known_keys_;
};

// A reader for the whole file (no prefix).
inline TableReader root_reader(const ParsedFile& parsed, ErrorSink& errors) {
  return TableReader(parsed.file, errors, &parsed.root, "");
}

}  // namespace trainer::config::detail
