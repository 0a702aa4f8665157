#include "trainer/hil/device_edit.hpp"

#include <algorithm>
#include <optional>

namespace trainer::hil {

namespace {

std::vector<std::string> split_lines(std::string_view text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) {
      lines.emplace_back(text.substr(start));
      break;
    }
    lines.emplace_back(text.substr(start, end - start));
    start = end + 1;
  }
  return lines;
}

std::string_view trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r'))
    text.remove_suffix(1);
  return text;
}

// "[instrument.pitch]" -> "instrument.pitch"; "[[instrument]]" -> "[instrument]" (array);
// nullopt for other lines.
std::optional<std::string> header_of(std::string_view line) {
  std::string_view t = trim(line);
  if (t.empty() || t.front() != '[') return std::nullopt;
  const std::size_t hash = t.find('#');
  if (hash != std::string_view::npos) t = trim(t.substr(0, hash));
  if (t.size() >= 4 && t.substr(0, 2) == "[[" && t.substr(t.size() - 2) == "]]") {
    return "[" + std::string(trim(t.substr(2, t.size() - 4))) + "]";
  }
  if (t.size() >= 2 && t.back() == ']') return std::string(trim(t.substr(1, t.size() - 2)));
  return std::nullopt;
}

struct KeyLine {
  std::string key;
  std::size_t value_begin = 0;  // in the line
  std::size_t value_end = 0;    // one past the value (before spaces and the comment)
};

// `key = value  # comment` with a one-line value; nullopt for anything else.
std::optional<KeyLine> key_line(std::string_view line) {
  std::size_t i = 0;
  while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
  const std::size_t key_begin = i;
  while (i < line.size() && (std::isalnum(static_cast<unsigned char>(line[i])) != 0 ||
                             line[i] == '_' || line[i] == '-')) {
    ++i;
  }
  if (i == key_begin) return std::nullopt;
  KeyLine out;
  out.key = std::string(line.substr(key_begin, i - key_begin));
  while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
  if (i >= line.size() || line[i] != '=') return std::nullopt;
  ++i;
  while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
  out.value_begin = i;
  bool in_string = false;
  std::size_t end = i;
  for (; end < line.size(); ++end) {
    const char c = line[end];
    if (c == '"') in_string = !in_string;
    if (c == '#' && !in_string) break;
  }
  while (end > out.value_begin && (line[end - 1] == ' ' || line[end - 1] == '\t' ||
                                   line[end - 1] == '\r')) {
    --end;
  }
  out.value_end = end;
  return out;
}

bool multi_line_value(std::string_view value) {
  if (value.starts_with("\"\"\"") || value.starts_with("'''")) return true;
  if (value.starts_with("[")) return std::count(value.begin(), value.end(), '[') !=
                                     std::count(value.begin(), value.end(), ']');
  return value.empty();
}

std::string where(std::string_view file_name, const Correction& c) {
  std::string text = std::string(file_name) + ": [" + c.table + "]";
  if (!c.instrument.empty()) text += " of instrument \"" + c.instrument + "\"";
  return text;
}

// The line range [begin, end) of the table a correction names.
core::Expected<std::pair<std::size_t, std::size_t>> find_table(const std::vector<std::string>& lines,
                                                               std::string_view file_name,
                                                               const Correction& c) {
  std::optional<std::size_t> block_begin;
  std::size_t block_end = lines.size();
  if (!c.instrument.empty()) {
    // The [[instrument]] block whose `name` is the instrument.
    for (std::size_t i = 0; i < lines.size() && !block_begin; ++i) {
      if (header_of(lines[i]) != std::optional<std::string>("[instrument]")) continue;
      for (std::size_t j = i + 1; j < lines.size() && !header_of(lines[j]); ++j) {
        const auto key = key_line(lines[j]);
        if (!key || key->key != "name") continue;
        const std::string_view value(lines[j].data() + key->value_begin,
                                     key->value_end - key->value_begin);
        if (value == "\"" + c.instrument + "\"") block_begin = i;
      }
    }
    if (!block_begin) {
      return core::make_error(where(file_name, c) + ": the file has no [[instrument]] named \"" +
                              c.instrument + "\": correction of " + c.key + " refused");
    }
    for (std::size_t i = *block_begin + 1; i < lines.size(); ++i) {
      if (header_of(lines[i]) == std::optional<std::string>("[instrument]")) {
        block_end = i;
        break;
      }
    }
  }
  const std::size_t search_begin = block_begin.value_or(0);
  for (std::size_t i = search_begin; i < block_end; ++i) {
    if (header_of(lines[i]) != std::optional<std::string>(c.table)) continue;
    std::size_t end = i + 1;
    while (end < block_end && !header_of(lines[end])) ++end;
    return std::pair{i + 1, end};
  }
  return core::make_error(where(file_name, c) + ": the file has no such table: correction of " +
                          c.key + " refused");
}

}  // namespace

