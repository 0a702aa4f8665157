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
//  5. the watchdog: SET_WATCHDOG --trip-watchdog-ms, one more enabled report, then no OUT: the
//     next IN report must say watchdog_tripped no earlier than the watchdog; enabled reports are
//     then answered but not applied; clear_watchdog clears it and enable applies again.
// Prints the round-trip figures (min, median, p99, max, rate) and writes them as JSON
// (--json FILE). Exit status 0 all checks passed, 1 a check failed, 2 usage.
#include <libusb-1.0/libusb.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
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

 private:
  libusb_device_handle* handle_;
  Endpoints ep_;
  Options options_;
  std::uint16_t out_sequence_ = 0;
};

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
    else ok = false;
    if (!ok) {
      std::fprintf(stderr,
                   "usage: usb_probe [--serial S] [--speed high|full|any] [--exchanges N] "
                   "[--current-ma MA] [--min-move COUNTS] [--exchange-watchdog-ms MS] "
                   "[--trip-watchdog-ms MS] [--timeout-ms MS] [--json FILE]\n");
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

  // --- 5. the watchdog ---
  check(probe.set_watchdog(options.trip_watchdog_ms) == 0, "SET_WATCHDOG for the trip");
  check(probe.send(up::kOutFlagEnable, channels, options.current_ma) == 0, "last report before silence");
  (void)probe.receive(in, decoded, options.timeout_ms);
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
         << ",\"trip_after_ms\":" << trip_ms << ",\"failures\":" << failures << "}\n";
  }
  libusb_release_interface(handle, endpoints.interface_number);
  libusb_close(handle);
  libusb_exit(context);
  std::printf("usb_probe: %s (%d failed checks)\n", failures == 0 ? "PASS" : "FAIL", failures);
  return failures == 0 ? 0 : 1;
}
