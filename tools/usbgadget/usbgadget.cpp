// usbgadget: the trainer's USB haptic interface (docs/usb-protocol.md), emulated on Linux's USB
// gadget stack through FunctionFS, with the simulated bench's plant behind it (docs/usb.md).
// The trainer's libusb backend (or any host) talks to it as to a real interface: in the bench VM
// over dummy_hcd, on a board with a USB device controller (a Raspberry Pi's dwc2) over a cable.
//
//   usbgadget --scene config/scenes/cbd.toml [--device FILE] [--script S] [--udc NAME]
//             [--gadget-name NAME] [--serial S] [--ffs-dir DIR] [--no-configfs] [--remove-stale]
//             [--watchdog-ms N] [--period-us N] [--slow-motion N] [--events FILE|-]
//             [--exit-after-idle S] [--max-seconds S]
//
// Threads: main (ep0 events and control requests, the watchdog, signals, events file), one that
// reads OUT reports from the OUT endpoint file and runs the emulator on each, one that writes IN
// reports to the IN endpoint file (the newest waiting report; blocking while the host does not
// poll, which must not stop the watchdog). The emulator is shared under a mutex. Endpoint I/O
// blocks in the kernel; shutdown interrupts it with SIGUSR1 (a handler without SA_RESTART).
//
// Exit status: 0 ended by a signal or a limit, 1 setup error (files, configfs, mount, UDC), 2
// usage error.
#include <endian.h>
#include <fcntl.h>
#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/eventfd.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "ffs_descriptors.hpp"
#include "gadget_setup.hpp"
#include "haptic_emulator.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/clock.hpp"

