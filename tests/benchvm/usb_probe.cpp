// usb_probe: a small libusb host that checks the USB haptic interface (docs/usb-protocol.md) as
// the bench VM's smoke test sees it (tests/benchvm/usb_gadget_test.sh), against tools/usbgadget
// on dummy_hcd or any device that implements the protocol:
//  1. finds VID:PID 1209:0001 with the given serial; it must run at high speed (--speed);
//  2. reads the endpoint addresses, types, sizes and intervals of the class-0xFF interface from
//     the active configuration descriptor (never assumes them);
//  3. GET_IDENTITY by control request; an unknown request and an out-of-range SET_WATCHDOG
//     must stall; SET_WATCHDOG sets the watchdog for the exchange (--exchange-watchdog-ms);
//  4. N synchronous OUT -> IN round trips (64-byte interrupt transfers): every IN report must
//     decode, echo the OUT sequence (out_sequence_applied), count its own sequence up by one,
//     advance device time one frame, report enabled; channel 0 gets --current-ma for the second
//     half and its encoder count must move by at least --min-move counts against the first;
//  4b. optionally (--paced-frames N --period-us P) the host's RT pattern: one OUT per period from
//     a clock_nanosleep loop, IN transfers kept in flight, missed frames (no IN since the last
//     tick), stale reports and round trips counted over N frames;
//  5. the watchdog: SET_WATCHDOG --trip-watchdog-ms, one more enabled report, then no OUT: the
//     next IN report must say watchdog_tripped no earlier than the watchdog; enabled reports are
//     then answered but not applied; clear_watchdog clears it and enable applies again.
// Prints the round-trip figures (min, median, p99, max, rate) and writes them as JSON
// (--json FILE). Exit status 0 all checks passed, 1 a check failed, 2 usage.
#include <libusb-1.0/libusb.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "trainer/hal_usbproto/protocol.hpp"

namespace {

namespace up = trainer::hal::usbproto;

struct Options {
  std::string serial = "usbgadget-0001";
  int exchanges = 1000;
  int current_ma = 1000;
  int min_move = 100;
  int exchange_watchdog_ms = 1000;
  int trip_watchdog_ms = 50;
  std::string speed = "high";
  std::string json;
  int timeout_ms = 5000;
  int paced_frames = 0;    // 0: no paced run
  int period_us = 1000;    // paced run: one OUT report per period
};

int failures = 0;

void check(bool ok, const std::string& what) {
  if (ok) return;
  ++failures;
  std::fprintf(stderr, "usb_probe: FAIL: %s\n", what.c_str());
}

const char* speed_name(int speed) {
  switch (speed) {
    case LIBUSB_SPEED_LOW: return "low";
    case LIBUSB_SPEED_FULL: return "full";
    case LIBUSB_SPEED_HIGH: return "high";
    case LIBUSB_SPEED_SUPER: return "super";
    default: return "unknown";
  }
}

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(p * static_cast<double>(values.size() - 1) + 0.5);
  return values[std::min(index, values.size() - 1)];
}

struct Endpoints {
  int interface_number = -1;
  unsigned char in = 0;
  unsigned char out = 0;
  int in_size = 0;
  int out_size = 0;
  int in_interval = 0;
  int out_interval = 0;
  bool in_interrupt = false;
  bool out_interrupt = false;
};

Endpoints find_endpoints(libusb_device* device) {
  Endpoints found;
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(device, &config) != 0) return found;
  for (int i = 0; i < config->bNumInterfaces; ++i) {
    const libusb_interface& interface = config->interface[i];
    for (int a = 0; a < interface.num_altsetting; ++a) {
      const libusb_interface_descriptor& alt = interface.altsetting[a];
      if (alt.bInterfaceClass != up::kInterfaceClass) continue;
      found.interface_number = alt.bInterfaceNumber;
      for (int e = 0; e < alt.bNumEndpoints; ++e) {
        const libusb_endpoint_descriptor& ep = alt.endpoint[e];
        const bool interrupt = (ep.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) == LIBUSB_TRANSFER_TYPE_INTERRUPT;
        if ((ep.bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN) {
          found.in = ep.bEndpointAddress;
          found.in_size = ep.wMaxPacketSize;
          found.in_interval = ep.bInterval;
          found.in_interrupt = interrupt;
        } else {
          found.out = ep.bEndpointAddress;
          found.out_size = ep.wMaxPacketSize;
          found.out_interval = ep.bInterval;
          found.out_interrupt = interrupt;
        }
      }
    }
  }
  libusb_free_config_descriptor(config);
  return found;
}

