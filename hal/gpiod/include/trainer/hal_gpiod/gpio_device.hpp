// GpioDevice: the HAL backend for digital lines on Linux GPIO chips (libgpiod 1.6, the
// character device's v1 uAPI): the safety inputs (e-stop, enable switch, handle buttons) and
// outputs (drive enable, lamps) as bits of the HAL's digital words. It offers
// DigitalInputInterface and DigitalOutputInterface only; the motion comes from another device
// (hal::CompositeDevice puts them together). docs/gpio.md.
//
// Lines are named by chip (label, name "gpiochipN" or path "/dev/gpiochipN") and line (name,
// or offset), with active-low and bias; every value at this interface is LOGICAL (1 = active:
// e-stop pressed, enable held, drive enable on), the kernel applies active-low.
//
// Lifecycle (non-RT):
//  configure(): checks the parameters (capacities, one bit per line and word) and claims every
//    line with the consumer name: inputs for both-edge events (non-blocking event descriptor),
//    outputs at their inactive level (drive enable off) in one request per chip. A chip or line
//    that does not exist, a line already used (its consumer named), a line twice in the file or
//    a line that does not take the requested direction fails configure naming chip and line;
//    nothing stays claimed.
//  activate(): claims the lines again if deactivate() released them; outputs stay inactive
//    until the first write.
//  deactivate(): drives every output to its inactive level, then releases every line. Never
//    fails, any state.
//
// RT (noexcept, no heap, no blocking):
//  read_digital_inputs(): per input the level now and whether the line changed since the last
//    read (edge events drained without blocking). A line that changed reports its LATCH level
//    for this read, whatever it reads now: a press shorter than a period is seen in the read
//    that follows it. Inputs latch "active" by default (e-stop, buttons: a short press wins);
//    the enable switch latches "inactive" (a short release wins). A failed read returns
//    ReturnCode::error (the controller then treats the e-stop as pressed).
//  write_digital_outputs(): the output bits, one bulk set call per claimed output request.
//
// Threads: lifecycle and RT calls from one thread at a time; stats() from the same thread or
// while it is stopped.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/hal/device.hpp"

namespace trainer::hal::gpiod {

// Lines per device, distinct chips per device.
inline constexpr std::size_t kMaxLines = 16;
inline constexpr std::size_t kMaxChips = 4;

enum class Direction : std::uint8_t { input, output };
enum class Bias : std::uint8_t { as_is, disable, pull_up, pull_down };
const char* to_string(Bias bias) noexcept;
// Which level an input reports for a read after which it changed (see above).
enum class Latch : std::uint8_t { active, inactive };

struct LineParams {
  std::string config_key;  // how messages name it, e.g. "gpio.input[0]"
  Direction direction = Direction::input;
  int bit = -1;           // bit of the HAL input or output word, 0..31
  std::string chip;       // label, "gpiochipN" or a path
  std::string line_name;  // the line's name, or empty when `offset` names it
  int offset = -1;        // the line's offset on the chip when line_name is empty
  bool active_low = false;
  Bias bias = Bias::as_is;
  Latch latch = Latch::active;  // inputs only
};

// "chip 'bench' line 'estop'" / "chip 'gpiochip0' line 3": how messages name a line.
std::string describe_line(const LineParams& line);

struct GpioDeviceParams {
  std::string name;
  std::string consumer = "trainer";  // shown by gpioinfo as the lines' user
  std::vector<LineParams> lines;     // at most kMaxLines
};

// The lines as the device needs them: the seam between the device's bit and latch logic and
// the kernel. GpiodLineIo (make_gpiod_line_io) is libgpiod; tests inject their own.
class LineIo {
 public:
  LineIo() = default;
  LineIo(const LineIo&) = delete;
  LineIo& operator=(const LineIo&) = delete;
  virtual ~LineIo() = default;

  // Non-RT. Claims every line (index = position in `lines`): inputs for both-edge events,
  // outputs at logical 0. All or nothing: on failure nothing stays claimed and the message
  // names chip and line.
  virtual core::Expected<void> claim(std::span<const LineParams> lines,
                                     std::string_view consumer) = 0;
  // RT. Input `index`: its logical level now, and whether any edge event arrived since the
  // last call for it (events drained, never waiting).
  virtual ReturnCode sample_input(std::size_t index, bool& active, bool& changed) noexcept = 0;
  // RT. The kernel's timestamp (CLOCK_MONOTONIC, ns) of the oldest edge event that the last
  // sample_input() of input `index` drained; 0 when it drained none or the seam keeps no time.
  // For measurements (hil's edge-to-latch step); the device's logic does not use it.
  virtual std::int64_t oldest_event_ns(std::size_t /*index*/) const noexcept { return 0; }
  // RT. Sets every output line to levels[index] (logical; entries of inputs ignored).
  virtual ReturnCode write_outputs(std::span<const std::uint8_t, kMaxLines> levels) noexcept = 0;
  // Non-RT. Releases every claimed line (no-op when none).
  virtual void release() noexcept = 0;
};

std::unique_ptr<LineIo> make_gpiod_line_io();

struct GpioStats {
  std::uint64_t reads = 0;
  std::uint64_t read_errors = 0;
  std::uint64_t write_errors = 0;
  // Per input line (index as in the params): reads after which the line had changed, and of
  // those the ones whose latch level was not the level read (a pulse shorter than a period,
  // seen only through its events).
  std::array<std::uint64_t, kMaxLines> changed_reads{};
  std::array<std::uint64_t, kMaxLines> pulses_latched{};
  // Per input line: the kernel timestamp (CLOCK_MONOTONIC ns) of the oldest edge event drained
  // by the last read after which the line had changed (LineIo::oldest_event_ns; 0 = unknown).
  std::array<std::int64_t, kMaxLines> last_change_event_ns{};
};

class GpioDevice final : public hal::Device,
                         public hal::DigitalInputInterface,
                         public hal::DigitalOutputInterface {
 public:
  explicit GpioDevice(GpioDeviceParams params);  // libgpiod lines
  GpioDevice(GpioDeviceParams params, std::unique_ptr<LineIo> io);
  ~GpioDevice() override;

  std::string_view name() const noexcept override { return params_.name; }
  core::Expected<void> configure() override;
  core::Expected<void> activate() override;
  void deactivate() noexcept override;
  LifecycleState state() const noexcept override { return state_; }

  DigitalInputInterface* digital_inputs() noexcept override { return this; }
  DigitalOutputInterface* digital_outputs() noexcept override { return this; }

  std::size_t digital_input_count() const noexcept override { return input_count_; }
  ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override;
  std::size_t digital_output_count() const noexcept override { return output_count_; }
  ReturnCode write_digital_outputs(std::uint32_t levels) noexcept override;

  const GpioStats& stats() const noexcept { return stats_; }
  const GpioDeviceParams& params() const noexcept { return params_; }

 private:
  core::Expected<void> check_params() const;
  core::Expected<void> claim_lines();
  void drive_outputs_inactive() noexcept;

  GpioDeviceParams params_;
  std::unique_ptr<LineIo> io_;
  LifecycleState state_ = LifecycleState::unconfigured;
  bool claimed_ = false;
  std::size_t input_count_ = 0;
  std::size_t output_count_ = 0;
  std::array<std::uint8_t, kMaxLines> out_levels_{};
  GpioStats stats_;
};

}  // namespace trainer::hal::gpiod
