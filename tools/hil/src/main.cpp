// hil: the hardware-in-the-loop bring-up and commissioning tool (docs/hil.md).
//
//   hil [--device FILE] [--json] [--yes] [--act CMD] [--slow-motion N] [--can-interface NAME]
//       [--report-json FILE] [--report-md FILE] [--write-device FILE | --fix]
//       scan  [--only PART]... [--nmt-reset] [--listen-ms N]
//       check [--only PART/STEP]... [--torque-limit F] [--trials N] [--period-us N]
//             [--jitter-syncs N] [--action-timeout S] [--gpio-period-us N]
//             [--latch-margin-ms X] [--exchanges N]
//
// Every part of the bench (CAN drives; GPIO lines and USB devices from tools/hil/io) scans and
// checks through the table kParts below. Human output: one line per step
// (PASS/FAIL/SKIP id reason [figures]); --json prints the report's JSON on stdout instead (the
// lines then go to stderr). Exit status: 0 every step passed or was skipped, 1 a step failed,
// 2 usage error, 3 setup error (device file, interface, report or device file not written,
// interrupted).
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "trainer/config/device.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"
#include "trainer/hil/can_part.hpp"
#include "trainer/hil/device_edit.hpp"
#include "trainer/hil/device_write.hpp"
#include "trainer/hil/io_parts.hpp"
#include "trainer/hil/operators.hpp"
#include "trainer/hil/report.hpp"
#include "trainer/hil/step_filter.hpp"

#ifndef TRAINER_HIL_VERSION
#define TRAINER_HIL_VERSION "unknown"
#endif
#ifndef TRAINER_HIL_GIT_DESCRIBE
#define TRAINER_HIL_GIT_DESCRIBE "unknown"
#endif