class Probe {
 public:
  Probe(libusb_device_handle* handle, const Endpoints& endpoints, const Options& options)
      : handle_(handle), ep_(endpoints), options_(options) {}

  int control_in(std::uint8_t request, unsigned char* data, std::uint16_t length) {
    return libusb_control_transfer(handle_, up::kRequestTypeVendorInterfaceIn, request, 0,
                                   static_cast<std::uint16_t>(ep_.interface_number), data, length,
                                   static_cast<unsigned>(options_.timeout_ms));
  }
  int set_watchdog(int ms) {
    return libusb_control_transfer(handle_, up::kRequestTypeVendorInterfaceOut,
                                   up::kRequestSetWatchdog, static_cast<std::uint16_t>(ms),
                                   static_cast<std::uint16_t>(ep_.interface_number), nullptr, 0,
                                   static_cast<unsigned>(options_.timeout_ms));
  }
  // Sends one OUT report; returns the libusb status.
  int send(std::uint8_t flags, std::uint8_t channels, int channel0_ma) {
    up::OutReport out;
    out.sequence = ++out_sequence_;
    out.flags = flags;
    out.channel_count = channels;
    out.current_ma[0] = static_cast<std::int16_t>(channel0_ma);
    std::array<std::uint8_t, up::kReportSize> bytes{};
    up::encode(out, bytes);
    int transferred = 0;
    const int status = libusb_interrupt_transfer(handle_, ep_.out, bytes.data(), static_cast<int>(bytes.size()),
                                                 &transferred, static_cast<unsigned>(options_.timeout_ms));
    if (status == 0 && transferred != static_cast<int>(bytes.size())) return LIBUSB_ERROR_IO;
    return status;
  }
  // Reads one IN report (timeout_ms); returns the libusb status, decode status in `decoded`.
  int receive(up::InReport& in, up::DecodeStatus& decoded, int timeout_ms) {
    std::array<std::uint8_t, up::kReportSize> bytes{};
    int transferred = 0;
    const int status = libusb_interrupt_transfer(handle_, ep_.in, bytes.data(), static_cast<int>(bytes.size()),
                                                 &transferred, static_cast<unsigned>(timeout_ms));
    if (status != 0) return status;
    decoded = up::decode(std::span<const std::uint8_t>(bytes.data(), static_cast<std::size_t>(transferred)), in);
    return 0;
  }
  std::uint16_t out_sequence() const { return out_sequence_; }
  std::uint16_t skip_sequence() { return ++out_sequence_; }

 private:
  libusb_device_handle* handle_;
  Endpoints ep_;
  Options options_;
  std::uint16_t out_sequence_ = 0;
};

// --- the paced run: the host's RT pattern with transfers kept in flight ------------------------
// One OUT report per period from a clock_nanosleep(TIMER_ABSTIME) loop, two IN transfers always
// submitted (resubmitted from their callback), libusb events handled until the next tick. At
// each tick, before sending: no IN report arrived since the previous tick = a missed frame; the
// newest IN's out_sequence_applied more than 2 behind the last OUT sent = stale. The round trip
// of OUT s is the time from its submission to the first IN report with out_sequence_applied s.
struct PacedRun {
  libusb_context* context = nullptr;
  libusb_device_handle* handle = nullptr;
  unsigned char in_endpoint = 0;
  unsigned char out_endpoint = 0;
  std::array<std::int64_t, 65536> sent_ns{};
  std::uint16_t last_sent = 0;
  bool in_since_tick = false;
  up::InReport newest;
  bool have_newest = false;
  std::uint16_t last_applied_seen = 0;
  std::vector<double> round_trip_us;
  int in_reports = 0;
  int in_decode_errors = 0;
  int in_transfer_errors = 0;
  int out_transfer_errors = 0;
  int out_in_flight = 0;
  int out_skipped_busy = 0;
  bool stopping = false;
  int in_active = 0;
  std::array<int, 8> out_error_status{};  // index = libusb_transfer_status
  std::array<int, 8> in_error_status{};
};

