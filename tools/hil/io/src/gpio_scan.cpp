// hil scan, GPIO: every chip in /dev and its lines through libgpiod 1.6, and the comparison with
// the device file's [gpio] table (docs/hil-io.md).
#include <gpiod.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

bool gpio_scan_digits(const std::string& text) {
  return !text.empty() && std::all_of(text.begin(), text.end(),
                                      [](char c) { return c >= '0' && c <= '9'; });
}

// gpiochip12 sorts after gpiochip2.
unsigned gpio_scan_chip_number(const std::string& name) {
  const std::string digits = name.substr(std::string("gpiochip").size());
  return gpio_scan_digits(digits) ? static_cast<unsigned>(std::stoul(digits)) : 0U;
}

std::string gpio_scan_chip_text(const GpioChipInfo& chip) {
  return chip.name + " '" + chip.label + "'";
}

std::string gpio_scan_line_text(const GpioChipInfo& chip, const GpioLineInfo& line) {
  std::string text = chip.name + ":" + std::to_string(line.offset);
  if (!line.name.empty()) text += " '" + line.name + "'";
  return text;
}

std::string gpio_scan_wanted(const config::GpioLineConfig& line) {
  return "chip '" + line.chip + "' line " +
         (line.line_name.empty() ? std::to_string(line.offset) : "'" + line.line_name + "'");
}

}  // namespace

std::vector<GpioChipInfo> list_gpio_chips(std::string* error) {
  std::vector<GpioChipInfo> chips;
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("gpiochip", 0) == 0 && gpio_scan_digits(name.substr(8))) names.push_back(name);
  }
  std::sort(names.begin(), names.end(), [](const std::string& a, const std::string& b) {
    return gpio_scan_chip_number(a) < gpio_scan_chip_number(b);
  });
  std::string errors;
  for (const std::string& name : names) {
    const std::string path = "/dev/" + name;
    gpiod_chip* chip = gpiod_chip_open(path.c_str());
    if (chip == nullptr) {
      errors += (errors.empty() ? "" : "; ") + path + ": " + std::strerror(errno);
      continue;
    }
    GpioChipInfo info;
    info.name = gpiod_chip_name(chip);
    info.label = gpiod_chip_label(chip);
    info.path = path;
    const unsigned count = gpiod_chip_num_lines(chip);
    for (unsigned offset = 0; offset < count; ++offset) {
      gpiod_line* line = gpiod_chip_get_line(chip, offset);
      if (line == nullptr) continue;
      GpioLineInfo l;
      l.offset = offset;
      if (const char* n = gpiod_line_name(line)) l.name = n;
      if (const char* c = gpiod_line_consumer(line)) l.consumer = c;
      l.used = gpiod_line_is_used(line);
      l.output = gpiod_line_direction(line) == GPIOD_LINE_DIRECTION_OUTPUT;
      l.active_low = gpiod_line_active_state(line) == GPIOD_LINE_ACTIVE_STATE_LOW;
      info.lines.push_back(std::move(l));
    }
    gpiod_chip_close(chip);
    chips.push_back(std::move(info));
  }
  if (error != nullptr) *error = errors;
  return chips;
}

std::string gpio_line_role(const config::DeviceConfig& device, const config::GpioLineConfig& line,
                           bool output) {
  const config::DigitalConfig& d = device.digital;
  if (!output && line.bit == d.estop_input_bit) return "estop";
  if (!output && line.bit == d.enable_input_bit) return "enable";
  if (output && line.bit == d.drive_enable_output_bit) return "drive_enable";
  if (output && line.bit == d.fault_lamp_output_bit) return "fault_lamp";
  return (output ? "output" : "input") + std::to_string(line.bit);
}

const GpioChipInfo* find_gpio_chip(const std::vector<GpioChipInfo>& chips, const std::string& text) {
  const bool by_name = text.rfind("gpiochip", 0) == 0 && gpio_scan_digits(text.substr(8));
  const bool by_path = !text.empty() && text.front() == '/';
  for (const GpioChipInfo& chip : chips) {
    if (by_path) {
      std::error_code ec;
      if (chip.path == text || std::filesystem::equivalent(chip.path, text, ec)) return &chip;
    } else if (by_name) {
      if (chip.name == text) return &chip;
    } else if (chip.label == text) {
      return &chip;
    }
  }
  return nullptr;
}

