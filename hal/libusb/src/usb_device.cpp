#include "trainer/hal_libusb/usb_device.hpp"

#include <libusb.h>
#include <poll.h>
#include <pthread.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <utility>

namespace trainer::hal::libusb {

namespace {

std::string usb_error_text(int code) {
  return std::string(libusb_error_name(code)) + " (" + libusb_strerror(code) + ")";
}

std::string hex4(std::uint16_t value) {
  char text[8];
  std::snprintf(text, sizeof text, "%04x", value);
  return text;
}

std::string vid_pid(std::uint16_t vendor, std::uint16_t product) {
  return hex4(vendor) + ":" + hex4(product);
}

std::string version_text(std::uint16_t version) {
  return std::to_string(version >> 8U) + "." + std::to_string(version & 0xFFU) + " (0x" +
         hex4(version) + ")";
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

// Milliseconds for libusb's unsigned timeouts (at least 1: 0 means "forever" to libusb).
unsigned int usb_timeout_ms(std::int64_t ns) {
  return static_cast<unsigned int>(std::max<std::int64_t>(1, ns / 1'000'000));
}

void sleep_wall_ns(std::int64_t ns) {
  std::this_thread::sleep_for(std::chrono::nanoseconds(ns));
}

int hotplug_left(libusb_context* /*context*/, libusb_device* device, libusb_hotplug_event event,
                 void* user_data);

}  // namespace

// Friend-free trampoline: the hotplug callback needs the device and handle.
struct UsbHotplugAccess {
  static void left(UsbDevice& self, libusb_device* device) noexcept {
    if (self.handle_ != nullptr && libusb_get_device(self.handle_) == device) {
      self.report_lost("hotplug");
    }
  }
};

namespace {
int hotplug_left(libusb_context* /*context*/, libusb_device* device, libusb_hotplug_event event,
                 void* user_data) {
  if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT) {
    UsbHotplugAccess::left(*static_cast<UsbDevice*>(user_data), device);
  }
  return 0;  // stay registered
}
}  // namespace

UsbDevice::UsbDevice(core::Clock& clock, UsbDeviceParams params)
    : clock_(clock), params_(std::move(params)) {}

UsbDevice::~UsbDevice() {
  deactivate();
  close_device();
  if (context_ != nullptr) libusb_exit(context_);
}

// ------------------------------------------------------------------------------ setup

core::Expected<void> UsbDevice::open_device() {
  if (context_ == nullptr) {
    if (const int rc = libusb_init(&context_); rc != 0) {
      context_ = nullptr;
      return core::make_error(params_.name + ": libusb_init failed: " + usb_error_text(rc));
    }
  }
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context_, &list);
  if (count < 0) {
    return core::make_error(params_.name + ": cannot list USB devices: " +
                            usb_error_text(static_cast<int>(count)));
  }
  const std::string wanted = vid_pid(params_.vendor_id, params_.product_id) +
                             (params_.serial.empty() ? std::string(" (any serial)")
                                                     : " serial \"" + params_.serial + "\"");
  std::string found;
  libusb_device_handle* chosen = nullptr;
  for (ssize_t i = 0; i < count; ++i) {
    libusb_device* device = list[i];
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(device, &descriptor) != 0) continue;
    std::string entry = vid_pid(descriptor.idVendor, descriptor.idProduct) + " on bus " +
                        std::to_string(libusb_get_bus_number(device)) + " address " +
                        std::to_string(libusb_get_device_address(device));
    if (descriptor.idVendor == params_.vendor_id && descriptor.idProduct == params_.product_id) {
      libusb_device_handle* handle = nullptr;
      if (const int rc = libusb_open(device, &handle); rc != 0) {
        entry += " (cannot open: " + usb_error_text(rc) + ")";
      } else {
        std::array<unsigned char, 128> text{};
        std::string serial;
        if (descriptor.iSerialNumber != 0) {
          const int length = libusb_get_string_descriptor_ascii(
              handle, descriptor.iSerialNumber, text.data(), static_cast<int>(text.size()));
          if (length > 0) serial.assign(reinterpret_cast<const char*>(text.data()),
                                        static_cast<std::size_t>(length));
        }
        entry += " serial \"" + serial + "\"";
        if (chosen == nullptr && (params_.serial.empty() || serial == params_.serial)) {
          chosen = handle;
          identity_.serial = serial;
          identity_.speed = speed_name(libusb_get_device_speed(device));
        } else {
          libusb_close(handle);
        }
      }
    }
    found += (found.empty() ? "" : "; ") + entry;
  }
  libusb_free_device_list(list, 1);
  if (chosen == nullptr) {
    return core::make_error(params_.name + ": no USB device " + wanted +
                            " (usb.vendor_id, usb.product_id, usb.serial); found: " +
                            (found.empty() ? std::string("no USB devices at all") : found));
  }
  handle_ = chosen;
  (void)libusb_set_auto_detach_kernel_driver(handle_, 1);  // NOT_SUPPORTED off Linux: fine

  // The vendor-specific interface and its interrupt endpoints, from the descriptors.
  libusb_config_descriptor* config = nullptr;
  if (const int rc = libusb_get_active_config_descriptor(libusb_get_device(handle_), &config);
      rc != 0) {
    return core::make_error(params_.name + ": cannot read the configuration descriptor: " +
                            usb_error_text(rc));
  }
  interface_number_ = -1;
  for (int i = 0; i < config->bNumInterfaces && interface_number_ < 0; ++i) {
    const libusb_interface& interface = config->interface[i];
    if (interface.num_altsetting < 1) continue;
    const libusb_interface_descriptor& alt = interface.altsetting[0];
    if (alt.bInterfaceClass != proto::kInterfaceClass) continue;
    std::uint8_t in = 0;
    std::uint8_t out = 0;
    std::uint16_t in_packet = 0;
    std::uint16_t out_packet = 0;
    for (int e = 0; e < alt.bNumEndpoints; ++e) {
      const libusb_endpoint_descriptor& endpoint = alt.endpoint[e];
      if ((endpoint.bmAttributes & LIBUSB_TRANSFER_TYPE_MASK) != LIBUSB_TRANSFER_TYPE_INTERRUPT)
        continue;
      const auto packet = static_cast<std::uint16_t>(endpoint.wMaxPacketSize & 0x7FFU);
      if ((endpoint.bEndpointAddress & LIBUSB_ENDPOINT_DIR_MASK) == LIBUSB_ENDPOINT_IN) {
        in = endpoint.bEndpointAddress;
        in_packet = packet;
        identity_.interval = endpoint.bInterval;
      } else {
        out = endpoint.bEndpointAddress;
        out_packet = packet;
      }
    }
    if (in != 0 && out != 0) {
      interface_number_ = alt.bInterfaceNumber;
      identity_.in_endpoint = in;
      identity_.out_endpoint = out;
      identity_.max_packet = std::min(in_packet, out_packet);
    }
  }
  libusb_free_config_descriptor(config);
  if (interface_number_ < 0) {
    return core::make_error(params_.name + ": device " + wanted +
                            " has no vendor-specific interface (class 0xff) with an interrupt "
                            "IN and an interrupt OUT endpoint: not the trainer's protocol");
  }
  if (identity_.max_packet < proto::kReportSize) {
    return core::make_error(params_.name + ": interrupt endpoints of " +
                            std::to_string(identity_.max_packet) + " bytes max packet, expected " +
                            std::to_string(proto::kReportSize) + " (docs/usb-protocol.md)");
  }
  if (const int rc = libusb_claim_interface(handle_, interface_number_); rc != 0) {
    return core::make_error(params_.name + ": cannot claim interface " +
                            std::to_string(interface_number_) + " of " + wanted + ": " +
                            usb_error_text(rc));
  }
  return {};
}