std::int64_t now_ns_monotonic() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

const char* transfer_status_name(int status) {
  switch (status) {
    case LIBUSB_TRANSFER_COMPLETED: return "COMPLETED";
    case LIBUSB_TRANSFER_ERROR: return "ERROR";
    case LIBUSB_TRANSFER_TIMED_OUT: return "TIMED_OUT";
    case LIBUSB_TRANSFER_CANCELLED: return "CANCELLED";
    case LIBUSB_TRANSFER_STALL: return "STALL";
    case LIBUSB_TRANSFER_NO_DEVICE: return "NO_DEVICE";
    case LIBUSB_TRANSFER_OVERFLOW: return "OVERFLOW";
    default: return "?";
  }
}

void LIBUSB_CALL paced_in_done(libusb_transfer* transfer) {
  auto& run = *static_cast<PacedRun*>(transfer->user_data);
  if (transfer->status == LIBUSB_TRANSFER_COMPLETED) {
    up::InReport in;
    if (up::decode(std::span<const std::uint8_t>(transfer->buffer, static_cast<std::size_t>(transfer->actual_length)), in) ==
        up::DecodeStatus::ok) {
      ++run.in_reports;
      run.in_since_tick = true;
      if (!run.have_newest || in.out_sequence_applied != run.last_applied_seen) {
        run.round_trip_us.push_back(static_cast<double>(now_ns_monotonic() - run.sent_ns[in.out_sequence_applied]) * 1e-3);
        run.last_applied_seen = in.out_sequence_applied;
      }
      run.newest = in;
      run.have_newest = true;
    } else {
      ++run.in_decode_errors;
    }
  } else if (transfer->status != LIBUSB_TRANSFER_CANCELLED && transfer->status != LIBUSB_TRANSFER_TIMED_OUT) {
    ++run.in_transfer_errors;
    ++run.in_error_status[static_cast<std::size_t>(transfer->status) & 7U];
  }
  if (run.stopping || libusb_submit_transfer(transfer) != 0) --run.in_active;
}

// user_data of an OUT transfer: the run and the slot's busy flag.
struct OutSlot {
  PacedRun* run = nullptr;
  bool busy = false;
};

void LIBUSB_CALL paced_out_done(libusb_transfer* transfer) {
  auto& slot = *static_cast<OutSlot*>(transfer->user_data);
  slot.busy = false;
  auto& run = *slot.run;
  if (transfer->status != LIBUSB_TRANSFER_COMPLETED) {
    ++run.out_transfer_errors;
    ++run.out_error_status[static_cast<std::size_t>(transfer->status) & 7U];
  }
  --run.out_in_flight;
}

struct PacedResult {
  int frames = 0;
  int missed = 0;
  int stale = 0;
  double seconds = 0.0;
  std::vector<double> round_trip_us;
  int errors = 0;
  int skipped = 0;
};

