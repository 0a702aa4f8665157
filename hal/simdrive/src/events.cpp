// Events log ring and its JSON lines.
#include "trainer/hal_simdrive/events.hpp"

#include <algorithm>
#include <cstdio>

#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/nmt.hpp"

namespace trainer::hal::simdrive {

namespace {

std::string event_hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

// JSON string body: quotes, backslashes and control characters escaped.
std::string json_escaped(const char* text) {
  std::string out;
  for (const char* c = text; *c != '\0'; ++c) {
    const auto byte = static_cast<unsigned char>(*c);
    if (*c == '"' || *c == '\\') {
      out += '\\';
      out += *c;
    } else if (byte < 0x20) {
      char escape[8];
      std::snprintf(escape, sizeof escape, "\\u%04X", static_cast<unsigned>(byte));
      out += escape;
    } else {
      out += *c;
    }
  }
  return out;
}

void add_string(std::string& json, const char* key, const char* value) {
  json += ",\"";
  json += key;
  json += "\":\"";
  json += json_escaped(value);
  json += '"';
}

void add_number(std::string& json, const char* key, std::uint64_t value) {
  json += ",\"";
  json += key;
  json += "\":";
  json += std::to_string(value);
}

const char* nmt_name(std::uint32_t value) {
  const auto state = canopen::nmt_state_from_byte(static_cast<std::uint8_t>(value));
  return state ? canopen::to_string(*state) : "?";
}

const char* power_name(std::uint32_t value) {
  return canopen::to_string(static_cast<canopen::PowerState>(value));
}

}  // namespace

const char* to_string(EventKind kind) noexcept {
  switch (kind) {
    case EventKind::boot: return "boot";
    case EventKind::nmt_state: return "nmt_state";
    case EventKind::power_state: return "power_state";
    case EventKind::master_heartbeat_seen: return "master_heartbeat_seen";
    case EventKind::master_heartbeat_lost: return "master_heartbeat_lost";
    case EventKind::master_heartbeat_recovered: return "master_heartbeat_recovered";
    case EventKind::rpdo_deadline_expired: return "rpdo_deadline_expired";
    case EventKind::torque_removed: return "torque_removed";
    case EventKind::torque_enabled: return "torque_enabled";
    case EventKind::abort_connection: return "abort_connection";
    case EventKind::fault_injected: return "fault_injected";
    case EventKind::fault_cleared: return "fault_cleared";
    case EventKind::emcy_sent: return "emcy_sent";
    case EventKind::plant_started: return "plant_started";
  }
  return "?";
}

std::string to_json(const DriveEvent& event) {
  std::string json = "{\"t_ns\":" + std::to_string(event.t_ns);
  add_number(json, "sync", event.sync);
  add_number(json, "node", event.node);
  add_string(json, "event", to_string(event.kind));
  switch (event.kind) {
    case EventKind::nmt_state:
      add_string(json, "from", nmt_name(event.a));
      add_string(json, "to", nmt_name(event.b));
      break;
    case EventKind::power_state:
      add_string(json, "from", power_name(event.a));
      add_string(json, "to", power_name(event.b));
      break;
    case EventKind::master_heartbeat_seen:
    case EventKind::master_heartbeat_lost:
      add_number(json, "producer", event.a);
      add_number(json, "consumer_time_ms", event.b);
      break;
    case EventKind::master_heartbeat_recovered: add_number(json, "producer", event.a); break;
    case EventKind::rpdo_deadline_expired:
      add_number(json, "rpdo", event.a);
      add_number(json, "event_timer_ms", event.b);
      break;
    case EventKind::abort_connection: add_number(json, "option", event.a); break;
    case EventKind::emcy_sent:
      add_string(json, "code", event_hex(event.a, 4).c_str());
      add_string(json, "register", event_hex(event.b, 2).c_str());
      add_string(json, "meaning",
                 event.a == 0 ? "error reset / no error"
                              : canopen::describe_emcy_code(static_cast<std::uint16_t>(event.a)));
      break;
    default: break;
  }
  if (event.cause != nullptr) add_string(json, "cause", event.cause);
  if (event.text[0] != '\0') {
    std::array<char, kEventTextBytes + 1> text{};
    std::copy(event.text.begin(), event.text.end(), text.begin());
    add_string(json, event.kind == EventKind::emcy_sent ? "note" : "fault", text.data());
  }
  json += '}';
  return json;
}

EventLog::EventLog(std::size_t capacity) : ring_(std::max<std::size_t>(capacity, 1)) {}

bool EventLog::push(const DriveEvent& event) noexcept {
  ++recorded_;
  if (count_ == ring_.size()) {
    ++dropped_;
    return false;
  }
  ring_[(head_ + count_) % ring_.size()] = event;
  ++count_;
  return true;
}

bool EventLog::pop(DriveEvent& out) noexcept {
  if (count_ == 0) return false;
  out = ring_[head_];
  head_ = (head_ + 1) % ring_.size();
  --count_;
  return true;
}

std::vector<DriveEvent> EventLog::snapshot() const {
  std::vector<DriveEvent> copy;
  copy.reserve(count_);
  for (std::size_t i = 0; i < count_; ++i) copy.push_back(ring_[(head_ + i) % ring_.size()]);
  return copy;
}

}  // namespace trainer::hal::simdrive