std::vector<StepResult> compare_gpio(const std::vector<GpioChipInfo>& chips,
                                     const config::DeviceConfig& device) {
  std::vector<StepResult> steps;
  // chip path + offset -> the key that named it first.
  std::map<std::pair<std::string, unsigned>, std::string> seen;
  std::string chip_list;
  for (const GpioChipInfo& chip : chips) {
    chip_list += (chip_list.empty() ? "" : ", ") + gpio_scan_chip_text(chip);
  }
  if (chip_list.empty()) chip_list = "none";
  auto one = [&](const config::GpioLineConfig& want, bool output) {
    StepResult step;
    const std::string role = gpio_line_role(device, want, output);
    step.id = "gpio.scan." + role;
    step.title = role + " (" + want.key + "): " + gpio_scan_wanted(want);
    step.details = {{"key", want.key}, {"chip", want.chip}, {"direction", output ? "output" : "input"}};
    if (want.line_name.empty()) {
      step.details["offset"] = want.offset;
    } else {
      step.details["line"] = want.line_name;
    }
    step.outcome = Outcome::fail;
    const GpioChipInfo* chip = find_gpio_chip(chips, want.chip);
    if (chip == nullptr) {
      step.reason = "no GPIO chip '" + want.chip + "' (chips on this system: " + chip_list + ")";
      steps.push_back(std::move(step));
      return;
    }
    const GpioLineInfo* line = nullptr;
    if (want.line_name.empty()) {
      if (want.offset < 0 || static_cast<std::size_t>(want.offset) >= chip->lines.size()) {
        step.reason = "offset " + std::to_string(want.offset) + " out of range: " +
                      gpio_scan_chip_text(*chip) + " has offsets 0.." +
                      std::to_string(chip->lines.empty() ? 0 : chip->lines.size() - 1);
        steps.push_back(std::move(step));
        return;
      }
      line = &chip->lines[static_cast<std::size_t>(want.offset)];
    } else {
      for (const GpioLineInfo& l : chip->lines) {
        if (l.name == want.line_name) {
          line = &l;
          break;
        }
      }
      if (line == nullptr) {
        step.reason = "no line named '" + want.line_name + "' on " + gpio_scan_chip_text(*chip);
        steps.push_back(std::move(step));
        return;
      }
    }
    step.details["found"] = gpio_scan_line_text(*chip, *line);
    const auto where = std::make_pair(chip->path, line->offset);
    if (const auto it = seen.find(where); it != seen.end()) {
      step.reason = gpio_scan_line_text(*chip, *line) + " is the same line as " + it->second;
      steps.push_back(std::move(step));
      return;
    }
    seen.emplace(where, want.key);
    const char* const dir = line->output ? "output" : "input";
    if (line->used) {
      const std::string who = line->consumer.empty() ? "(no consumer name)" : "'" + line->consumer + "'";
      step.reason = gpio_scan_line_text(*chip, *line) + " already used by " + who + " as an " + dir;
      if (line->output != output) {
        step.reason += std::string(": wrong direction, the device file wants an ") +
                       (output ? "output" : "input");
      } else if (line->consumer == device.gpio.consumer) {
        step.reason += " (the consumer name of this device file: is a trainer running?)";
      }
      steps.push_back(std::move(step));
      return;
    }
    step.outcome = Outcome::pass;
    step.reason = gpio_scan_line_text(*chip, *line) + " on " + gpio_scan_chip_text(*chip) +
                  ", free";
    if (line->output != output) {
      step.reason += std::string(", now an ") + dir + " (the trainer requests it as an " +
                     (output ? "output" : "input") + ")";
    }
    steps.push_back(std::move(step));
  };
  for (const auto& line : device.gpio.inputs) one(line, false);
  for (const auto& line : device.gpio.outputs) one(line, true);
  return steps;
}

ScanSection make_gpio_scan_section(const std::vector<GpioChipInfo>& chips,
                                   const std::optional<config::DeviceConfig>& device) {
  ScanSection section;
  section.part = "gpio";
  for (const GpioChipInfo& chip : chips) {
    ScanItem item;
    item.kind = "gpio_chip";
    item.name = chip.name;
    item.properties = {{"label", chip.label}, {"path", chip.path}, {"lines", chip.lines.size()}};
    section.found.push_back(std::move(item));
    for (const GpioLineInfo& line : chip.lines) {
      ScanItem l;
      l.kind = "gpio_line";
      l.name = gpio_scan_line_text(chip, line);
      l.properties = {{"chip", chip.name},      {"offset", line.offset},
                      {"name", line.name},      {"consumer", line.consumer},
                      {"used", line.used},      {"direction", line.output ? "output" : "input"},
                      {"active_low", line.active_low}};
      section.found.push_back(std::move(l));
    }
  }
  if (!device) return section;
  if (device->digital_io != config::DigitalIo::gpio) {
    StepResult step;
    step.id = "gpio.scan.device_file";
    step.title = "device file's GPIO lines";
    step.outcome = Outcome::skip;
    step.reason = device->source_path.string() +
                  " has no [gpio] table (digital_io is not \"gpio\"): nothing to compare";
    section.comparison.push_back(std::move(step));
    return section;
  }
  section.comparison = compare_gpio(chips, *device);
  return section;
}

ScanSection scan_gpio(const BenchContext& bench) {
  std::string error;
  const std::vector<GpioChipInfo> chips = list_gpio_chips(&error);
  ScanSection section = make_gpio_scan_section(chips, bench.device);
  if (!error.empty()) {
    StepResult step;
    step.id = "gpio.scan.chips";
    step.title = "GPIO chips readable";
    step.outcome = Outcome::fail;
    step.reason = "cannot open " + error + " (the user needs read/write access to /dev/gpiochip*)";
    section.comparison.insert(section.comparison.begin(), std::move(step));
  }
  return section;
}

}  // namespace trainer::hil