PacedResult paced_run(libusb_context* context, libusb_device_handle* handle, const Endpoints& ep,
                      std::uint8_t channels, std::uint16_t first_sequence, const Options& options) {
  auto run = std::make_unique<PacedRun>();
  run->context = context;
  run->handle = handle;
  run->last_sent = first_sequence;
  run->round_trip_us.reserve(static_cast<std::size_t>(options.paced_frames));
  std::array<std::array<unsigned char, up::kReportSize>, 2> in_buffers{};
  std::array<libusb_transfer*, 2> in_transfers{};
  for (std::size_t i = 0; i < in_transfers.size(); ++i) {
    in_transfers[i] = libusb_alloc_transfer(0);
    libusb_fill_interrupt_transfer(in_transfers[i], handle, ep.in, in_buffers[i].data(),
                                   static_cast<int>(up::kReportSize), paced_in_done, run.get(), 0);
    if (libusb_submit_transfer(in_transfers[i]) == 0) ++run->in_active;
  }
  constexpr int kOutSlots = 4;
  std::array<std::array<unsigned char, up::kReportSize>, kOutSlots> out_buffers{};
  std::array<libusb_transfer*, kOutSlots> out_transfers{};
  std::array<OutSlot, kOutSlots> out_slots{};
  for (auto& transfer : out_transfers) transfer = libusb_alloc_transfer(0);
  for (auto& slot : out_slots) slot.run = run.get();

  PacedResult result;
  const std::int64_t period_ns = static_cast<std::int64_t>(options.period_us) * 1000;
  std::int64_t tick = now_ns_monotonic() + period_ns;
  const std::int64_t start = now_ns_monotonic();
  for (int frame = 0; frame < options.paced_frames; ++frame) {
    // Events until the tick, then sleep to it exactly.
    for (std::int64_t now = now_ns_monotonic(); now < tick; now = now_ns_monotonic()) {
      timeval timeout{0, static_cast<long>(std::min<std::int64_t>(tick - now, 999'999'000) / 1000)};
      libusb_handle_events_timeout_completed(context, &timeout, nullptr);
    }
    tick += period_ns;
    if (frame > 0) {
      if (!run->in_since_tick) ++result.missed;
      if (run->have_newest && up::sequence_distance(run->last_sent, run->newest.out_sequence_applied) > 2) ++result.stale;
    }
    run->in_since_tick = false;
    std::size_t free_slot = kOutSlots;
    for (std::size_t i = 0; i < kOutSlots && free_slot == kOutSlots; ++i) {
      if (!out_slots[i].busy) free_slot = i;
    }
    if (free_slot == kOutSlots) {
      ++result.skipped;
      continue;
    }
    up::OutReport out;
    out.sequence = static_cast<std::uint16_t>(run->last_sent + 1);
    out.flags = up::kOutFlagEnable;
    out.channel_count = channels;
    auto& buffer = out_buffers[free_slot];
    auto* transfer = out_transfers[free_slot];
    up::encode(out, std::span<std::uint8_t, up::kReportSize>(buffer.data(), up::kReportSize));
    libusb_fill_interrupt_transfer(transfer, handle, ep.out, buffer.data(), static_cast<int>(up::kReportSize),
                                   paced_out_done, &out_slots[free_slot], static_cast<unsigned>(options.timeout_ms));
    run->sent_ns[out.sequence] = now_ns_monotonic();
    if (libusb_submit_transfer(transfer) == 0) {
      out_slots[free_slot].busy = true;
      ++run->out_in_flight;
      run->last_sent = out.sequence;
      ++result.frames;
    } else {
      ++run->out_transfer_errors;
    }
  }
  result.seconds = static_cast<double>(now_ns_monotonic() - start) * 1e-9;
  // Drain: let the last answers arrive, then cancel the IN transfers.
  const std::int64_t drain_until = now_ns_monotonic() + 200'000'000;
  while (now_ns_monotonic() < drain_until && (run->out_in_flight > 0 || run->last_applied_seen != run->last_sent)) {
    timeval timeout{0, 10'000};
    libusb_handle_events_timeout_completed(context, &timeout, nullptr);
  }
  run->stopping = true;
  for (auto* transfer : in_transfers) libusb_cancel_transfer(transfer);
  const std::int64_t cancel_until = now_ns_monotonic() + 2'000'000'000;
  while ((run->in_active > 0 || run->out_in_flight > 0) && now_ns_monotonic() < cancel_until) {
    timeval timeout{0, 10'000};
    libusb_handle_events_timeout_completed(context, &timeout, nullptr);
  }
  for (auto* transfer : in_transfers) libusb_free_transfer(transfer);
  for (auto* transfer : out_transfers) libusb_free_transfer(transfer);
  result.round_trip_us = std::move(run->round_trip_us);
  result.errors = run->in_decode_errors + run->in_transfer_errors + run->out_transfer_errors;
  std::printf("usb_probe: paced: IN reports %d, decode errors %d, IN transfer errors %d, OUT transfer errors %d\n",
              run->in_reports, run->in_decode_errors, run->in_transfer_errors, run->out_transfer_errors);
  for (std::size_t i = 0; i < run->out_error_status.size(); ++i) {
    if (run->out_error_status[i] > 0) {
      std::printf("usb_probe: paced: %d OUT transfers ended %s\n", run->out_error_status[i],
                  transfer_status_name(static_cast<int>(i)));
    }
    if (run->in_error_status[i] > 0) {
      std::printf("usb_probe: paced: %d IN transfers ended %s\n", run->in_error_status[i],
                  transfer_status_name(static_cast<int>(i)));
    }
  }
  return result;
}

bool parse_int(const char* text, int& value) {
  char* end = nullptr;
  const long parsed = std::strtol(text, &end, 10);
  if (end == text || *end != '\0') return false;
  value = static_cast<int>(parsed);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    bool ok = has_value;
    if (arg == "--serial" && has_value) options.serial = argv[++i];
    else if (arg == "--speed" && has_value) options.speed = argv[++i];
    else if (arg == "--json" && has_value) options.json = argv[++i];
    else if (arg == "--exchanges" && has_value) ok = parse_int(argv[++i], options.exchanges);
    else if (arg == "--current-ma" && has_value) ok = parse_int(argv[++i], options.current_ma);
    else if (arg == "--min-move" && has_value) ok = parse_int(argv[++i], options.min_move);
    else if (arg == "--exchange-watchdog-ms" && has_value) ok = parse_int(argv[++i], options.exchange_watchdog_ms);
    else if (arg == "--trip-watchdog-ms" && has_value) ok = parse_int(argv[++i], options.trip_watchdog_ms);
    else if (arg == "--timeout-ms" && has_value) ok = parse_int(argv[++i], options.timeout_ms);
    else if (arg == "--paced-frames" && has_value) ok = parse_int(argv[++i], options.paced_frames);
    else if (arg == "--period-us" && has_value) ok = parse_int(argv[++i], options.period_us);
    else ok = false;
    if (!ok) {
      std::fprintf(stderr,
                   "usage: usb_probe [--serial S] [--speed high|full|any] [--exchanges N] "
                   "[--current-ma MA] [--min-move COUNTS] [--exchange-watchdog-ms MS] "
                   "[--trip-watchdog-ms MS] [--timeout-ms MS] [--paced-frames N] [--period-us P] [--json FILE]\n");
      return 2;
    }
  }
  if (options.exchanges < 10) options.exchanges = 10;

  libusb_context* context = nullptr;
  if (libusb_init(&context) != 0) {
    std::fprintf(stderr, "usb_probe: libusb_init failed\n");
    return 1;
  }
  // --- 1. the device by VID:PID and serial ---
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context, &list);
  libusb_device_handle* handle = nullptr;
  libusb_device* device = nullptr;
  int matching_vid_pid = 0;
  for (ssize_t i = 0; i < count && handle == nullptr; ++i) {
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(list[i], &descriptor) != 0) continue;
    if (descriptor.idVendor != up::kVendorId || descriptor.idProduct != up::kProductId) continue;
    ++matching_vid_pid;
    libusb_device_handle* candidate = nullptr;
    if (libusb_open(list[i], &candidate) != 0) continue;
    unsigned char serial[128] = {};
    const int length = descriptor.iSerialNumber == 0 ? -1
        : libusb_get_string_descriptor_ascii(candidate, descriptor.iSerialNumber, serial, sizeof(serial));
    if (length > 0 && options.serial == reinterpret_cast<const char*>(serial)) {
      handle = candidate;
      device = list[i];
      std::printf("usb_probe: found %04x:%04x serial %s at bus %d address %d, bcdDevice 0x%04x\n",
                  descriptor.idVendor, descriptor.idProduct, serial, libusb_get_bus_number(device),
                  libusb_get_device_address(device), descriptor.bcdDevice);
    } else {
      libusb_close(candidate);
    }
  }
  if (handle == nullptr) {
    std::fprintf(stderr, "usb_probe: FAIL: no %04x:%04x with serial \"%s\" (%d with that VID:PID, %zd devices)\n",
                 up::kVendorId, up::kProductId, options.serial.c_str(), matching_vid_pid, count);
    libusb_free_device_list(list, 1);
    libusb_exit(context);
    return 1;
  }
  const int speed = libusb_get_device_speed(device);
  std::printf("usb_probe: speed %s\n", speed_name(speed));
  if (options.speed != "any") check(options.speed == speed_name(speed), "speed is " + std::string(speed_name(speed)) + ", expected " + options.speed);

  // --- 2. endpoints from the descriptors ---
  const Endpoints endpoints = find_endpoints(device);
  libusb_free_device_list(list, 1);
  std::printf("usb_probe: interface %d: IN 0x%02x (%d bytes, bInterval %d), OUT 0x%02x (%d bytes, bInterval %d)\n",
              endpoints.interface_number, endpoints.in, endpoints.in_size, endpoints.in_interval,
              endpoints.out, endpoints.out_size, endpoints.out_interval);
  check(endpoints.interface_number >= 0, "no interface of class 0xff");
  check(endpoints.in != 0 && endpoints.out != 0, "IN and OUT endpoints");
  check(endpoints.in_interrupt && endpoints.out_interrupt, "both endpoints are interrupt endpoints");
  check(endpoints.in_size == up::kMaxPacketSize && endpoints.out_size == up::kMaxPacketSize, "wMaxPacketSize 64");
  check(endpoints.in_interval == 1 && endpoints.out_interval == 1, "bInterval 1");
  if (failures > 0 || libusb_claim_interface(handle, endpoints.interface_number) != 0) {
    std::fprintf(stderr, "usb_probe: FAIL: cannot use the interface\n");
    libusb_close(handle);
    libusb_exit(context);
    return 1;
  }
  Probe probe(handle, endpoints, options);

  // --- 3. control requests ---
  std::array<unsigned char, 64> buffer{};
  const int got = probe.control_in(up::kRequestGetIdentity, buffer.data(), static_cast<std::uint16_t>(buffer.size()));
  up::Identity identity;
  const up::DecodeStatus identity_status =
      got < 0 ? up::DecodeStatus::wrong_length
              : up::decode(std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(got)), identity);
  check(identity_status == up::DecodeStatus::ok,
        "GET_IDENTITY: " + (got < 0 ? std::string(libusb_error_name(got)) : up::to_string(identity_status)));
  std::printf("usb_probe: identity: protocol %u, firmware 0x%04x, %u channels, watchdog %u ms, frame %u us, max current %u mA\n",
              identity.protocol_version, identity.firmware_version, identity.channel_count,
              identity.watchdog_ms, identity.frame_interval_us, identity.max_current_ma);
  check(identity.channel_count >= 1, "identity names at least one channel");
  check(probe.control_in(0x7F, buffer.data(), 8) == LIBUSB_ERROR_PIPE, "an unknown vendor request stalls");
  check(probe.set_watchdog(1) == LIBUSB_ERROR_PIPE, "SET_WATCHDOG 1 ms (out of range) stalls");
  check(probe.set_watchdog(options.exchange_watchdog_ms) == 0, "SET_WATCHDOG for the exchange");
  const std::uint8_t channels = identity.channel_count;

  // --- 4. the exchange ---
  std::vector<double> round_trip_us;
  round_trip_us.reserve(static_cast<std::size_t>(options.exchanges));
  up::InReport in;
  up::DecodeStatus decoded = up::DecodeStatus::ok;
  int sequence_errors = 0;
  int decode_errors = 0;
  int transfer_errors = 0;
  int time_errors = 0;
  int not_enabled = 0;
  std::uint16_t previous_in = 0;
  std::uint32_t previous_time = 0;
  std::int32_t counts_without_current = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < options.exchanges; ++i) {
    const bool second_half = i >= options.exchanges / 2;
    const auto sent_at = std::chrono::steady_clock::now();
    if (probe.send(up::kOutFlagEnable, channels, second_half ? options.current_ma : 0) != 0 ||
        probe.receive(in, decoded, options.timeout_ms) != 0) {
      ++transfer_errors;
      continue;
    }
    round_trip_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - sent_at).count());
    if (decoded != up::DecodeStatus::ok) {
      ++decode_errors;
      continue;
    }
    if (in.out_sequence_applied != probe.out_sequence()) ++sequence_errors;
    if (i > 0 && up::sequence_distance(in.sequence, previous_in) != 1) ++sequence_errors;
    if (i > 0 && in.device_time_us - previous_time != identity.frame_interval_us) ++time_errors;
    if ((in.status & up::kStatusEnabled) == 0) ++not_enabled;
    previous_in = in.sequence;
    previous_time = in.device_time_us;
    if (i == options.exchanges / 2 - 1) counts_without_current = in.counts[0];
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::int32_t moved = in.counts[0] - counts_without_current;
  std::printf("usb_probe: %d exchanges in %.2f s (%.0f/s): transfer errors %d, decode errors %d, "
              "sequence errors %d, device-time errors %d, not enabled %d\n",
              options.exchanges, seconds, options.exchanges / seconds, transfer_errors, decode_errors,
              sequence_errors, time_errors, not_enabled);
  std::printf("usb_probe: round trip OUT->IN us: min %.0f median %.0f p99 %.0f max %.0f\n",
              percentile(round_trip_us, 0.0), percentile(round_trip_us, 0.5),
              percentile(round_trip_us, 0.99), percentile(round_trip_us, 1.0));
  std::printf("usb_probe: channel 0 moved %d counts with %d mA\n", moved, options.current_ma);
  check(transfer_errors == 0 && decode_errors == 0, "every exchange completes and decodes");
  check(sequence_errors == 0, "sequences echoed and counted");
  check(time_errors == 0, "device time advances one frame per exchange");
  check(not_enabled == 0, "every report enabled");
  check(std::abs(moved) >= options.min_move, "encoder count moves with current");

  // --- 4b. the paced run (optional) ---
  PacedResult paced;
  if (options.paced_frames > 0) {
    paced = paced_run(context, handle, endpoints, channels, probe.out_sequence(), options);
    // The synchronous probe continues after the paced run's sequences.
    for (int i = 0; i < paced.frames; ++i) (void)probe.skip_sequence();
    std::printf("usb_probe: paced at %d us: %d periods in %.2f s, %d OUT sent, %d not sent (4 in flight), "
                "missed %d (%.3f %% of periods), stale %d, errors %d\n",
                options.period_us, options.paced_frames, paced.seconds, paced.frames, paced.skipped, paced.missed,
                100.0 * paced.missed / options.paced_frames, paced.stale, paced.errors);
    std::printf("usb_probe: paced round trip OUT->IN us: min %.0f median %.0f p99 %.0f p99.9 %.0f max %.0f (%zu reports)\n",
                percentile(paced.round_trip_us, 0.0), percentile(paced.round_trip_us, 0.5),
                percentile(paced.round_trip_us, 0.99), percentile(paced.round_trip_us, 0.999),
                percentile(paced.round_trip_us, 1.0), paced.round_trip_us.size());
    check(paced.errors == 0, "paced run without transfer or decode errors");
  }

  // --- 5. the watchdog ---
  check(probe.set_watchdog(options.trip_watchdog_ms) == 0, "SET_WATCHDOG for the trip");
  check(probe.send(up::kOutFlagEnable, channels, options.current_ma) == 0, "last report before silence");
  check(probe.receive(in, decoded, options.timeout_ms) == 0 && decoded == up::DecodeStatus::ok &&
            (in.status & up::kStatusEnabled) != 0 && in.out_sequence_applied == probe.out_sequence(),
        "the last report before silence is answered, enabled (SET_WATCHDOG did not trip at once)");
  const auto silent_from = std::chrono::steady_clock::now();
  up::InReport trip;
  const int trip_status = probe.receive(trip, decoded, options.trip_watchdog_ms * 20 + 2000);
  const double trip_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - silent_from).count();
  const bool tripped = trip_status == 0 && decoded == up::DecodeStatus::ok &&
                       (trip.status & up::kStatusWatchdogTripped) != 0;
  std::printf("usb_probe: watchdog %d ms: trip report after %.1f ms of silence (status 0x%04x)\n",
              options.trip_watchdog_ms, trip_ms, trip.status);
  check(tripped, "the watchdog trips when OUT stops");
  check(trip_ms >= options.trip_watchdog_ms * 0.9, "not before the watchdog time");
  check((trip.status & up::kStatusEnabled) == 0, "tripped report is not enabled");
  check(trip.out_sequence_applied == probe.out_sequence(), "trip report names the last applied OUT");
  (void)probe.send(up::kOutFlagEnable, channels, options.current_ma);
  (void)probe.receive(in, decoded, options.timeout_ms);
  check((in.status & up::kStatusWatchdogTripped) != 0 && (in.status & up::kStatusEnabled) == 0,
        "latched: an enable report is not applied");
  (void)probe.send(up::kOutFlagClearWatchdog, channels, 0);
  (void)probe.receive(in, decoded, options.timeout_ms);
  check((in.status & up::kStatusWatchdogTripped) == 0, "clear_watchdog clears the latch");
  (void)probe.send(up::kOutFlagEnable, channels, 0);
  (void)probe.receive(in, decoded, options.timeout_ms);
  check((in.status & up::kStatusEnabled) != 0, "enable applies again after the clear");
  // Leave it disabled and quiet.
  (void)probe.send(0, channels, 0);
  (void)probe.receive(in, decoded, options.timeout_ms);

  if (!options.json.empty()) {
    std::ofstream json(options.json);
    json << "{\"exchanges\":" << options.exchanges << ",\"seconds\":" << seconds
         << ",\"rate_per_s\":" << options.exchanges / seconds
         << ",\"round_trip_us\":{\"min\":" << percentile(round_trip_us, 0.0)
         << ",\"median\":" << percentile(round_trip_us, 0.5) << ",\"p99\":" << percentile(round_trip_us, 0.99)
         << ",\"max\":" << percentile(round_trip_us, 1.0) << "},\"transfer_errors\":" << transfer_errors
         << ",\"sequence_errors\":" << sequence_errors << ",\"moved_counts\":" << moved
         << ",\"speed\":\"" << speed_name(speed) << "\",\"watchdog_ms\":" << options.trip_watchdog_ms
         << ",\"trip_after_ms\":" << trip_ms;
    if (options.paced_frames > 0) {
      json << ",\"paced\":{\"period_us\":" << options.period_us << ",\"frames\":" << paced.frames
           << ",\"seconds\":" << paced.seconds << ",\"missed\":" << paced.missed << ",\"stale\":" << paced.stale
           << ",\"skipped\":" << paced.skipped << ",\"errors\":" << paced.errors
           << ",\"round_trip_us\":{\"min\":" << percentile(paced.round_trip_us, 0.0)
           << ",\"median\":" << percentile(paced.round_trip_us, 0.5) << ",\"p99\":" << percentile(paced.round_trip_us, 0.99)
           << ",\"p999\":" << percentile(paced.round_trip_us, 0.999) << ",\"max\":" << percentile(paced.round_trip_us, 1.0) << "}}";
    }
    json << ",\"failures\":" << failures << "}\n";
  }
  libusb_release_interface(handle, endpoints.interface_number);
  libusb_close(handle);
  libusb_exit(context);
  std::printf("usb_probe: %s (%d failed checks)\n", failures == 0 ? "PASS" : "FAIL", failures);
  return failures == 0 ? 0 : 1;
}