namespace {

namespace up = trainer::hal::usbproto;
namespace ug = trainer::tools::usbgadget;

std::int64_t monotonic_ns() {
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

std::string json_escape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

void on_interrupt_signal(int) {}

// Writes a whole buffer to a FunctionFS file; throws naming the file.
void write_ep0_blob(int fd, const std::string& path, const std::vector<std::uint8_t>& blob,
                    const char* what) {
  const ssize_t written = ::write(fd, blob.data(), blob.size());
  if (written != static_cast<ssize_t>(blob.size())) {
    const int error = errno;
    throw std::runtime_error(path + ": writing the " + what + " (" + std::to_string(blob.size()) +
                             " bytes): " + (written < 0 ? std::strerror(error) : "short write"));
  }
}

int open_or_throw(const std::string& path, int flags) {
  const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    throw std::runtime_error(path + ": open: " + std::strerror(error));
  }
  return fd;
}

// Everything the threads share.
struct Shared {
  std::mutex mutex;  // guards emulator, events, pending_in
  ug::HapticEmulator* emulator = nullptr;
  std::condition_variable in_ready;
  std::optional<std::array<std::uint8_t, up::kReportSize>> pending_in;
  std::atomic<bool> stop{false};
  std::atomic<bool> reader_done{false};
  std::atomic<bool> writer_done{false};
  std::atomic<std::int64_t> last_out_ns{0};  // real CLOCK_MONOTONIC of the last OUT transfer
  std::atomic<std::uint64_t> out_transfers{0};
  std::atomic<std::uint64_t> in_written{0};
  std::atomic<std::uint64_t> in_overwritten{0};   // replaced before the host polled
  std::atomic<std::uint64_t> io_shutdowns{0};     // ESHUTDOWN: the host disabled the interface
  std::atomic<std::uint64_t> io_errors{0};
  std::vector<std::string> io_messages;           // first few I/O errors, for the events file
  // Written when an applied report moved the watchdog deadline earlier (armed, or a shorter
  // watchdog in force): the main thread may be sleeping towards the old one.
  int wake_fd = -1;
};

void post_in(Shared& shared, const up::InReport& report) {
  std::array<std::uint8_t, up::kReportSize> bytes{};
  if (up::encode(report, bytes) != up::kReportSize) return;  // cannot happen: counts wrapped
  if (shared.pending_in) shared.in_overwritten.fetch_add(1);
  shared.pending_in = bytes;
  shared.in_ready.notify_one();
}

void note_io_error(Shared& shared, const std::string& text) {
  shared.io_errors.fetch_add(1);
  std::lock_guard lock(shared.mutex);
  if (shared.io_messages.size() < 20) shared.io_messages.push_back(text);
}

void out_reader(Shared& shared, int fd, const std::string& path, trainer::core::Clock& clock) {
  std::array<std::uint8_t, up::kReportSize> buffer{};
  while (!shared.stop.load()) {
    const ssize_t got = ::read(fd, buffer.data(), buffer.size());
    if (got < 0) {
      const int error = errno;
      if (error == EINTR) continue;
      if (error == ESHUTDOWN) {
        shared.io_shutdowns.fetch_add(1);
        continue;  // the next read waits for the host to enable the interface again
      }
      note_io_error(shared, path + ": read: " + std::strerror(error));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    shared.out_transfers.fetch_add(1);
    shared.last_out_ns.store(monotonic_ns());
    const std::int64_t now = clock.now_ns();
    std::lock_guard lock(shared.mutex);
    up::InReport in;
    const std::int64_t deadline_before = shared.emulator->next_deadline_ns();
    if (shared.emulator->on_out_report(std::span(buffer.data(), static_cast<std::size_t>(got)), now, in)) {
      post_in(shared, in);
    }
    if (shared.emulator->next_deadline_ns() < deadline_before) {
      const std::uint64_t one = 1;
      (void)::write(shared.wake_fd, &one, sizeof(one));
    }
  }
  shared.reader_done.store(true);
}

void in_writer(Shared& shared, int fd, const std::string& path) {
  while (!shared.stop.load()) {
    std::array<std::uint8_t, up::kReportSize> bytes{};
    {
      std::unique_lock lock(shared.mutex);
      shared.in_ready.wait(lock, [&] { return shared.stop.load() || shared.pending_in.has_value(); });
      if (shared.stop.load()) break;
      bytes = *shared.pending_in;
      shared.pending_in.reset();
    }
    for (;;) {
      const ssize_t written = ::write(fd, bytes.data(), bytes.size());
      if (written == static_cast<ssize_t>(bytes.size())) {
        shared.in_written.fetch_add(1);
        break;
      }
      const int error = errno;
      if (written < 0 && error == EINTR && !shared.stop.load()) continue;
      if (written < 0 && error == ESHUTDOWN) {
        shared.io_shutdowns.fetch_add(1);
      } else if (!(written < 0 && error == EINTR)) {
        note_io_error(shared, path + ": write: " + (written < 0 ? std::strerror(error) : "short write"));
      }
      break;  // this report is dropped; the next one is newer anyway
    }
  }
  shared.writer_done.store(true);
}

// Interrupts a thread blocked in endpoint I/O until it has left its loop.
void stop_thread(std::thread& thread, const std::atomic<bool>& done, Shared& shared) {
  if (!thread.joinable()) return;
  for (int i = 0; i < 200 && !done.load(); ++i) {
    shared.in_ready.notify_all();
    ::pthread_kill(thread.native_handle(), SIGUSR1);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (done.load()) {
    thread.join();
  } else {
    thread.detach();  // stuck in the kernel: leave it, the process ends anyway
    std::cerr << "usbgadget: an endpoint thread did not stop within 1 s\n";
  }
}

const char* event_name(std::uint8_t type) {
  switch (type) {
    case FUNCTIONFS_BIND: return "bind";
    case FUNCTIONFS_UNBIND: return "unbind";
    case FUNCTIONFS_ENABLE: return "enable";
    case FUNCTIONFS_DISABLE: return "disable";
    case FUNCTIONFS_SETUP: return "setup";
    case FUNCTIONFS_SUSPEND: return "suspend";
    case FUNCTIONFS_RESUME: return "resume";
  }
  return "unknown";
}

class EventsFile {
 public:
  explicit EventsFile(std::ostream* out) : out_(out) {}
  void write(std::int64_t t_ns, const std::string& kind, const std::string& detail) {
    if (out_ == nullptr) return;
    *out_ << "{\"t_ns\":" << t_ns << ",\"event\":\"" << json_escape(kind) << "\",\"detail\":\""
          << json_escape(detail) << "\"}\n";
    out_->flush();
  }

 private:
  std::ostream* out_;
};

struct ControlStats {
  std::uint64_t identity_requests = 0;
  std::uint64_t watchdog_requests = 0;
  std::uint64_t stalled = 0;
  std::uint64_t enables = 0;
  std::uint64_t disables = 0;
};

// Answers one SETUP event on ep0 (docs/usb-protocol.md "Control requests").
void handle_setup(int ep0, const usb_ctrlrequest& setup, Shared& shared, EventsFile& events,
                  ControlStats& stats, std::int64_t now) {
  const std::uint8_t type = setup.bRequestType;
  const std::uint16_t value = le16toh(setup.wValue);
  const std::uint16_t length = le16toh(setup.wLength);
  std::array<std::uint8_t, 8> scratch{};
  if (type == up::kRequestTypeVendorInterfaceIn && setup.bRequest == up::kRequestGetIdentity) {
    std::array<std::uint8_t, up::kIdentitySize> bytes{};
    {
      std::lock_guard lock(shared.mutex);
      (void)up::encode(shared.emulator->identity(), bytes);
    }
    const std::size_t count = std::min<std::size_t>(length, bytes.size());
    ++stats.identity_requests;
    if (::write(ep0, bytes.data(), count) < 0) {
      events.write(now, "ep0_error", std::string("identity answer: ") + std::strerror(errno));
    }
    return;
  }
  if (type == up::kRequestTypeVendorInterfaceOut && setup.bRequest == up::kRequestSetWatchdog &&
      length == 0) {
    bool accepted = false;
    {
      std::lock_guard lock(shared.mutex);
      accepted = shared.emulator->set_watchdog_ms(value);
    }
    if (accepted) {
      ++stats.watchdog_requests;
      (void)::read(ep0, scratch.data(), 0);  // status stage: acknowledge
      events.write(now, "set_watchdog", std::to_string(value) + " ms");
      return;
    }
  }
  // Anything else: stall (I/O in the direction opposite to the data stage).
  ++stats.stalled;
  char text[96];
  std::snprintf(text, sizeof(text), "bmRequestType 0x%02x bRequest 0x%02x wValue %u wLength %u",
                static_cast<unsigned>(type), static_cast<unsigned>(setup.bRequest),
                static_cast<unsigned>(value), static_cast<unsigned>(length));
  events.write(now, "setup_stalled", text);
  if ((type & USB_DIR_IN) != 0) {
    (void)::read(ep0, scratch.data(), 0);
  } else {
    (void)::write(ep0, scratch.data(), 0);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"usbgadget: the trainer's USB haptic interface emulated through FunctionFS, with the "
               "simulated bench's plant behind it"};
  std::string scene_file;
  std::string device_file;
  std::string script;
  std::string udc;
  std::string gadget_name = "trainer_haptic";
  std::string serial = "usbgadget-0001";
  std::string ffs_dir;
  bool no_configfs = false;
  bool remove_stale = false;
  int watchdog_ms = ug::kDefaultWatchdogMs;
  std::int64_t period_us = 0;
  std::int64_t slow_motion = 1;
  std::string events_file;
  double exit_after_idle_s = 0.0;
  double max_seconds = 0.0;
  std::string configfs_root = "/sys/kernel/config/usb_gadget";
  cli.add_option("--scene", scene_file, "scene file: its trainee script is the simulated hand, its "
                                        "loop period the plant time per exchange")
      ->required()
      ->check(CLI::ExistingFile);
  cli.add_option("--device", device_file,
                 "device file whose mechanism is simulated (default: the scene's own; its backend "
                 "kind is ignored)")
      ->check(CLI::ExistingFile);
  cli.add_option("--script", script, "trainee script instead of the scene's (builtin:hold, "
                                     "builtin:sweep or a trajectory CSV)");
  cli.add_option("--udc", udc, "USB device controller to bind (default: the only one in "
                               "/sys/class/udc; the bench VM's is dummy_udc.0)");
  cli.add_option("--gadget-name", gadget_name,
                 "configfs gadget and FunctionFS instance name ([A-Za-z0-9_], default "
                 "trainer_haptic)");
  cli.add_option("--serial", serial, "USB serial number string (default usbgadget-0001)");
  cli.add_option("--ffs-dir", ffs_dir, "where functionfs is mounted (default "
                                       "/run/usbgadget/<gadget-name>)");
  cli.add_flag("--no-configfs", no_configfs,
               "do not create, mount or bind anything: serve an existing functionfs mount "
               "(--ffs-dir) of a gadget set up and bound by someone else");
  cli.add_flag("--remove-stale", remove_stale,
               "first take apart a gadget of the same name left by a killed usbgadget (unbind, "
               "unmount, remove)");
  cli.add_option("--watchdog-ms", watchdog_ms, "device watchdog (SET_WATCHDOG changes it)")
      ->check(CLI::Range(static_cast<int>(up::kMinWatchdogMs), static_cast<int>(up::kMaxWatchdogMs)));
  cli.add_option("--period-us", period_us,
                 "plant time per exchange (default: the scene's loop.period_us)")
      ->check(CLI::Range(std::int64_t{50}, std::int64_t{100000}));
  cli.add_option("--slow-motion", slow_motion,
                 "the watchdog runs on CLOCK_MONOTONIC / N, as the trainer's --slow-motion N")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{1000}));
  cli.add_option("--events", events_file, "write events as JSON lines here ('-' = stdout)");
  cli.add_option("--exit-after-idle", exit_after_idle_s,
                 "exit when no OUT report came for this many seconds after the first")
      ->check(CLI::PositiveNumber);
  cli.add_option("--max-seconds", max_seconds, "exit after this many seconds")
      ->check(CLI::PositiveNumber);
  cli.add_option("--configfs-root", configfs_root, "where configfs USB gadgets live")
      ->default_val(configfs_root);
  CLI11_PARSE(cli, argc, argv);

  if (gadget_name.empty() || gadget_name.size() > 32 ||
      !std::all_of(gadget_name.begin(), gadget_name.end(),
                   [](char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; })) {
    std::cerr << "usbgadget: --gadget-name \"" << gadget_name
              << "\": expected 1..32 characters [A-Za-z0-9_]\n";
    return 2;
  }
  if (serial.empty() || serial.size() > 126) {
    std::cerr << "usbgadget: --serial: expected 1..126 characters\n";
    return 2;
  }
  if (ffs_dir.empty()) {
    if (no_configfs) {
      std::cerr << "usbgadget: --no-configfs needs --ffs-dir (the existing functionfs mount)\n";
      return 2;
    }
    ffs_dir = "/run/usbgadget/" + gadget_name;
  }

  // --- the plant ---
  trainer::config::LoadOptions load_options;
  if (!device_file.empty()) load_options.device_file = device_file;
  auto scene = trainer::config::load_scene(scene_file, load_options);
  if (!scene) {
    std::cerr << "usbgadget: " << scene.error().message << '\n';
    return 1;
  }
  ug::EmulatorParams params;
  params.plant = trainer::app::sim_params_from(scene->device, script.empty() ? scene->trainee.script : script);
  if (params.plant.plant_substep_ns <= 0) params.plant.plant_substep_ns = 100'000;
  // The emulated interface is wired right, as simdrive's drives are: the device file's
  // encoder_direction / motor_direction describe the host's view of a bench and are what hil
  // check measures, not the emulator's wiring.
  for (auto& instrument : params.plant.instruments) {
    for (auto& scale : instrument.scales) {
      scale.encoder_direction = 1;
      scale.motor_direction = 1;
    }
  }
  params.frame_ns = period_us > 0 ? period_us * 1000 : scene->loop.period_ns;
  params.watchdog_ms = static_cast<std::uint16_t>(watchdog_ms);
  ug::HapticEmulator emulator(std::move(params));
  if (auto configured = emulator.configure(); !configured) {
    std::cerr << "usbgadget: " << scene->device.source_path.string() << ": "
              << configured.error().message << '\n';
    return 1;
  }

  std::ofstream events_stream;
  std::ostream* events_out = nullptr;
  if (events_file == "-") {
    events_out = &std::cout;
  } else if (!events_file.empty()) {
    events_stream.open(events_file, std::ios::trunc);
    if (!events_stream) {
      std::cerr << "usbgadget: cannot write the events file " << events_file << ": "
                << std::strerror(errno) << '\n';
      return 1;
    }
    events_out = &events_stream;
  }
  EventsFile events(events_out);

  // --- signals: SIGINT/SIGTERM through a signalfd (blocked in every thread), SIGUSR1 interrupts
  // endpoint I/O ---
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  ::pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  const int signal_fd = ::signalfd(-1, &stop_signals, SFD_CLOEXEC | SFD_NONBLOCK);
  if (signal_fd < 0) {
    std::cerr << "usbgadget: signalfd: " << std::strerror(errno) << '\n';
    return 1;
  }
  struct sigaction interrupt {};
  interrupt.sa_handler = on_interrupt_signal;
  sigemptyset(&interrupt.sa_mask);
  interrupt.sa_flags = 0;  // no SA_RESTART: blocked read()/write() return EINTR
  ::sigaction(SIGUSR1, &interrupt, nullptr);

  std::unique_ptr<trainer::core::Clock> clock;
  if (slow_motion > 1) {
    clock = std::make_unique<trainer::core::SlowMotionClock>(slow_motion);
  } else {
    clock = std::make_unique<trainer::core::MonotonicClock>();
  }

  Shared shared;
  shared.emulator = &emulator;
  shared.wake_fd = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  if (shared.wake_fd < 0) {
    std::cerr << "usbgadget: eventfd: " << std::strerror(errno) << '\n';
    return 1;
  }
  std::optional<ug::ConfigfsGadget> gadget;
  int ep0 = -1;
  int ep_in = -1;
  int ep_out = -1;
  std::thread reader;
  std::thread writer;
  ControlStats control;
  const std::int64_t start_ns = monotonic_ns();
  int exit_status = 0;
  const char* end_reason = "signal";
  const std::string ep0_path = ffs_dir + "/ep0";

  try {
    if (!no_configfs) {
      if (remove_stale && std::filesystem::exists(std::filesystem::path(configfs_root) / gadget_name)) {
        ug::remove_stale_gadget(std::filesystem::path(configfs_root) / gadget_name, ffs_dir);
        events.write(monotonic_ns(), "stale_gadget_removed", configfs_root + "/" + gadget_name);
        std::cerr << "usbgadget: removed the stale gadget " << configfs_root << "/" << gadget_name << '\n';
      }
      gadget.emplace(configfs_root, gadget_name, ffs_dir);
      ug::GadgetIdentity identity;
      identity.vendor_id = up::kVendorId;
      identity.product_id = up::kProductId;
      identity.bcd_device = ug::kFirmwareVersion;
      identity.manufacturer = "trainer";
      identity.product = "trainer haptic interface";
      identity.serial = serial;
      identity.configuration = "haptic";
      gadget->create(identity);
      events.write(monotonic_ns(), "gadget_created",
                   gadget->gadget_dir().string() + ", functionfs on " + ffs_dir);
    }
    ep0 = open_or_throw(ep0_path, O_RDWR);
    write_ep0_blob(ep0, ep0_path, ug::ffs_descriptors(), "descriptors");
    write_ep0_blob(ep0, ep0_path, ug::ffs_strings(), "strings");
    const std::string in_path = ffs_dir + "/" + ug::kInEndpointFile;
    const std::string out_path = ffs_dir + "/" + ug::kOutEndpointFile;
    ep_in = open_or_throw(in_path, O_RDWR);
    ep_out = open_or_throw(out_path, O_RDWR);

    // The endpoint threads inherit the blocked SIGINT/SIGTERM; SIGUSR1 stays deliverable.
    reader = std::thread(out_reader, std::ref(shared), ep_out, out_path, std::ref(*clock));
    writer = std::thread(in_writer, std::ref(shared), ep_in, in_path);

    if (gadget) {
      if (udc.empty()) {
        const std::vector<std::string> udcs = ug::list_udcs();
        if (udcs.size() != 1) {
          std::string names;
          for (const auto& name : udcs) names += (names.empty() ? "" : ", ") + name;
          throw std::runtime_error(
              "/sys/class/udc: " + std::to_string(udcs.size()) +
              " USB device controllers (" + (names.empty() ? "none: load dummy_hcd or the board's UDC driver" : names) +
              "): name one with --udc");
        }
        udc = udcs[0];
      }
      gadget->bind(udc);
      events.write(monotonic_ns(), "bound", udc);
    }
    std::cerr << "usbgadget: " << emulator.channel_count() << " channels of "
              << scene->device.source_path.string() << ", serial " << serial << ", "
              << (gadget ? "bound to " + udc : "on " + ffs_dir) << ", plant time per exchange "
              << emulator.identity().frame_interval_us << " us, watchdog " << emulator.watchdog_ms()
              << " ms" << (slow_motion > 1 ? " (slow motion x" + std::to_string(slow_motion) + ")" : "")
              << '\n';

    // --- main loop: ep0 events, the watchdog, limits, signals ---
    const auto idle_limit_ns = static_cast<std::int64_t>(exit_after_idle_s * 1e9);
    const auto max_ns = static_cast<std::int64_t>(max_seconds * 1e9);
    std::size_t io_messages_written = 0;
    for (;;) {
      const std::int64_t now_real = monotonic_ns();
      std::int64_t wait_ns = 100'000'000;
      {
        std::lock_guard lock(shared.mutex);
        up::InReport in;
        const std::int64_t now = clock->now_ns();
        if (emulator.on_time(now, in)) post_in(shared, in);
        const std::int64_t deadline = emulator.next_deadline_ns();
        if (deadline != std::numeric_limits<std::int64_t>::max()) {
          wait_ns = std::min(wait_ns, std::max<std::int64_t>(0, deadline - now) * slow_motion);
        }
        for (const ug::EmulatorEvent& event : emulator.take_events()) {
          events.write(event.t_ns * slow_motion, event.kind, event.detail);
        }
        for (; io_messages_written < shared.io_messages.size(); ++io_messages_written) {
          events.write(now_real, "io_error", shared.io_messages[io_messages_written]);
        }
      }
      if (max_ns > 0 && now_real - start_ns >= max_ns) {
        end_reason = "--max-seconds";
        break;
      }
      const std::int64_t last_out = shared.last_out_ns.load();
      if (idle_limit_ns > 0 && last_out > 0 && now_real - last_out >= idle_limit_ns) {
        end_reason = "--exit-after-idle";
        break;
      }
      if (max_ns > 0) wait_ns = std::min(wait_ns, start_ns + max_ns - now_real);
      if (idle_limit_ns > 0 && last_out > 0) wait_ns = std::min(wait_ns, last_out + idle_limit_ns - now_real);
      wait_ns = std::clamp<std::int64_t>(wait_ns, 0, 100'000'000);
      std::array<pollfd, 3> fds{{{ep0, POLLIN, 0}, {signal_fd, POLLIN, 0}, {shared.wake_fd, POLLIN, 0}}};
      const timespec timeout{static_cast<time_t>(wait_ns / 1'000'000'000),
                             static_cast<long>(wait_ns % 1'000'000'000)};
      if (::ppoll(fds.data(), fds.size(), &timeout, nullptr) < 0 && errno != EINTR) {
        throw std::runtime_error(std::string("ppoll: ") + std::strerror(errno));
      }
      if ((fds[1].revents & POLLIN) != 0) break;
      if ((fds[2].revents & POLLIN) != 0) {
        std::uint64_t wakes = 0;
        (void)::read(shared.wake_fd, &wakes, sizeof(wakes));
      }
      if ((fds[0].revents & POLLIN) == 0) continue;
      std::array<usb_functionfs_event, 4> ffs_events{};
      const ssize_t got = ::read(ep0, ffs_events.data(), sizeof(ffs_events));
      if (got < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        throw std::runtime_error(ep0_path + ": read events: " + std::strerror(errno));
      }
      const std::size_t count = static_cast<std::size_t>(got) / sizeof(usb_functionfs_event);
      for (std::size_t i = 0; i < count; ++i) {
        const usb_functionfs_event& event = ffs_events[i];
        const std::int64_t now = monotonic_ns();
        if (event.type == FUNCTIONFS_SETUP) {
          handle_setup(ep0, event.u.setup, shared, events, control, now);
          continue;
        }
        if (event.type == FUNCTIONFS_ENABLE) ++control.enables;
        if (event.type == FUNCTIONFS_DISABLE) ++control.disables;
        events.write(now, event_name(event.type), "");
      }
    }
  } catch (const std::exception& error) {
    std::cerr << "usbgadget: " << error.what() << '\n';
    events.write(monotonic_ns(), "error", error.what());
    exit_status = 1;
    end_reason = "error";
  }

  // --- shutdown: unbind (the host sees a disconnect), stop the threads, remove what we made ---
  if (gadget) {
    if (std::string failed = gadget->unbind(); !failed.empty()) {
      std::cerr << "usbgadget: unbind: " << failed << '\n';
    }
  }
  shared.stop.store(true);
  stop_thread(reader, shared.reader_done, shared);
  stop_thread(writer, shared.writer_done, shared);
  {
    std::lock_guard lock(shared.mutex);  // a thread stuck in the kernel was detached
    for (const ug::EmulatorEvent& event : emulator.take_events()) {
      events.write(event.t_ns * slow_motion, event.kind, event.detail);
    }
  }
  for (int* fd : {&ep_in, &ep_out, &ep0}) {
    if (*fd >= 0) ::close(*fd);
    *fd = -1;
  }
  if (gadget) {
    const std::vector<std::string> failures = gadget->remove();
    for (const std::string& failure : failures) std::cerr << "usbgadget: cleanup: " << failure << '\n';
    events.write(monotonic_ns(), failures.empty() ? "gadget_removed" : "gadget_remove_failed",
                 gadget->gadget_dir().string());
  }
  ::close(signal_fd);
  ::close(shared.wake_fd);

  const ug::EmulatorStats& stats = emulator.stats();
  std::cout << "usbgadget: stopped (" << end_reason << ") after "
            << static_cast<double>(monotonic_ns() - start_ns) * 1e-9 << " s\n"
            << "  OUT transfers " << shared.out_transfers.load() << ", applied " << stats.out_applied
            << ", rejected " << stats.out_rejected << " (wrong channel count "
            << stats.out_wrong_channel_count << ")\n"
            << "  IN reports produced " << stats.in_produced << ", written " << shared.in_written.load()
            << ", replaced before the host polled " << shared.in_overwritten.load() << "\n"
            << "  watchdog trips " << stats.watchdog_trips << ", clears " << stats.clears
            << ", current-limited reports " << stats.current_limited_reports << "\n"
            << "  control: identity " << control.identity_requests << ", set watchdog "
            << control.watchdog_requests << ", stalled " << control.stalled << "; enable "
            << control.enables << ", disable " << control.disables << "; endpoint shutdowns "
            << shared.io_shutdowns.load() << ", I/O errors " << shared.io_errors.load() << "\n"
            << "  plant time " << static_cast<double>(emulator.plant_time_ns()) * 1e-9 << " s\n";
  return exit_status;
}
