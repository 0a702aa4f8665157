// The device file's I/O tables: [gpio] (digital I/O on GPIO lines, digital_io = "gpio") with
// its check against [digital], and [telemetry] (the graphics host's stream). Read by
// load_device.cpp's read_device(); keys, units, ranges and defaults in docs/config.md.
#include "device_io_tables.hpp"

#include <array>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <arpa/inet.h>
#include <netinet/in.h>

namespace trainer::config::detail {
namespace {

constexpr std::array<std::string_view, 4> kGpioBiasChoices = {"as-is", "disable", "pull-up",
                                                              "pull-down"};
constexpr std::array<std::string_view, 2> kGpioLatchChoices = {"active", "inactive"};
constexpr IntRange kGpioBitRange{0, 31};
constexpr IntRange kGpioOffsetRange{0, 511};

GpioLineConfig read_gpio_line(TableReader& table, bool input, const DigitalConfig& digital,
                              ErrorSink& errors) {
  GpioLineConfig line;
  line.key = table.prefix();
  line.bit = static_cast<int>(table.required_int(
      "bit", kGpioBitRange, input ? "bit of the digital input word" : "bit of the digital output word"));
  line.chip = table.required_string("chip", "the GPIO chip: its label, gpiochipN or /dev/gpiochipN");
  const bool named = table.has("line");
  const bool numbered = table.has("offset");
  if (named) line.line_name = table.required_string("line", "the line's name");
  if (numbered) {
    line.offset = static_cast<int>(table.required_int("offset", kGpioOffsetRange, "line offset on the chip"));
  }
  if (errors.ok() && named && numbered) {
    table.fail_value("offset", ": expected either line (a name) or offset, not both");
  } else if (errors.ok() && !named && !numbered) {
    (void)table.required_string("line", "the line's name, or give offset");
  }
  line.active_low = table.optional_bool("active_low", false);
  if (table.has("bias")) {
    const auto bias = table.required_choice("bias", kGpioBiasChoices);
    if (bias) line.bias = static_cast<GpioBias>(*bias);
  }
  if (input) {
    // The enable (dead-man) switch latches its release; everything else its press.
    line.latch = line.bit == digital.enable_input_bit ? GpioLatch::inactive : GpioLatch::active;
    if (table.has("latch")) {
      const auto latch = table.required_choice("latch", kGpioLatchChoices);
      if (latch) line.latch = static_cast<GpioLatch>(*latch);
    }
  }
  table.finish();
  return line;
}

}  // namespace

GpioConfig read_gpio(TableReader& table, const DigitalConfig& digital, ErrorSink& errors) {
  GpioConfig gpio;
  gpio.consumer = table.optional_string("consumer", "the lines' user name").value_or("trainer");
  if (errors.ok() && (gpio.consumer.empty() || gpio.consumer.size() > 31)) {
    table.fail_value("consumer", ": expected 1..31 characters");
  }
  auto inputs = table.array_of_tables("input", 0, kMaxGpioLines, "input lines");
  auto outputs = table.array_of_tables("output", 0, kMaxGpioLines, "output lines");
  for (auto& entry : inputs) gpio.inputs.push_back(read_gpio_line(entry, true, digital, errors));
  for (auto& entry : outputs) gpio.outputs.push_back(read_gpio_line(entry, false, digital, errors));
  if (errors.ok() && gpio.inputs.size() + gpio.outputs.size() > kMaxGpioLines) {
    table.fail_value(gpio.outputs.empty() ? "input" : "output",
                     ": too many lines: expected at most " + std::to_string(kMaxGpioLines) +
                         " inputs and outputs together");
  }
  // One line per bit in each word.
  for (auto* list : {&gpio.inputs, &gpio.outputs}) {
    auto& readers = list == &gpio.inputs ? inputs : outputs;
    for (std::size_t i = 0; errors.ok() && i < list->size(); ++i) {
      for (std::size_t k = 0; errors.ok() && k < i; ++k) {
        if ((*list)[i].bit == (*list)[k].bit) {
          readers[i].fail_value("bit", " is already used by " + readers[k].qualified("bit") +
                                           ": expected one line per bit");
        }
      }
    }
  }
  table.finish();
  return gpio;
}

// Every wired [digital] bit needs its line: an e-stop bit without a line would read "released"
// for ever.
void check_gpio_wiring(const DeviceConfig& config, TableReader& digital_table, ErrorSink& errors) {
  const auto has_bit = [](const std::vector<GpioLineConfig>& lines, int bit) {
    for (const GpioLineConfig& line : lines) {
      if (line.bit == bit) return true;
    }
    return false;
  };
  const DigitalConfig& digital = config.digital;
  const std::array<std::pair<std::string_view, int>, 2> inputs = {
      std::pair{std::string_view("estop_input_bit"), digital.estop_input_bit},
      std::pair{std::string_view("enable_input_bit"), digital.enable_input_bit}};
  for (const auto& [key, bit] : inputs) {
    if (errors.ok() && bit != kNotWired && !has_bit(config.gpio.inputs, bit)) {
      digital_table.fail_value(key, ": digital_io = \"gpio\" but no [[gpio.input]] has bit = " +
                                        std::to_string(bit) + " (-1 = not wired)");
    }
  }
  const std::array<std::pair<std::string_view, int>, 2> outputs = {
      std::pair{std::string_view("drive_enable_output_bit"), digital.drive_enable_output_bit},
      std::pair{std::string_view("fault_lamp_output_bit"), digital.fault_lamp_output_bit}};
  for (const auto& [key, bit] : outputs) {
    if (errors.ok() && bit != kNotWired && !has_bit(config.gpio.outputs, bit)) {
      digital_table.fail_value(key, ": digital_io = \"gpio\" but no [[gpio.output]] has bit = " +
                                        std::to_string(bit) + " (-1 = not wired)");
    }
  }
}

// [telemetry] (docs/config.md, docs/telemetry.md): optional; when present and enabled the
// destination is required. The address must be numeric (inet_pton): the appliance does no
// name lookups at run time.
constexpr IntRange kTelemetryPortRange{1, 65'535};
constexpr IntRange kTelemetryRateRangeHz{30, 120};
constexpr IntRange kTelemetrySourcePortRange{0, 65'535};

TelemetryConfig read_telemetry(TableReader& table) {
  TelemetryConfig telemetry;
  telemetry.enabled = table.optional_bool("enabled", true);
  telemetry.rate_hz = static_cast<std::uint32_t>(
      table.optional_int("rate_hz", 60, kTelemetryRateRangeHz, "frames per second"));
  // Disabled, the destination may be left out (the table then only keeps the setting).
  if (!telemetry.enabled && !table.has("address") && !table.has("port")) {
    table.finish();
    return telemetry;
  }
  telemetry.address =
      table.required_string("address", "the graphics host's numeric IPv4 or IPv6 address");
  telemetry.port = static_cast<std::uint16_t>(
      table.required_int("port", kTelemetryPortRange, "UDP port"));
  telemetry.source_port = static_cast<std::uint16_t>(table.optional_int(
      "source_port", 0, kTelemetrySourcePortRange, "local UDP port, 0 = any"));
  if (!telemetry.address.empty()) {
    in_addr v4{};
    in6_addr v6{};
    if (inet_pton(AF_INET, telemetry.address.c_str(), &v4) != 1 &&
        inet_pton(AF_INET6, telemetry.address.c_str(), &v6) != 1) {
      table.fail_value("address", ": expected a numeric IPv4 (192.168.1.20) or IPv6 (fd00::20) "
                                  "address; host names are not looked up");
    }
  }
  table.finish();
  return telemetry;
}

}  // namespace trainer::config::detail