core::Expected<void> UsbDevice::check_identity() {
  std::array<std::uint8_t, proto::kIdentitySize> bytes{};
  const int got = libusb_control_transfer(
      handle_, proto::kRequestTypeVendorInterfaceIn, proto::kRequestGetIdentity, 0,
      static_cast<std::uint16_t>(interface_number_), bytes.data(),
      static_cast<std::uint16_t>(bytes.size()), usb_timeout_ms(params_.control_timeout_ns));
  if (got < 0) {
    return core::make_error(params_.name + ": GET_IDENTITY control request failed: " +
                            usb_error_text(got) + " (within usb.control_timeout_ms = " +
                            std::to_string(params_.control_timeout_ns / 1'000'000) + ")");
  }
  proto::Identity identity;
  const proto::DecodeStatus status =
      proto::decode(std::span<const std::uint8_t>(bytes.data(), static_cast<std::size_t>(got)),
                    identity);
  if (status != proto::DecodeStatus::ok) {
    return core::make_error(params_.name + ": the identity answer (" + std::to_string(got) +
                            " bytes) does not decode: " + proto::to_string(status) +
                            ": not the trainer's protocol");
  }
  identity_.protocol_version = identity.protocol_version;
  identity_.firmware_version = identity.firmware_version;
  identity_.device_channels = identity.channel_count;
  identity_.max_current_ma = identity.max_current_ma;
  if (identity.protocol_version != params_.protocol_version) {
    return core::make_error(params_.name + ": usb.protocol_version = " +
                            std::to_string(params_.protocol_version) + " but the device speaks " +
                            std::to_string(identity.protocol_version));
  }
  if (identity.channel_count != params_.channels.size()) {
    return core::make_error(params_.name + ": the device has " +
                            std::to_string(identity.channel_count) +
                            " channels, the device file's instruments have " +
                            std::to_string(params_.channels.size()) +
                            " joints ([[instrument]] x 5 joints): expected equal");
  }
  if (params_.min_firmware_version && identity.firmware_version < *params_.min_firmware_version) {
    return core::make_error(params_.name + ": usb.min_firmware_version = " +
                            version_text(*params_.min_firmware_version) +
                            " but the device runs firmware " +
                            version_text(identity.firmware_version));
  }
  for (const UsbChannelParams& channel : params_.channels) {
    const double limit_ma = std::floor(channel.scale.current_limit_a * 1000.0);
    if (limit_ma > static_cast<double>(identity.max_current_ma)) {
      return core::make_error(params_.name + ": " + channel.config_key + ".current_limit_a = " +
                              std::to_string(channel.scale.current_limit_a) +
                              " A exceeds the device's limit of " +
                              std::to_string(identity.max_current_ma) +
                              " mA: expected at most that");
    }
  }
  const int set = libusb_control_transfer(
      handle_, proto::kRequestTypeVendorInterfaceOut, proto::kRequestSetWatchdog,
      params_.watchdog_ms, static_cast<std::uint16_t>(interface_number_), nullptr, 0,
      usb_timeout_ms(params_.control_timeout_ns));
  if (set < 0) {
    return core::make_error(params_.name + ": SET_WATCHDOG (usb.watchdog_ms = " +
                            std::to_string(params_.watchdog_ms) + ") failed: " +
                            usb_error_text(set));
  }
  identity_.watchdog_ms = params_.watchdog_ms;
  return {};
}

