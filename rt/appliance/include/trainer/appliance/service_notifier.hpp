// The trainer's messages to systemd (sd_notify(3), libsystemd): READY=1, STATUS=, WATCHDOG=1,
// STOPPING=1. Inactive (every call a no-op) when NOTIFY_SOCKET is unset, i.e. outside a
// Type=notify unit. Supervisor thread only: sd_notify opens a socket and sends a datagram,
// which the RT thread must never do.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace trainer::appliance {

class ServiceNotifier {
 public:
  // Reads NOTIFY_SOCKET and sd_watchdog_enabled() (WATCHDOG_USEC, WATCHDOG_PID) once.
  static ServiceNotifier from_environment();

  bool active() const noexcept { return active_; }
  // WATCHDOG_USEC when the watchdog is enabled for this process, else 0.
  std::uint64_t watchdog_usec() const noexcept { return watchdog_usec_; }

  void ready(std::string_view status) const;
  void status(std::string_view status) const;
  void watchdog() const;
  void stopping(std::string_view status) const;
  // The last message sent and whether sd_notify accepted it (for STATUS in the report).
  std::uint64_t messages_sent() const noexcept { return sent_; }

 private:
  void send(const std::string& message) const;
  bool active_ = false;
  std::uint64_t watchdog_usec_ = 0;
  mutable std::uint64_t sent_ = 0;
};

}  // namespace trainer::appliance
