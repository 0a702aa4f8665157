// Names, SystemFiles, CPU-list parsing and the human-readable report of the RT self-check.
#include "trainer/appliance/rt_check.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <system_error>

namespace trainer::appliance {

std::string_view to_string(RtCheckId id) noexcept {
  return kRtCheckNames[static_cast<std::size_t>(id)];
}

std::optional<RtCheckId> rt_check_from_name(std::string_view name) noexcept {
  for (std::size_t k = 0; k < kRtCheckNames.size(); ++k) {
    if (kRtCheckNames[k] == name) return static_cast<RtCheckId>(k);
  }
  return std::nullopt;
}

std::string_view to_string(RtOutcome outcome) noexcept {
  switch (outcome) {
    case RtOutcome::pass: return "pass";
    case RtOutcome::warn: return "warn";
    case RtOutcome::fail: return "fail";
  }
  return "?";
}

SystemFiles::SystemFiles(std::filesystem::path root) : root_(std::move(root)) {}

std::filesystem::path SystemFiles::map(std::string_view absolute) const {
  std::string_view relative = absolute;
  while (!relative.empty() && relative.front() == '/') relative.remove_prefix(1);
  return root_ / std::filesystem::path(relative);
}

// POSIX read until EOF: /proc and /sys files report size 0.
std::optional<std::string> SystemFiles::read(std::string_view absolute) const {
  const std::string path = map(absolute).string();
  const int descriptor = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (descriptor < 0) return std::nullopt;
  std::string contents;
  char buffer[4096];
  for (;;) {
    const ssize_t got = ::read(descriptor, buffer, sizeof buffer);
    if (got > 0) {
      contents.append(buffer, static_cast<std::size_t>(got));
    } else if (got == 0 || errno != EINTR) {
      break;
    }
  }
  close(descriptor);
  return contents;
}

std::vector<std::string> SystemFiles::list(std::string_view absolute) const {
  std::vector<std::string> names;
  std::error_code error;
  for (std::filesystem::directory_iterator it(map(absolute), error), end; !error && it != end;
       it.increment(error)) {
    names.push_back(it->path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

bool SystemFiles::exists(std::string_view absolute) const {
  std::error_code error;
  return std::filesystem::exists(map(absolute), error);
}

bool SystemFiles::writable(std::string_view absolute) const {
  return access(map(absolute).c_str(), W_OK) == 0;
}

std::string SystemFiles::resolve(std::string_view absolute) const {
  std::error_code error;
  const std::filesystem::path link = map(absolute);
  if (!std::filesystem::is_symlink(link, error)) return {};
  const std::filesystem::path target = std::filesystem::canonical(link, error);
  if (error) return {};
  const std::filesystem::path root = std::filesystem::canonical(root_, error);
  if (error) return {};
  const std::string text = target.string();
  const std::string prefix = root.string() == "/" ? std::string{} : root.string();
  return text.rfind(prefix, 0) == 0 ? text.substr(prefix.size()) : text;
}

std::optional<std::vector<int>> parse_cpu_list(std::string_view text) {
  std::vector<int> cpus;
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.remove_suffix(1);
  if (text.empty()) return cpus;
  const auto number = [](std::string_view part) -> std::optional<int> {
    int value = 0;
    const auto [end, error] = std::from_chars(part.data(), part.data() + part.size(), value);
    if (error != std::errc{} || end != part.data() + part.size() || value < 0) return std::nullopt;
    return value;
  };
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    text = comma == std::string_view::npos ? std::string_view{} : text.substr(comma + 1);
    const std::size_t dash = item.find('-');
    const auto first = number(item.substr(0, dash));
    const auto last = dash == std::string_view::npos ? first : number(item.substr(dash + 1));
    if (!first || !last || *last < *first || *last - *first > 65536) return std::nullopt;
    for (int cpu = *first; cpu <= *last; ++cpu) cpus.push_back(cpu);
  }
  return cpus;
}

std::string format_rt_check(const std::vector<RtCheckResult>& results) {
  std::string text = "RT self-check\n";
  std::size_t warnings = 0;
  std::size_t failures = 0;
  std::string fatal_names;
  for (const RtCheckResult& result : results) {
    std::string label(to_string(result.outcome));
    std::transform(label.begin(), label.end(), label.begin(),
                   [](char c) { return static_cast<char>(c - 'a' + 'A'); });
    if (result.fatal) label = "FATAL";
    std::string name(to_string(result.id));
    name.resize(std::max<std::size_t>(name.size(), 16), ' ');
    label.resize(6, ' ');
    text += "  " + label + name + result.detail + "\n";
    if (!result.fix.empty()) text += "        fix: " + result.fix + "\n";
    if (result.outcome == RtOutcome::warn) ++warnings;
    if (result.outcome == RtOutcome::fail) ++failures;
    if (result.fatal)
      fatal_names += (fatal_names.empty() ? "" : ", ") + name.substr(0, name.find(' '));
  }
  text +=
      "result: " + std::to_string(failures) + " failed, " + std::to_string(warnings) + " warned";
  text += fatal_names.empty() ? "; none of the scene's fatal checks failed\n"
                              : "; fatal (loop.rt_check_fatal): " + fatal_names + "\n";
  return text;
}

bool rt_check_failed(const std::vector<RtCheckResult>& results) noexcept {
  return std::any_of(results.begin(), results.end(),
                     [](const RtCheckResult& result) { return result.fatal; });
}

}  // namespace trainer::appliance
