// Test helpers for rt/config: a per-test temporary directory to write scene/device files into,
// the repository's config files as text, and text edits that report the line they touched so
// tests can assert "<file>:<line>:" without hard-coding line numbers of files that evolve.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>

namespace trainer::config::testing {

inline std::string read_text(const std::filesystem::path& path) {
  // Sized read: istreambuf_iterator trips GCC 12's -Wnull-dereference at -O3.
  std::error_code error_code;
  const auto size = std::filesystem::file_size(path, error_code);
  EXPECT_FALSE(error_code) << "cannot stat " << path;
  std::string text(error_code ? 0 : static_cast<std::size_t>(size), '\0');
  std::ifstream stream(path, std::ios::binary);
  stream.read(text.data(), static_cast<std::streamsize>(text.size()));
  EXPECT_EQ(stream.gcount(), static_cast<std::streamsize>(text.size())) << "cannot read " << path;
  return text;
}

inline std::filesystem::path repo_path(std::string_view relative) {
  return std::filesystem::path(TRAINER_SOURCE_DIR) / relative;
}

// A text with one substring replaced, and the 1-based line where the replacement starts.
struct Edited {
  std::string text;
  int line = 0;
};

inline int line_at(const std::string& text, std::size_t position) {
  int line = 1;
  for (std::size_t i = 0; i < position && i < text.size(); ++i) {
    if (text[i] == '\n') ++line;
  }
  return line;
}

// Replaces the first occurrence of `from` (which must exist: the edit is the point of the test).
inline Edited replace_first(const std::string& text, std::string_view from, std::string_view to) {
  const std::size_t position = text.find(from);
  EXPECT_NE(position, std::string::npos) << "test edit: '" << from << "' not in the text";
  if (position == std::string::npos) return {text, 0};
  std::string edited = text;
  edited.replace(position, from.size(), to);
  return {edited, line_at(edited, position)};
}

// Line of the first occurrence of `needle` (which must exist).
inline int line_of(const std::string& text, std::string_view needle) {
  const std::size_t position = text.find(needle);
  EXPECT_NE(position, std::string::npos) << "'" << needle << "' not in the text";
  return position == std::string::npos ? 0 : line_at(text, position);
}

// Fixture owning an empty temporary directory for the duration of one test.
class ConfigFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = std::filesystem::temp_directory_path() /
            ("trainer_config_test_" + std::to_string(::getpid()) + "_" +
             std::string(info->test_suite_name()) + "_" + std::string(info->name()));
    std::filesystem::remove_all(root_);
    std::filesystem::create_directories(root_);
  }
  void TearDown() override {
    std::error_code ignored;
    std::filesystem::remove_all(root_, ignored);
  }

  std::filesystem::path write(std::string_view relative, std::string_view content) const {
    const std::filesystem::path path = root_ / relative;
    std::filesystem::create_directories(path.parent_path());
    std::ofstream stream(path, std::ios::binary);
    stream << content;
    EXPECT_TRUE(stream.good()) << "cannot write " << path;
    return path;
  }

  std::filesystem::path root_;
};

// Prints the message when a substring is missing, so a failing test shows what it got.
inline void expect_contains(const std::string& message, std::string_view part) {
  EXPECT_NE(message.find(part), std::string::npos)
      << "message:  " << message << "\nexpected to contain: " << part;
}

}  // namespace trainer::config::testing