std::string LineChange::describe(std::string_view file_name) const {
  std::string text = std::string(file_name) + ":" + std::to_string(line) + ": ";
  if (correction != nullptr) {
    text += "[" + correction->table + "]";
    if (!correction->instrument.empty()) text += " of \"" + correction->instrument + "\"";
    text += " " + correction->key + " " +
            (correction->old_value.empty() ? "(absent)" : correction->old_value) + " -> " +
            correction->new_value;
    if (!correction->why.empty()) text += " (" + correction->why + ")";
  }
  return text;
}

core::Expected<EditedFile> apply_corrections(std::string_view text, std::string_view file_name,
                                             std::span<const Correction> corrections) {
  for (std::size_t i = 0; i < corrections.size(); ++i) {
    for (std::size_t j = i + 1; j < corrections.size(); ++j) {
      const Correction& a = corrections[i];
      const Correction& b = corrections[j];
      if (a.table == b.table && a.instrument == b.instrument && a.key == b.key &&
          a.new_value != b.new_value) {
        return core::make_error(where(file_name, a) + ": " + a.key + " corrected to both " +
                                a.new_value + " and " + b.new_value + ": refused");
      }
    }
  }
  std::vector<std::string> lines = split_lines(text);
  const bool trailing_newline = !text.empty() && text.back() == '\n';
  EditedFile edited;
  for (const Correction& c : corrections) {
    auto table = find_table(lines, file_name, c);
    if (!table) return std::move(table).error();
    const auto [begin, end] = *table;
    std::optional<std::size_t> at;
    std::size_t last_key = begin - 1;  // the header
    for (std::size_t i = begin; i < end; ++i) {
      const auto key = key_line(lines[i]);
      if (!key) continue;
      last_key = i;
      if (key->key == c.key) at = i;
    }
    LineChange change;
    change.correction = &c;
    if (at) {
      std::string& line = lines[*at];
      const auto key = key_line(line);
      const std::string old_value = line.substr(key->value_begin, key->value_end - key->value_begin);
      if (multi_line_value(old_value)) {
        return core::make_error(std::string(file_name) + ":" + std::to_string(*at + 1) + ": " +
                                c.key + " = " + old_value +
                                ": a value over several lines is not edited: refused");
      }
      change.before = line;
      // Keep the comment's column when the new value is not longer than the spaces allow.
      std::size_t spaces_end = key->value_end;
      while (spaces_end < line.size() && (line[spaces_end] == ' ' || line[spaces_end] == '\t'))
        ++spaces_end;
      const std::string rest = line.substr(spaces_end);
      std::string updated = line.substr(0, key->value_begin) + c.new_value;
      if (!rest.empty()) {
        const std::size_t column = spaces_end;
        updated += std::string(updated.size() + 1 <= column ? column - updated.size() : 1, ' ');
        updated += rest;
      } else {
        updated += line.substr(key->value_end);  // trailing spaces as they were
      }
      line = updated;
      change.after = line;
      change.line = *at + 1;
    } else {
      const std::string line = c.key + " = " + c.new_value;
      lines.insert(lines.begin() + static_cast<std::ptrdiff_t>(last_key + 1), line);
      change.inserted = true;
      change.after = line;
      change.line = last_key + 2;
      // Later changes' lines move down by one.
      for (LineChange& earlier : edited.changes) {
        if (earlier.line >= change.line) ++earlier.line;
      }
    }
    edited.changes.push_back(std::move(change));
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    edited.text += lines[i];
    if (i + 1 < lines.size() || trailing_newline) edited.text += '\n';
  }
  return edited;
}

}  // namespace trainer::hil
