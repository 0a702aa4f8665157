// simdrive: the trainer's CiA 402 servo drives, simulated, on a SocketCAN interface: one CANopen
// slave per joint of a device file, the simulated bench's plant behind them and the scene's
// trainee script as the hand (docs/simdrive.md). The trainer (the master) runs as another
// process on the same bus.
//
//   simdrive --scene config/scenes/cbd.toml --device config/devices/canopen_vcan.toml
//            [--interface NAME] [--fault SPEC]... [--events FILE|-] [--vendor-id N]
//            [--product-code N] [--rated-torque-scale F] [--exit-after-idle S] [--max-seconds S]
//            [--period-us N] [--slow-motion N] [--no-stdin] [--fd N]
//            [--miswire reverse_encoder|reverse_motor:node=N]... [--node-id-map A=B]...
//
// --miswire / --node-id-map present a wrongly wired bench for `hil` (docs/simdrive.md).
// Fault SPECs (hal_simdrive/fault.hpp) on the command line are applied at once or scheduled
// (at_sync / at_s count from the first NMT start); the same syntax on a stdin line applies a
// fault at once. The loop waits in ppoll() on the CAN socket, stdin and a signalfd for
// SIGINT/SIGTERM with the bus's next timer deadline as timeout. The protocol timers (heartbeats,
// deadlines, at_s, delay) run on CLOCK_MONOTONIC, or with --slow-motion N on CLOCK_MONOTONIC
// / N: the trainer's --slow-motion N time line, so both processes keep their heartbeat and
// deadline ratios under an emulator (core::SlowMotionClock). The events log's t_ns is always
// CLOCK_MONOTONIC.
// --max-seconds and --exit-after-idle are real seconds. On exit it prints per node the
// final NMT and power state, frames and faults.
//
// Exit status: 0 ended by a signal, --max-seconds or --exit-after-idle; 1 setup error (file,
// interface); 2 usage error (options, a bad --fault SPEC). --fd N (for tests on machines without
// SocketCAN) takes an inherited descriptor that carries one struct can_frame per message, e.g.
// one end of socketpair(AF_UNIX, SOCK_SEQPACKET), instead of opening the interface.
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "simdrive_setup.hpp"
#include "trainer/hal_simdrive/sim_drive_bus.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace {

namespace sd = trainer::hal::simdrive;
namespace ts = trainer::tools::simdrive;