void UsbDevice::close_device() noexcept {
  if (handle_ != nullptr) {
    if (interface_number_ >= 0) (void)libusb_release_interface(handle_, interface_number_);
    libusb_close(handle_);
    handle_ = nullptr;
  }
  interface_number_ = -1;
}

core::Expected<void> UsbDevice::configure() {
  if (state_ != hal::LifecycleState::unconfigured) {
    return core::make_error(params_.name + ": configure() needs an unconfigured device "
                            "(deactivate first)");
  }
  if (static_cast<std::int64_t>(params_.watchdog_ms) * 1'000'000 < 2 * params_.loop_period_ns) {
    return core::make_error(params_.name + ": usb.watchdog_ms = " +
                            std::to_string(params_.watchdog_ms) +
                            " is shorter than two loop periods (" +
                            std::to_string(params_.loop_period_ns / 1000) +
                            " us each): the device would drop the currents between commands");
  }
  std::vector<hal::JointScale> scales;
  for (const UsbChannelParams& channel : params_.channels) scales.push_back(channel.scale);
  if (auto configured = logic_.configure(scales, params_.stale_limit_cycles); !configured) {
    return core::make_error(params_.name + ": " + configured.error().message);
  }
  identity_ = UsbDiagnostics{};
  lost_.store(false, std::memory_order_relaxed);
  if (auto opened = open_device(); !opened) {
    close_device();
    return opened;
  }
  if (auto checked = check_identity(); !checked) {
    close_device();
    return checked;
  }
  state_ = hal::LifecycleState::inactive;
  configured_once_ = true;
  return {};
}

// ------------------------------------------------------------------------------ event thread

void UsbDevice::report_lost(const char* source) noexcept {
  bool expected = false;
  if (lost_.compare_exchange_strong(expected, true, std::memory_order_acq_rel)) {
    lost_report_ns_.store(wall_.now_ns(), std::memory_order_relaxed);
    lost_report_cycle_.store(rt_cycles_.load(std::memory_order_relaxed),
                             std::memory_order_relaxed);
    lost_source_.store(source, std::memory_order_release);
  }
}

