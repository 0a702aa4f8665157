// LineIo over libgpiod 1.6 (the GPIO character device, uAPI v1).
//
// Inputs: one event request per line (v1 gives every event line its own descriptor), both
// edges, the descriptor set O_NONBLOCK. sample_input() reads the value (one ioctl on that
// descriptor) and then drains the queued events with read() until it would block: the kernel
// queues up to 16 events per line; a full queue only means "changed" all the more.
// Outputs: one request per (chip, flags) group, so one GPIOHANDLE_SET_LINE_VALUES ioctl per
// chip when a chip's outputs share active-low and bias.
#include <fcntl.h>
#include <gpiod.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <string>
#include <string_view>

#include "trainer/hal_gpiod/gpio_device.hpp"

namespace trainer::hal::gpiod {
namespace {

// gpiod_line_event_read_fd_multiple() reads at most this many per call (the kernel's queue).
constexpr unsigned kEventBatch = 16;
// Batches drained per input and read at most (the queue holds one batch; more means the line
// toggles faster than it can be read, which is "changed" already).
constexpr int kMaxEventBatches = 4;

std::string errno_text(int error) {
  return std::string(std::strerror(error));
}

int request_flags(const LineParams& line) {
  int flags = 0;
  if (line.active_low) flags |= GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW;
  switch (line.bias) {
    case Bias::as_is: break;
    case Bias::disable: flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_DISABLE; break;
    case Bias::pull_up: flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP; break;
    case Bias::pull_down: flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_DOWN; break;
  }
  return flags;
}

bool all_digits(std::string_view text) {
  if (text.empty()) return false;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
  }
  return true;
}

class GpiodLineIo final : public LineIo {
 public:
  ~GpiodLineIo() override { release(); }

  core::Expected<void> claim(std::span<const LineParams> lines,
                             std::string_view consumer) override {
    release();
    auto claimed = claim_all(lines, std::string(consumer));
    if (!claimed) release();
    return claimed;
  }

  ReturnCode sample_input(std::size_t index, bool& active, bool& changed) noexcept override {
    changed = false;
    active = false;
    if (index >= lines_.size() || lines_[index].line == nullptr || !lines_[index].input) {
      return ReturnCode::error;
    }
    Line& line = lines_[index];
    line.oldest_event_ns = 0;
    const int value = gpiod_line_get_value(line.line);
    if (value < 0) return ReturnCode::error;
    active = value != 0;
    std::array<gpiod_line_event, kEventBatch> events{};
    for (int batch = 0; batch < kMaxEventBatches; ++batch) {
      const int count =
          gpiod_line_event_read_fd_multiple(line.event_fd, events.data(), kEventBatch);
      if (count < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) break;
        return ReturnCode::error;
      }
      if (count > 0 && !changed) {
        // uAPI v1 timestamps are CLOCK_MONOTONIC since Linux 5.7 (REALTIME before).
        line.oldest_event_ns = static_cast<std::int64_t>(events[0].ts.tv_sec) * 1'000'000'000 +
                               static_cast<std::int64_t>(events[0].ts.tv_nsec);
      }
      if (count > 0) changed = true;
      if (count < static_cast<int>(kEventBatch)) break;
    }
    return ReturnCode::ok;
  }

  ReturnCode write_outputs(std::span<const std::uint8_t, kMaxLines> levels) noexcept override {
    ReturnCode result = ReturnCode::ok;
    for (std::size_t g = 0; g < group_count_; ++g) {
      OutputGroup& group = groups_[g];
      std::array<int, GPIOD_LINE_BULK_MAX_LINES> values{};
      for (unsigned k = 0; k < group.count; ++k) values[k] = levels[group.index[k]];
      if (gpiod_line_set_value_bulk(&group.bulk, values.data()) != 0) result = ReturnCode::error;
    }
    return result;
  }

  std::int64_t oldest_event_ns(std::size_t index) const noexcept override {
    return index < lines_.size() ? lines_[index].oldest_event_ns : 0;
  }