std::int64_t monotonic_ns() {
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

std::optional<std::uint32_t> parse_u32(const std::string& text) {
  if (text.empty()) return std::nullopt;
  errno = 0;
  char* end = nullptr;
  const unsigned long long value = std::strtoull(text.c_str(), &end, 0);
  if (errno != 0 || end != text.c_str() + text.size() ||
      value > std::numeric_limits<std::uint32_t>::max()) {
    return std::nullopt;
  }
  return static_cast<std::uint32_t>(value);
}

// Writes the events waiting in the log as JSON lines. Their t_ns is the bus's time line
// (CLOCK_MONOTONIC / slow_motion): written back on CLOCK_MONOTONIC (to within slow_motion ns),
// so other processes' monotonic times compare with it.
void drain_events(sd::EventLog& log, std::ostream* out, std::int64_t slow_motion) {
  sd::DriveEvent event;
  while (log.pop(event)) {
    event.t_ns *= slow_motion;
    if (out != nullptr) *out << sd::to_json(event) << '\n';
  }
  if (out != nullptr) out->flush();
}

// Reading the terminal from a background job would stop the process (SIGTTIN).
bool stdin_usable() {
  if (::isatty(STDIN_FILENO) == 0) return true;
  return ::tcgetpgrp(STDIN_FILENO) == ::getpgrp();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{
      "simdrive: simulated CiA 402 servo drives (one CANopen node per joint) on a SocketCAN bus"};
  std::string scene_file;
  std::string device_file;
  std::string interface;
  std::vector<std::string> fault_texts;
  std::string events_file;
  std::string vendor_text;
  std::string product_text;
  double rated_torque_scale = 1.0;
  double exit_after_idle_s = 0.0;
  double max_seconds = 0.0;
  bool no_stdin = false;
  int inherited_fd = -1;
  std::int64_t period_us = 0;
  std::int64_t slow_motion = 1;
  cli.add_option("--scene", scene_file, "scene file: its trainee script is the simulated hand")
      ->required()
      ->check(CLI::ExistingFile);
  cli.add_option("--device", device_file,
                 "CANopen device file (default: the scene's own); its drives, bus and mechanism "
                 "are simulated")
      ->check(CLI::ExistingFile);
  cli.add_option("--interface", interface,
                 "SocketCAN interface (default: the device file's canopen.interface)");
  cli.add_option(
      "--fault", fault_texts,
      "fault SPEC, repeatable, e.g. emcy:node=3,at_sync=500,code=0x2310 (docs/simdrive.md)");
  cli.add_option("--events", events_file, "write the events log here as JSON lines ('-' = stdout)");
  cli.add_option("--vendor-id", vendor_text,
                 "every drive reports this vendor id (0x1018:1) instead of the file's");
  cli.add_option("--product-code", product_text,
                 "every drive reports this product code (0x1018:2)");
  cli.add_option("--rated-torque-scale", rated_torque_scale,
                 "every drive reports its motor rated torque (0x6076) times this")
      ->check(CLI::PositiveNumber);
  cli.add_option("--exit-after-idle", exit_after_idle_s,
                 "exit when nothing was received for this many seconds after the first frame")
      ->check(CLI::PositiveNumber);
  cli.add_option(
         "--period-us", period_us,
         "the trainer's loop period when it runs with --period-us (plant time per SYNC when "
         "canopen.sync_period_us = 0); default: the scene's loop.period_us")
      ->check(CLI::Range(std::int64_t{50}, std::int64_t{100000}));
  cli.add_option(
         "--slow-motion", slow_motion,
         "protocol time = CLOCK_MONOTONIC / N, as the trainer's --slow-motion N (emulators)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1000}));
  cli.add_option("--max-seconds", max_seconds, "exit after this many seconds")
      ->check(CLI::PositiveNumber);
  cli.add_flag("--no-stdin", no_stdin, "do not read fault SPECs from stdin");
  std::vector<std::string> miswire_texts;
  std::vector<std::string> node_map_texts;
  cli.add_option("--miswire", miswire_texts,
                 "a wrongly wired drive (repeatable): reverse_encoder:node=N (position actual "
                 "negated), reverse_motor:node=N (torque turns the joint the other way)");
  cli.add_option("--node-id-map", node_map_texts,
                 "FILE_ID=BUS_ID (repeatable): the drive the file calls node FILE_ID answers as "
                 "node BUS_ID");
  cli.add_option(
         "--fd", inherited_fd,
         "tests: use this inherited descriptor (socketpair carrying struct can_frame) instead of "
         "a SocketCAN interface")
      ->check(CLI::NonNegativeNumber);
  CLI11_PARSE(cli, argc, argv);

  ts::IdentityOverrides overrides;
  overrides.rated_torque_scale = rated_torque_scale;
  if (!vendor_text.empty()) {
    overrides.vendor_id = parse_u32(vendor_text);
    if (!overrides.vendor_id) {
      std::cerr << "simdrive: --vendor-id " << vendor_text
                << ": expected a 32-bit number (0x... for hex)\n";
      return 2;
    }
  }
  if (!product_text.empty()) {
    overrides.product_code = parse_u32(product_text);
    if (!overrides.product_code) {
      std::cerr << "simdrive: --product-code " << product_text
                << ": expected a 32-bit number (0x... for hex)\n";
      return 2;
    }
  }
  ts::Miswiring miswiring;
  for (const std::string& text : miswire_texts) {
    if (auto parsed = ts::parse_miswire(text, miswiring); !parsed) {
      std::cerr << "simdrive: " << parsed.error().message << '\n';
      return 2;
    }
  }
  for (const std::string& text : node_map_texts) {
    if (auto parsed = ts::parse_node_id_map(text, miswiring); !parsed) {
      std::cerr << "simdrive: " << parsed.error().message << '\n';
      return 2;
    }
  }
  std::vector<sd::FaultSpec> faults;
  for (const std::string& text : fault_texts) {
    auto spec = sd::parse_fault_spec(text);
    if (!spec) {
      std::cerr << "simdrive: --fault: " << spec.error().message << '\n';
      return 2;
    }
    faults.push_back(*spec);
  }

  std::optional<std::filesystem::path> device_path;
  if (!device_file.empty()) device_path = device_file;
  auto scene = ts::load_scene_with_device(scene_file, device_path);
  if (!scene) {
    std::cerr << "simdrive: " << scene.error().message << '\n';
    return 1;
  }
  const std::int64_t loop_period_ns = period_us > 0 ? period_us * 1000 : scene->loop.period_ns;
  auto params =
      ts::bus_params_from(scene->device, scene->trainee.script, loop_period_ns, overrides);
  if (!params) {
    std::cerr << "simdrive: " << params.error().message << '\n';
    return 1;
  }
  if (auto miswired = ts::apply_miswiring(miswiring, *params); !miswired) {
    std::cerr << "simdrive: " << miswired.error().message << '\n';
    return 2;
  }
  if (interface.empty()) interface = scene->device.canopen.interface;
  trainer::hal::socketcan::SocketCanOptions options;
  options.error_frames = false;  // the drives do not read bus errors; receive every frame
  if (inherited_fd >= 0) interface = "fd " + std::to_string(inherited_fd);
  auto transport =
      inherited_fd >= 0
          ? trainer::hal::socketcan::CanTransport::from_fd(inherited_fd, interface)
          : trainer::hal::socketcan::CanTransport::open_socketcan(interface, {}, options);
  if (!transport) {
    std::cerr << "simdrive: " << transport.error().message << '\n';
    return 1;
  }
  const int can_fd = transport->fd();
  auto bus = sd::SimDriveBus::create(std::move(*params), std::move(*transport));
  if (!bus) {
    std::cerr << "simdrive: " << bus.error().message << '\n';
    return 1;
  }
  sd::SimDriveBus& drives = **bus;

  std::ofstream events_stream;
  std::ostream* events_out = nullptr;
  if (events_file == "-") {
    events_out = &std::cout;
  } else if (!events_file.empty()) {
    events_stream.open(events_file, std::ios::trunc);
    if (!events_stream) {
      std::cerr << "simdrive: cannot write the events log " << events_file << ": "
                << std::strerror(errno) << '\n';
      return 1;
    }
    events_out = &events_stream;
  }

  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  ::sigprocmask(SIG_BLOCK, &stop_signals, nullptr);
  const int signal_fd = ::signalfd(-1, &stop_signals, SFD_CLOEXEC | SFD_NONBLOCK);
  if (signal_fd < 0) {
    std::cerr << "simdrive: signalfd: " << std::strerror(errno) << '\n';
    return 1;
  }

  std::cerr << "simdrive: " << drives.node_count() << " drives of "
            << scene->device.source_path.string() << " on " << interface << ", plant time per SYNC "
            << drives.params().sync_period_ns / 1000 << " us, trainee " << scene->trainee.script
            << '\n';

  // The bus's time line (the trainer's under --slow-motion) and the program's own real time.
  const auto bus_now = [slow_motion] { return monotonic_ns() / slow_motion; };
  const std::int64_t start_ns = monotonic_ns();
  drives.power_on(bus_now());
  for (const sd::FaultSpec& spec : faults) {
    if (const auto status = drives.inject(spec, bus_now()); !status) {
      std::cerr << "simdrive: --fault " << sd::format_fault_spec(spec) << ": " << status.detail()
                << '\n';
      return 2;
    }
  }

  bool read_stdin = !no_stdin && stdin_usable();
  std::string stdin_buffer;
  std::uint64_t frames_seen = 0;
  std::int64_t last_frame_ns = start_ns;
  const auto idle_limit_ns = static_cast<std::int64_t>(exit_after_idle_s * 1e9);
  const auto max_ns = static_cast<std::int64_t>(max_seconds * 1e9);
  const char* end_reason = "signal";
  for (;;) {
    const std::int64_t polled_at = bus_now();
    const std::int64_t deadline = drives.poll(polled_at);
    drain_events(drives.events(), events_out, slow_motion);
    // Real nanoseconds until the bus's next deadline.
    const std::int64_t until_deadline_ns =
        deadline >= std::numeric_limits<std::int64_t>::max() / 2
            ? std::numeric_limits<std::int64_t>::max() / 2
            : std::max<std::int64_t>(0, deadline - bus_now()) * slow_motion;
    const std::int64_t now = monotonic_ns();
    if (drives.stats().frames_received != frames_seen) {
      frames_seen = drives.stats().frames_received;
      last_frame_ns = now;
    }
    if (max_ns > 0 && now - start_ns >= max_ns) {
      end_reason = "--max-seconds";
      break;
    }
    if (idle_limit_ns > 0 && frames_seen > 0 && now - last_frame_ns >= idle_limit_ns) {
      end_reason = "--exit-after-idle";
      break;
    }
    std::int64_t wait_ns = until_deadline_ns;
    if (max_ns > 0) wait_ns = std::min(wait_ns, start_ns + max_ns - now);
    if (idle_limit_ns > 0 && frames_seen > 0)
      wait_ns = std::min(wait_ns, last_frame_ns + idle_limit_ns - now);
    wait_ns = std::clamp<std::int64_t>(wait_ns, 0, 1'000'000'000);
    std::array<pollfd, 3> fds{
        {{can_fd, POLLIN, 0}, {signal_fd, POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}}};
    const timespec timeout{static_cast<time_t>(wait_ns / 1'000'000'000),
                           static_cast<long>(wait_ns % 1'000'000'000)};
    const nfds_t count = read_stdin ? 3 : 2;
    if (::ppoll(fds.data(), count, &timeout, nullptr) < 0 && errno != EINTR) {
      std::cerr << "simdrive: ppoll: " << std::strerror(errno) << '\n';
      break;
    }
    if ((fds[1].revents & POLLIN) != 0) break;
    if (read_stdin && (fds[2].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
      std::array<char, 512> chunk{};
      const ssize_t got = ::read(STDIN_FILENO, chunk.data(), chunk.size());
      if (got <= 0) {
        read_stdin = false;  // EOF: keep running without commands
      } else {
        stdin_buffer.append(chunk.data(), static_cast<std::size_t>(got));
        std::size_t newline = 0;
        while ((newline = stdin_buffer.find('\n')) != std::string::npos) {
          const std::string line = stdin_buffer.substr(0, newline);
          stdin_buffer.erase(0, newline + 1);
          if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
          auto spec = sd::parse_fault_spec(line);
          if (!spec) {
            std::cerr << "simdrive: " << spec.error().message << '\n';
            continue;
          }
          sd::FaultSpec immediate = *spec;  // a command acts now, whatever its schedule keys say
          if (immediate.scheduled()) {
            std::cerr << "simdrive: " << line << ": at_sync/at_s ignored on stdin: applied now\n";
            immediate.at_sync.reset();
            immediate.at_ns.reset();
          }
          if (const auto status = drives.inject(immediate, bus_now()); !status) {
            std::cerr << "simdrive: " << line << ": " << status.detail() << '\n';
          } else {
            std::cerr << "simdrive: applied " << sd::format_fault_spec(immediate) << '\n';
          }
        }
      }
    }
  }
  drain_events(drives.events(), events_out, slow_motion);
  ::close(signal_fd);
  std::cout << "simdrive: stopped (" << end_reason << ") after "
            << static_cast<double>(monotonic_ns() - start_ns) * 1e-9 << " s\n"
            << drives.summary();
  return 0;
}