void UsbDevice::in_callback(libusb_transfer* transfer) {
  auto& self = *static_cast<UsbDevice*>(transfer->user_data);
  switch (transfer->status) {
    case LIBUSB_TRANSFER_COMPLETED: {
      RawInReport& report = self.in_reports_.back();
      const auto length = static_cast<std::size_t>(std::clamp(transfer->actual_length, 0,
                                                   static_cast<int>(report.bytes.size())));
      std::memcpy(report.bytes.data(), transfer->buffer, length);
      report.length = static_cast<std::uint16_t>(length);
      report.received_ns = self.wall_.now_ns();
      report.index = ++self.in_index_;
      (void)self.in_reports_.publish();
      self.in_completed_.fetch_add(1, std::memory_order_relaxed);
      break;
    }
    case LIBUSB_TRANSFER_NO_DEVICE:
      self.report_lost("transfer");
      --self.in_flight_;
      return;
    case LIBUSB_TRANSFER_CANCELLED:
      --self.in_flight_;
      return;
    default:  // timed out, stall, overflow, error: counted, tried again
      self.transfer_errors_.fetch_add(1, std::memory_order_relaxed);
      break;
  }
  if (self.stop_.load(std::memory_order_acquire)) {
    --self.in_flight_;
    return;
  }
  if (const int rc = libusb_submit_transfer(transfer); rc != 0) {
    --self.in_flight_;
    if (rc == LIBUSB_ERROR_NO_DEVICE) {
      self.report_lost("transfer");
    } else {
      self.transfer_errors_.fetch_add(1, std::memory_order_relaxed);
    }
  }
}

void UsbDevice::out_callback(libusb_transfer* transfer) {
  auto& self = *static_cast<UsbDevice*>(transfer->user_data);
  self.out_busy_ = false;
  switch (transfer->status) {
    case LIBUSB_TRANSFER_COMPLETED:
      self.out_completed_.fetch_add(1, std::memory_order_relaxed);
      break;
    case LIBUSB_TRANSFER_NO_DEVICE:
      self.report_lost("transfer");
      break;
    case LIBUSB_TRANSFER_CANCELLED:
      break;
    default:
      self.transfer_errors_.fetch_add(1, std::memory_order_relaxed);
      break;
  }
  self.submit_pending_out();
}

void UsbDevice::submit_pending_out() noexcept {
  if (out_busy_ || stop_.load(std::memory_order_acquire) ||
      lost_.load(std::memory_order_acquire) || !out_reports_.take()) {
    return;
  }
  std::memcpy(out_buffer_.data(), out_reports_.front().bytes.data(), out_buffer_.size());
  if (const int rc = libusb_submit_transfer(out_transfer_); rc != 0) {
    if (rc == LIBUSB_ERROR_NO_DEVICE) {
      report_lost("transfer");
    } else {
      transfer_errors_.fetch_add(1, std::memory_order_relaxed);
    }
    return;
  }
  out_busy_ = true;
  out_submitted_.fetch_add(1, std::memory_order_relaxed);
}

void UsbDevice::wake_events() noexcept {
  // One non-blocking write(2) on an eventfd: the RT cycle's only system call into the USB
  // side (the HAL's own I/O); a full counter (never in practice) just means already signalled.
  const std::uint64_t one = 1;
  if (wake_fd_ >= 0) (void)!::write(wake_fd_, &one, sizeof one);
}

void UsbDevice::event_loop() noexcept {
  // The thread sleeps in poll() on libusb's descriptors (the device's usbfs fd, libusb's event
  // and timer fds; fixed while the device is open) and on wake_fd_, which the RT cycle signals
  // when it published an OUT report; libusb then handles what is ready without waiting. So a
  // published OUT report is submitted at once and no thread spins. usb.event_poll_us bounds
  // the sleep when nothing happens (the stop flag, libusb's own timeouts).
  std::array<pollfd, 16> fds{};
  std::size_t count = 0;
  fds[count++] = pollfd{wake_fd_, POLLIN, 0};
  if (const libusb_pollfd** usb_fds = libusb_get_pollfds(context_)) {
    for (const libusb_pollfd** fd = usb_fds; *fd != nullptr && count < fds.size(); ++fd) {
      fds[count++] = pollfd{(*fd)->fd, (*fd)->events, 0};
    }
    libusb_free_pollfds(usb_fds);
  }
  const auto fallback_ms =
      static_cast<int>(std::max<std::int64_t>(params_.event_poll_ns / 1'000'000, 1));
  while (!stop_.load(std::memory_order_acquire)) {
    int timeout_ms = fallback_ms;
    timeval next{};
    if (libusb_get_next_timeout(context_, &next) == 1) {
      const auto next_ms = static_cast<int>(next.tv_sec * 1000 + (next.tv_usec + 999) / 1000);
      timeout_ms = std::min(timeout_ms, next_ms);
    }
    (void)::poll(fds.data(), count, timeout_ms);
    if ((fds[0].revents & POLLIN) != 0) {
      std::uint64_t signals = 0;
      (void)::read(wake_fd_, &signals, sizeof signals);
    }
    timeval zero{0, 0};
    (void)libusb_handle_events_timeout_completed(context_, &zero, nullptr);
    submit_pending_out();
  }
  drain_transfers();
}