namespace {

namespace hil = trainer::hil;
namespace sc = trainer::hal::socketcan;

constexpr int kExitUsage = 2;
constexpr int kExitSetup = 3;

struct Options {
  std::string device_file;
  bool json = false;
  bool yes = false;
  std::string act;
  std::int64_t slow_motion = 1;
  std::string can_interface;
  std::string report_json;
  std::string report_md;
  std::string write_device;
  bool fix = false;
  // scan
  bool nmt_reset = false;
  std::int64_t listen_ms = 300;
  // check
  std::vector<std::string> only;
  double torque_limit = 0.05;
  int trials = 0;
  std::int64_t period_us = 4000;
  std::int64_t jitter_syncs = 500;
  double action_timeout_s = 10.0;
  // GPIO part: the read loop's period (0 = 1 ms x slow motion) and the latch limit's margin
  // beyond one period (< 0 = half a period); USB part: round-trip exchanges.
  std::int64_t gpio_period_us = 0;
  double latch_margin_ms = -1.0;
  std::int64_t exchanges = 1000;
};

// --------------------------------------------------------------------------- the parts
// A part scans and checks one kind of bench hardware. nullopt: the part has nothing to do on
// this bench (e.g. no CAN interface and no CANopen device file).

std::optional<sc::CanTransport> open_can(const hil::BenchContext& context, const Options& options,
                                         std::string& error) {
  std::string interface = options.can_interface;
  if (interface.empty() && context.device && context.device->backend == "canopen")
    interface = context.device->canopen.interface;
  if (interface.empty()) return std::nullopt;
  sc::SocketCanOptions socket_options;
  socket_options.error_frames = false;
  auto transport = sc::CanTransport::open_socketcan(interface, {}, socket_options);
  if (!transport) {
    error = transport.error().message;
    return std::nullopt;
  }
  return std::move(*transport);
}

hil::can::CanOptions can_options(const Options& options) {
  hil::can::CanOptions can;
  can.listen_ns = options.listen_ms * 1'000'000;
  can.nmt_reset = options.nmt_reset;
  can.period_ns = options.period_us * 1000;
  can.jitter_syncs = options.jitter_syncs;
  return can;
}

// A part that could not open its hardware: the run ends with exit status 3.
bool g_setup_failed = false;

hil::StepResult setup_failure(const std::string& part, const std::string& why) {
  g_setup_failed = true;
  hil::StepResult step;
  step.id = part + ".setup";
  step.title = part + ": open the bus";
  step.outcome = hil::Outcome::fail;
  step.reason = why;
  return step;
}

std::optional<hil::ScanSection> can_scan(const hil::BenchContext& context, const Options& options) {
  std::string error;
  auto bus = open_can(context, options, error);
  if (!bus) {
    if (error.empty()) return std::nullopt;
    hil::ScanSection section;
    section.part = "can";
    section.comparison.push_back(setup_failure("can", error));
    return section;
  }
  return hil::can::scan(context, *bus, can_options(options));
}

std::optional<hil::CheckSection> can_check(const hil::BenchContext& context, const Options& options,
                                           const hil::StepFilter& filter) {
  if (!context.device || context.device->backend != "canopen") return std::nullopt;
  std::string error;
  auto bus = open_can(context, options, error);
  if (!bus) {
    hil::CheckSection section;
    section.part = "can";
    section.steps.push_back(setup_failure("can", error.empty() ? "no CAN interface" : error));
    return section;
  }
  return hil::can::check(context, *bus, filter, can_options(options));
}

struct Part {
  const char* name;
  std::optional<hil::ScanSection> (*scan)(const hil::BenchContext&, const Options&);
  std::optional<hil::CheckSection> (*check)(const hil::BenchContext&, const Options&,
                                            const hil::StepFilter&);
};

// The GPIO part (tools/hil/io): scans when the device file wires its lines to GPIO or the
// system has GPIO chips; checks when the device file's digital_io is "gpio".
bool bench_uses_gpio(const hil::BenchContext& context) {
  return context.device && context.device->digital_io == trainer::config::DigitalIo::gpio;
}

std::optional<hil::ScanSection> gpio_scan(const hil::BenchContext& context, const Options&) {
  if (!bench_uses_gpio(context) && hil::list_gpio_chips().empty()) return std::nullopt;
  return hil::scan_gpio(context);
}

// Steps --only leaves out are dropped after the part ran (its steps share one read loop).
void keep_wanted(std::vector<hil::StepResult>& steps, const hil::StepFilter& filter) {
  std::erase_if(steps, [&](const hil::StepResult& step) { return !filter.wants(step.id); });
}

std::optional<hil::CheckSection> gpio_check(const hil::BenchContext& context,
                                            const Options& options,
                                            const hil::StepFilter& filter) {
  if (!bench_uses_gpio(context)) return std::nullopt;
  hil::GpioCheckOptions gpio;
  gpio.period_ns = options.gpio_period_us * 1000;
  if (options.latch_margin_ms >= 0.0)
    gpio.margin_ns = static_cast<std::int64_t>(options.latch_margin_ms * 1e6);
  hil::CheckSection section = hil::check_gpio(context, gpio);
  keep_wanted(section.steps, filter);
  return section;
}

// The USB part (tools/hil/io): scans when the device file names a USB device or one with the
// protocol's VID:PID is plugged in; checks when the device file's backend is "usb".
bool bench_uses_usb(const hil::BenchContext& context) {
  return context.device && context.device->backend == "usb";
}

std::optional<hil::ScanSection> usb_scan(const hil::BenchContext& context, const Options&) {
  hil::ScanSection section = hil::scan_usb(context);
  if (!bench_uses_usb(context) && section.found.empty()) return std::nullopt;
  return section;
}

std::optional<hil::CheckSection> usb_check(const hil::BenchContext& context,
                                           const Options& options,
                                           const hil::StepFilter& filter) {
  if (!bench_uses_usb(context)) return std::nullopt;
  hil::UsbCheckOptions usb;
  usb.exchanges = options.exchanges;
  hil::CheckSection section = hil::check_usb(context, usb);
  keep_wanted(section.steps, filter);
  return section;
}

// THE PARTS TABLE. Each part is one line: its name (the PART of --only PART/STEP and of the step
// ids), its scan and its check; a part returns nothing when the bench has none of its hardware.
const Part kParts[] = {
    {"can", can_scan, can_check},
    {"gpio", gpio_scan, gpio_check},
    {"usb", usb_scan, usb_check},
};

// --------------------------------------------------------------------------- the program

void print_step(const hil::StepResult& step, std::ostream& out) { out << hil::human_line(step) << '\n'; }


bool write_text(const std::string& path, const std::string& text) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file << text;
  return static_cast<bool>(file);
}

