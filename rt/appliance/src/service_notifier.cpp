#include "trainer/appliance/service_notifier.hpp"

#include <systemd/sd-daemon.h>

#include <cstdlib>

namespace trainer::appliance {

ServiceNotifier ServiceNotifier::from_environment() {
  ServiceNotifier notifier;
  const char* socket = std::getenv("NOTIFY_SOCKET");
  notifier.active_ = socket != nullptr && socket[0] != '\0';
  std::uint64_t usec = 0;
  // > 0: the watchdog is on for this process (WATCHDOG_PID unset or ours); the variables stay
  // set (unset_environment = 0) so a re-exec would see them too.
  if (notifier.active_ && sd_watchdog_enabled(0, &usec) > 0) notifier.watchdog_usec_ = usec;
  return notifier;
}

// A status line is one line: newlines would start another assignment.
static std::string service_status_line(std::string_view status) {
  std::string line(status);
  for (char& c : line) {
    if (c == '\n') c = ' ';
  }
  return line;
}

void ServiceNotifier::send(const std::string& message) const {
  if (!active_) return;
  if (sd_notify(0, message.c_str()) > 0) ++sent_;
}

void ServiceNotifier::ready(std::string_view status) const {
  send("READY=1\nSTATUS=" + service_status_line(status));
}

void ServiceNotifier::status(std::string_view status) const {
  send("STATUS=" + service_status_line(status));
}

void ServiceNotifier::watchdog() const {
  send("WATCHDOG=1");
}

void ServiceNotifier::stopping(std::string_view status) const {
  send("STOPPING=1\nSTATUS=" + service_status_line(status));
}

}  // namespace trainer::appliance