void UsbDevice::drain_transfers() noexcept {
  // Cancel what is in flight and let the cancellations complete (bounded: 2 s).
  for (libusb_transfer* transfer : in_transfers_) {
    if (transfer != nullptr) (void)libusb_cancel_transfer(transfer);
  }
  if (out_busy_) (void)libusb_cancel_transfer(out_transfer_);
  for (int round = 0; round < 200 && (in_flight_ > 0 || out_busy_); ++round) {
    timeval timeout{0, 10'000};
    (void)libusb_handle_events_timeout_completed(context_, &timeout, nullptr);
  }
}

void UsbDevice::stop_events() noexcept {
  stop_.store(true, std::memory_order_release);
  wake_events();
  if (events_.joinable()) {
    events_.join();  // the thread drains its transfers before it ends
  } else if (in_flight_ > 0 || out_busy_) {
    drain_transfers();  // activate() failed before the thread started
  }
  if (hotplug_registered_) {
    libusb_hotplug_deregister_callback(context_, hotplug_handle_);
    hotplug_registered_ = false;
  }
  for (libusb_transfer*& transfer : in_transfers_) {
    if (transfer != nullptr) libusb_free_transfer(transfer);
    transfer = nullptr;
  }
  if (out_transfer_ != nullptr) libusb_free_transfer(out_transfer_);
  out_transfer_ = nullptr;
  in_flight_ = 0;
  out_busy_ = false;
  if (wake_fd_ >= 0) ::close(wake_fd_);
  wake_fd_ = -1;
}

// ------------------------------------------------------------------------------ activate

bool UsbDevice::exchange_setup_report(bool clear_watchdog, std::int64_t timeout_ns) noexcept {
  const std::array<hal::ActuatorCommand, proto::kMaxChannels> off{};
  (void)logic_.build_out(off, clear_watchdog, wall_.now_ns(), out_reports_.back());
  const std::uint16_t sequence = logic_.last_out_sequence();
  if (out_reports_.publish()) ++out_superseded_;
  wake_events();
  const std::int64_t deadline = wall_.now_ns() + timeout_ns;
  while (wall_.now_ns() < deadline && !lost_.load(std::memory_order_acquire)) {
    if (in_reports_.take()) {
      logic_.on_cycle(&in_reports_.front());
      if (logic_.acknowledged(sequence)) return true;
    }
    sleep_wall_ns(200'000);
  }
  return false;
}

core::Expected<void> UsbDevice::activate() {
  if (state_ != hal::LifecycleState::inactive || handle_ == nullptr) {
    return core::make_error(params_.name + ": activate() needs a configured, inactive device");
  }
  logic_.reset();
  RawInReport empty_in{};
  RawOutReport empty_out{};
  in_reports_.reset(empty_in);
  out_reports_.reset(empty_out);
  stop_.store(false, std::memory_order_relaxed);
  rt_cycles_.store(0, std::memory_order_relaxed);
  in_index_ = 0;
  out_superseded_ = 0;
  last_out_cycle_ns_ = 0;
  lost_latch_cycle_ = 0;
  lost_latch_ns_ = 0;
  shutdown_acknowledged_ = false;
  for (auto* counter : {&in_completed_, &out_completed_, &out_submitted_, &transfer_errors_})
    counter->store(0, std::memory_order_relaxed);

  const auto fail = [this](std::string message) -> core::Expected<void> {
    stop_events();
    return core::make_error(params_.name + ": " + std::move(message));
  };
  for (std::size_t i = 0; i < kInTransfers; ++i) {
    in_transfers_[i] = libusb_alloc_transfer(0);
    if (in_transfers_[i] == nullptr) return fail("libusb_alloc_transfer failed");
    libusb_fill_interrupt_transfer(in_transfers_[i], handle_, identity_.in_endpoint,
                                   in_buffers_[i].data(), static_cast<int>(proto::kReportSize),
                                   &UsbDevice::in_callback, this, 0);
  }
  out_transfer_ = libusb_alloc_transfer(0);
  if (out_transfer_ == nullptr) return fail("libusb_alloc_transfer failed");
  libusb_fill_interrupt_transfer(out_transfer_, handle_, identity_.out_endpoint,
                                 out_buffer_.data(), static_cast<int>(proto::kReportSize),
                                 &UsbDevice::out_callback, this,
                                 usb_timeout_ms(params_.control_timeout_ns));
  if (libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0) {
    const int rc = libusb_hotplug_register_callback(
        context_, LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT, LIBUSB_HOTPLUG_NO_FLAGS, params_.vendor_id,
        params_.product_id, LIBUSB_HOTPLUG_MATCH_ANY, &hotplug_left, this, &hotplug_handle_);
    hotplug_registered_ = rc == LIBUSB_SUCCESS;
  }
  identity_.hotplug = hotplug_registered_;
  for (libusb_transfer* transfer : in_transfers_) {
    if (const int rc = libusb_submit_transfer(transfer); rc != 0) {
      return fail("cannot submit the interrupt IN transfer: " + usb_error_text(rc));
    }
    ++in_flight_;
  }
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_fd_ < 0) return fail("eventfd failed");
  events_ = std::thread([this] { event_loop(); });
  pthread_setname_np(events_.native_handle(), "usb-events");

  // A trip or fault the device latched before (a previous run, an unplugged host) is cleared
  // here: activate() is the operator's reset. Then one disabled report, acknowledged.
  if (!exchange_setup_report(false, params_.start_timeout_ns)) {
    return fail(lost_.load() ? std::string("the device was lost while starting")
                             : "no IN report acknowledging the first OUT report within "
                               "usb.start_timeout_ms = " +
                                   std::to_string(params_.start_timeout_ns / 1'000'000));
  }
  const auto dirty = [this] {
    return (logic_.last_report().status &
            (proto::kStatusWatchdogTripped | proto::kStatusFault)) != 0U;
  };
  if (dirty()) {
    if (!exchange_setup_report(true, params_.start_timeout_ns) ||
        !exchange_setup_report(false, params_.start_timeout_ns) || dirty()) {
      return fail("the device's watchdog trip / fault did not clear (status 0x" +
                  hex4(logic_.last_report().status) + ")");
    }
  }
  if (logic_.latched()) return fail(std::string("fault while starting: ") + fault_report());
  logic_.arm_watchdog_check(true);
  logic_.restart_cycle_count();
  state_ = hal::LifecycleState::active;
  return {};
}

void UsbDevice::deactivate() noexcept {
  if (state_ == hal::LifecycleState::unconfigured) return;
  if (state_ == hal::LifecycleState::active && events_.joinable() &&
      !lost_.load(std::memory_order_acquire)) {
    logic_.arm_watchdog_check(false);
    shutdown_acknowledged_ = exchange_setup_report(false, params_.stop_timeout_ns);
  }
  stop_events();
  close_device();
  state_ = hal::LifecycleState::unconfigured;
}

// ------------------------------------------------------------------------------ RT cycle

void UsbDevice::latch_lost_if_reported() noexcept {
  if ((logic_.counters().faults & static_cast<std::uint32_t>(UsbFault::device_lost)) != 0U) return;
  if (!lost_.load(std::memory_order_acquire)) return;
  logic_.latch(UsbFault::device_lost);
  lost_latch_cycle_ = logic_.counters().cycles;
  lost_latch_ns_ = wall_.now_ns();
}

hal::ReturnCode UsbDevice::read_encoders(std::span<hal::EncoderSample> out) noexcept {
  if (state_ != hal::LifecycleState::active || out.size() < params_.channels.size()) {
    return hal::ReturnCode::error;
  }
  const RawInReport* fresh = in_reports_.take() ? &in_reports_.front() : nullptr;
  const bool answer_due = clock_.now_ns() - last_out_cycle_ns_ >= params_.loop_period_ns / 2;
  logic_.on_cycle(fresh, answer_due);
  rt_cycles_.store(logic_.counters().cycles, std::memory_order_relaxed);
  latch_lost_if_reported();
  logic_.fill_encoders(out);
  return logic_.latched() ? hal::ReturnCode::deactivate : hal::ReturnCode::ok;
}

hal::ReturnCode UsbDevice::write_actuators(std::span<const hal::ActuatorCommand> commands) noexcept {
  if (state_ != hal::LifecycleState::active || commands.size() < params_.channels.size()) {
    return hal::ReturnCode::error;
  }
  latch_lost_if_reported();
  const bool finite = logic_.build_out(commands, false, wall_.now_ns(), out_reports_.back());
  if (out_reports_.publish()) ++out_superseded_;
  wake_events();
  last_out_cycle_ns_ = clock_.now_ns();
  if (logic_.latched()) return hal::ReturnCode::deactivate;
  return finite ? hal::ReturnCode::ok : hal::ReturnCode::error;
}

hal::ReturnCode UsbDevice::read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept {
  if (!configured_once_ || out.size() < params_.channels.size()) return hal::ReturnCode::error;
  if (state_ == hal::LifecycleState::active) latch_lost_if_reported();
  logic_.fill_status(out);
  if (state_ == hal::LifecycleState::active && logic_.latched()) return hal::ReturnCode::deactivate;
  return hal::ReturnCode::ok;
}

hal::ReturnCode UsbDevice::read_digital_inputs(std::uint32_t& levels) noexcept {
  if (state_ != hal::LifecycleState::active || !logic_.has_report()) {
    return hal::ReturnCode::error;
  }
  latch_lost_if_reported();
  if (logic_.latched()) return hal::ReturnCode::deactivate;
  levels = logic_.counters().last_buttons;
  return hal::ReturnCode::ok;
}

// ------------------------------------------------------------------------------ report

UsbDiagnostics UsbDevice::diagnostics() const {
  UsbDiagnostics d = identity_;
  d.frames = logic_.counters();
  d.in_completed = in_completed_.load(std::memory_order_relaxed);
  d.out_completed = out_completed_.load(std::memory_order_relaxed);
  d.out_submitted = out_submitted_.load(std::memory_order_relaxed);
  d.out_superseded = out_superseded_;
  d.transfer_errors = transfer_errors_.load(std::memory_order_relaxed);
  d.lost_reported = lost_.load(std::memory_order_acquire);
  if (d.lost_reported) {
    const char* source = lost_source_.load(std::memory_order_acquire);
    d.lost_source = source != nullptr ? source : "";
    d.lost_report_cycle = lost_report_cycle_.load(std::memory_order_relaxed);
    d.lost_report_ns = lost_report_ns_.load(std::memory_order_relaxed);
  }
  d.lost_latch_cycle = lost_latch_cycle_;
  d.lost_latch_ns = lost_latch_ns_;
  d.shutdown_acknowledged = shutdown_acknowledged_;
  const core::LatencyHistogram& trip = logic_.round_trip();
  d.round_trips = trip.count();
  d.round_trip_min_ns = trip.min_ns();
  d.round_trip_p50_ns = trip.percentile_ns(0.5);
  d.round_trip_p99_ns = trip.percentile_ns(0.99);
  d.round_trip_p999_ns = trip.percentile_ns(0.999);
  d.round_trip_max_ns = trip.max_ns();
  d.round_trip_mean_ns = trip.mean_ns();
  return d;
}

std::string UsbDevice::fault_report() const {
  const UsbFrameCounters& c = logic_.counters();
  std::string text;
  for (std::uint32_t bit = 1; bit <= static_cast<std::uint32_t>(UsbFault::transfer_failed);
       bit <<= 1U) {
    if ((c.faults & bit) == 0U) continue;
    const auto fault = static_cast<UsbFault>(bit);
    if (!text.empty()) text += "; ";
    text += to_string(fault);
    if (fault == c.first_fault) text += " (first, cycle " + std::to_string(c.first_fault_cycle) + ")";
    if (fault == UsbFault::device_stopped) {
      text += " (" + std::to_string(c.stale_run_max) + " stale cycles in a row";
      if (c.last_bad_status != proto::DecodeStatus::ok)
        text += std::string(", last bad report: ") + proto::to_string(c.last_bad_status);
      text += ")";
    }
  }
  return text;
}

}  // namespace trainer::hal::libusb