int run(const std::string& command, const Options& options, const std::string& arguments) {
  hil::BenchContext context;
  hil::Report report;
  report.run.command = command;
  report.run.arguments = arguments;
  report.run.tool_version = TRAINER_HIL_VERSION;
  report.run.git_describe = TRAINER_HIL_GIT_DESCRIBE;
  report.run.date_utc = hil::utc_now_iso8601();
  report.run.host = hil::host_description();
  report.run.slow_motion = options.slow_motion;
  report.run.torque_limit_fraction = options.torque_limit;
  if (!options.device_file.empty()) {
    auto device = trainer::config::load_device(options.device_file);
    if (!device) {
      std::cerr << "hil: " << device.error().message << '\n';
      return kExitSetup;
    }
    context.device = std::move(*device);
    report.run.device_path = options.device_file;
    report.run.device_sha256 = hil::sha256_hex(hil::read_whole_file(options.device_file));
  }
  hil::OperatorOptions operator_options;
  operator_options.yes = options.yes;
  operator_options.act_command = options.act;
  operator_options.interactive = ::isatty(STDIN_FILENO) != 0;
  hil::ConsoleOperator op(operator_options);
  context.op = &op;
  context.max_torque_fraction = options.torque_limit;
  context.slow_motion = options.slow_motion;
  context.trials = options.trials;
  context.action_timeout_s = options.action_timeout_s;
  std::ostream& out = options.json ? std::cerr : std::cout;
  const hil::StepFilter filter(options.only);
  try {
    for (const Part& part : kParts) {
      if (!filter.wants_part(part.name)) continue;
      if (command == "scan") {
        auto section = part.scan(context, options);
        if (!section) continue;
        for (const hil::ScanItem& item : section->found) out << "found " << item.name << " " << item.properties.dump() << '\n';
        for (const hil::StepResult& step : section->comparison) print_step(step, out);
        report.scans.push_back(std::move(*section));
      } else {
        auto section = part.check(context, options, filter);
        if (!section) continue;
        for (const hil::StepResult& step : section->steps) print_step(step, out);
        report.checks.push_back(std::move(*section));
      }
    }
  } catch (const hil::Interrupted& stop) {
    std::cerr << "hil: " << stop.what() << '\n';
    return kExitSetup;
  }
  bool ok = true;
  if (context.device) {
    hil::WriteRequest request;
    request.device_file = options.device_file;
    if (options.fix) request.target = options.device_file;
    if (!options.write_device.empty()) request.target = options.write_device;
    ok = hil::write_corrections(request, op, report, out, std::cerr);
  }
  if (!options.report_json.empty() && !write_text(options.report_json, hil::to_json(report).dump(2) + "\n")) {
    std::cerr << "hil: cannot write " << options.report_json << '\n';
    ok = false;
  }
  if (!options.report_md.empty() && !write_text(options.report_md, hil::to_markdown(report))) {
    std::cerr << "hil: cannot write " << options.report_md << '\n';
    ok = false;
  }
  const hil::Tally t = hil::tally(report);
  out << "hil " << command << ": " << t.pass << " pass, " << t.fail << " fail, " << t.skip << " skip\n";
  if (options.json) std::cout << hil::to_json(report).dump(2) << '\n';
  if (!ok || g_setup_failed) return kExitSetup;
  return hil::exit_status(report);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"hil: hardware-in-the-loop bring-up and commissioning of the trainer's bench"};
  cli.require_subcommand(1);
  Options options;
  cli.add_option("--device", options.device_file, "device file of the bench (config/devices/*.toml)")
      ->check(CLI::ExistingFile);
  cli.add_flag("--json", options.json, "print the report as JSON on stdout (step lines go to stderr)");
  cli.add_flag("--yes", options.yes, "answer yes to every confirmation (torque, writing files)");
  cli.add_option("--act", options.act,
                 "scripted operator: run 'CMD ACTION' for each action asked of a person");
  cli.add_option("--slow-motion", options.slow_motion,
                 "time stretch of an emulator, as the trainer's --slow-motion (figures stay in "
                 "bench time)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1000}));
  cli.add_option("--can-interface", options.can_interface,
                 "SocketCAN interface (default: the device file's canopen.interface)");
  cli.add_option("--report-json", options.report_json, "write the commissioning report as JSON");
  cli.add_option("--report-md", options.report_md, "write the commissioning report as Markdown");
  auto* write = cli.add_option("--write-device", options.write_device,
                               "write the device file corrected from the measurements here "
                               "(each change shown and confirmed)");
  cli.add_flag("--fix", options.fix, "correct the --device file itself (confirmed)")->excludes(write);
  CLI::App* scan = cli.add_subcommand("scan", "what is on the bench, compared with --device");
  scan->add_flag("--nmt-reset", options.nmt_reset,
                 "send NMT reset communication to every node first (asks)");
  scan->add_option("--listen-ms", options.listen_ms, "listen for boot-ups/heartbeats this long")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{60000}));
  scan->add_option("--only", options.only, "only these parts: can, gpio, usb (repeatable)");
  CLI::App* check = cli.add_subcommand("check", "measure every axis and the bus (needs --device)");
  check->add_option("--only", options.only,
                    "only these steps: PART, PART/STEP, PART/AXIS, PART/AXIS.STEP (repeatable)");
  check->add_option("--torque-limit", options.torque_limit,
                    "torque limit as a fraction of each axis's current limit (default 0.05)")
      ->check(CLI::Range(0.001, 0.5));
  check->add_option("--trials", options.trials, "repetitions of the timed steps (heartbeat_loss)")
      ->check(CLI::Range(1, 100000));
  check->add_option("--period-us", options.period_us,
                    "SYNC period when the device file says 0 (every loop period)")
      ->check(CLI::Range(std::int64_t{500}, std::int64_t{100000}));
  check->add_option("--jitter-syncs", options.jitter_syncs,
                    "SYNCs of the bus statistics (sync_jitter, pdo_round_trip; default 500)")
      ->check(CLI::Range(std::int64_t{10}, std::int64_t{1000000}));
  check->add_option("--action-timeout", options.action_timeout_s,
                    "seconds a step waits for an operator's action (default 10)")
      ->check(CLI::Range(0.1, 3600.0));
  check->add_option("--gpio-period-us", options.gpio_period_us,
                    "GPIO part: the read loop's period (default 1000 x --slow-motion)")
      ->check(CLI::Range(std::int64_t{100}, std::int64_t{1000000}));
  check->add_option("--latch-margin-ms", options.latch_margin_ms,
                    "GPIO part: edge-to-latch limit beyond one period (default half a period)")
      ->check(CLI::Range(0.0, 10000.0));
  check->add_option("--exchanges", options.exchanges,
                    "USB part: round-trip exchanges (default 1000)")
      ->check(CLI::Range(std::int64_t{10}, std::int64_t{10000000}));
  // The program's options may also follow the subcommand (`hil check --device FILE`).
  scan->fallthrough();
  check->fallthrough();
  try {
    cli.parse(argc, argv);
  } catch (const CLI::CallForHelp& help) {
    return cli.exit(help);
  } catch (const CLI::ParseError& error) {
    (void)cli.exit(error);
    return kExitUsage;
  }
  const std::string command = scan->parsed() ? "scan" : "check";
  if (command == "check" && options.device_file.empty()) {
    std::cerr << "hil check: --device FILE is required (what the bench should be)\n";
    return kExitUsage;
  }
  if (options.fix && options.device_file.empty()) {
    std::cerr << "hil: --fix corrects the --device file: give one\n";
    return kExitUsage;
  }
  std::string arguments;
  for (int i = 0; i < argc; ++i) arguments += (i == 0 ? "" : " ") + std::string(argv[i]);
  hil::install_interrupt_handler();
  try {
    return run(command, options, arguments);
  } catch (const std::exception& error) {
    std::cerr << "hil: " << error.what() << '\n';
    return kExitSetup;
  }
}