  void release() noexcept override {
    for (std::size_t g = 0; g < group_count_; ++g) gpiod_line_release_bulk(&groups_[g].bulk);
    group_count_ = 0;
    for (Line& line : lines_) {
      if (line.line != nullptr && line.input && gpiod_line_is_requested(line.line)) {
        gpiod_line_release(line.line);
      }
      line = Line{};
    }
    for (std::size_t c = 0; c < chip_count_; ++c) gpiod_chip_close(chips_[c]);
    chip_count_ = 0;
  }

 private:
  struct Line {
    gpiod_line* line = nullptr;
    gpiod_chip* chip = nullptr;
    bool input = false;
    int flags = 0;
    int event_fd = -1;
    std::int64_t oldest_event_ns = 0;
  };
  struct OutputGroup {
    gpiod_chip* chip = nullptr;
    int flags = 0;
    gpiod_line_bulk bulk{};
    std::array<std::size_t, GPIOD_LINE_BULK_MAX_LINES> index{};
    unsigned count = 0;
  };

  // The chip named `chip` (label, name or path), opened once per device even when lines name
  // it differently.
  core::Expected<gpiod_chip*> open_chip(const LineParams& params) {
    gpiod_chip* chip = nullptr;
    if (!params.chip.empty() && params.chip.front() == '/') {
      chip = gpiod_chip_open(params.chip.c_str());
    } else if (params.chip.rfind("gpiochip", 0) == 0 && all_digits(params.chip.substr(8))) {
      chip = gpiod_chip_open_by_name(params.chip.c_str());
    } else {
      chip = gpiod_chip_open_by_label(params.chip.c_str());
    }
    if (chip == nullptr) {
      return core::make_error(params.config_key + ": " + describe_line(params) +
                              ": no such GPIO chip (" + errno_text(errno) +
                              "; a chip is named by its label, gpiochipN or /dev/gpiochipN)");
    }
    for (std::size_t c = 0; c < chip_count_; ++c) {
      if (std::string_view(gpiod_chip_name(chips_[c])) == gpiod_chip_name(chip)) {
        gpiod_chip_close(chip);
        return chips_[c];
      }
    }
    if (chip_count_ == kMaxChips) {
      gpiod_chip_close(chip);
      return core::make_error(params.config_key + ": " + describe_line(params) + ": more than " +
                              std::to_string(kMaxChips) + " GPIO chips");
    }
    chips_[chip_count_++] = chip;
    return chip;
  }

  core::Expected<void> claim_all(std::span<const LineParams> lines, const std::string& consumer) {
    if (lines.size() > kMaxLines) return core::make_error("too many GPIO lines");
    // Find every line first, so that a missing or used line fails before anything is claimed.
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const LineParams& params = lines[i];
      auto chip = open_chip(params);
      if (!chip) return std::move(chip).error();
      const std::string where = params.config_key + ": " + describe_line(params) + " (" +
                                gpiod_chip_name(*chip) + " '" + gpiod_chip_label(*chip) + "')";
      gpiod_line* line = nullptr;
      if (params.line_name.empty()) {
        const unsigned lines_on_chip = gpiod_chip_num_lines(*chip);
        if (params.offset < 0 || static_cast<unsigned>(params.offset) >= lines_on_chip) {
          return core::make_error(where + ": no such line, the chip has offsets 0.." +
                                  std::to_string(lines_on_chip - 1));
        }
        line = gpiod_chip_get_line(*chip, static_cast<unsigned>(params.offset));
      } else {
        line = gpiod_chip_find_line(*chip, params.line_name.c_str());
        if (line == nullptr) {
          return core::make_error(where + ": no line of that name on the chip");
        }
      }
      if (line == nullptr) return core::make_error(where + ": " + errno_text(errno));
      for (std::size_t k = 0; k < i; ++k) {
        if (lines_[k].line == line) {
          return core::make_error(where + ": the same line as " + lines[k].config_key);
        }
      }
      if (gpiod_line_update(line) == 0 && gpiod_line_is_used(line)) {
        const char* user = gpiod_line_consumer(line);
        const bool output = gpiod_line_direction(line) == GPIOD_LINE_DIRECTION_OUTPUT;
        return core::make_error(where + ": already used by '" +
                                std::string(user != nullptr ? user : "(kernel)") + "' as " +
                                (output ? "an output" : "an input"));
      }
      lines_[i] =
          Line{line, *chip, params.direction == Direction::input, request_flags(params), -1};
    }
    for (std::size_t i = 0; i < lines.size(); ++i) {
      Line& line = lines_[i];
      const LineParams& params = lines[i];
      if (!line.input) continue;
      const std::string where = params.config_key + ": " + describe_line(params);
      if (gpiod_line_request_both_edges_events_flags(line.line, consumer.c_str(), line.flags) !=
          0) {
        return core::make_error(where + ": cannot claim it as an input with edge events (" +
                                errno_text(errno) + ")");
      }
      line.event_fd = gpiod_line_event_get_fd(line.line);
      const int fd_flags = line.event_fd >= 0 ? fcntl(line.event_fd, F_GETFL) : -1;
      if (fd_flags < 0 || fcntl(line.event_fd, F_SETFL, fd_flags | O_NONBLOCK) != 0) {
        return core::make_error(where + ": cannot make its event descriptor non-blocking (" +
                                errno_text(errno) + ")");
      }
      if (auto checked = check_direction(line, where, GPIOD_LINE_DIRECTION_INPUT); !checked) {
        return checked;
      }
    }
    // Outputs grouped by chip and flags, each group claimed at logical 0 in one request.
    for (std::size_t i = 0; i < lines.size(); ++i) {
      Line& line = lines_[i];
      if (line.input) continue;
      OutputGroup* group = nullptr;
      for (std::size_t g = 0; g < group_count_; ++g) {
        if (groups_[g].chip == line.chip && groups_[g].flags == line.flags) group = &groups_[g];
      }
      if (group == nullptr) {
        group = &groups_[group_count_++];
        *group = OutputGroup{};
        group->chip = line.chip;
        group->flags = line.flags;
        gpiod_line_bulk_init(&group->bulk);
      }
      gpiod_line_bulk_add(&group->bulk, line.line);
      group->index[group->count++] = i;
    }
    for (std::size_t g = 0; g < group_count_; ++g) {
      OutputGroup& group = groups_[g];
      const std::array<int, GPIOD_LINE_BULK_MAX_LINES> zeros{};
      if (gpiod_line_request_bulk_output_flags(&group.bulk, consumer.c_str(), group.flags,
                                               zeros.data()) != 0) {
        const int error = errno;
        // Not claimed: release() must not release it.
        gpiod_line_bulk_init(&group.bulk);
        std::string names;
        for (unsigned k = 0; k < group.count; ++k) {
          names += (k > 0 ? ", " : "") + lines[group.index[k]].config_key + " (" +
                   describe_line(lines[group.index[k]]) + ")";
        }
        for (std::size_t later = g; later + 1 < group_count_; ++later) {
          groups_[later] = groups_[later + 1];
        }
        --group_count_;
        return core::make_error(names + ": cannot claim as outputs (" + errno_text(error) + ")");
      }
      for (unsigned k = 0; k < group.count; ++k) {
        const std::size_t i = group.index[k];
        const std::string where = lines[i].config_key + ": " + describe_line(lines[i]);
        if (auto checked = check_direction(lines_[i], where, GPIOD_LINE_DIRECTION_OUTPUT);
            !checked) {
          return checked;
        }
      }
    }
    return {};
  }

  // The kernel's view of a claimed line must be the direction asked for.
  static core::Expected<void> check_direction(const Line& line, const std::string& where,
                                              int expected) {
    if (gpiod_line_update(line.line) != 0) {
      return core::make_error(where + ": cannot read its state back (" + errno_text(errno) + ")");
    }
    if (gpiod_line_direction(line.line) != expected) {
      return core::make_error(where + ": wrong direction: the chip keeps it " +
                              (expected == GPIOD_LINE_DIRECTION_INPUT ? "an output" : "an input") +
                              ", expected " +
                              (expected == GPIOD_LINE_DIRECTION_INPUT ? "an input" : "an output"));
    }
    return {};
  }

  std::array<gpiod_chip*, kMaxChips> chips_{};
  std::size_t chip_count_ = 0;
  std::array<Line, kMaxLines> lines_{};
  std::array<OutputGroup, kMaxLines> groups_{};
  std::size_t group_count_ = 0;
};

}  // namespace

std::unique_ptr<LineIo> make_gpiod_line_io() {
  return std::make_unique<GpiodLineIo>();
}

}  // namespace trainer::hal::gpiod
