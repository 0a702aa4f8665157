// Fault SPEC parsing and formatting.
#include "trainer/hal_simdrive/fault.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

namespace trainer::hal::simdrive {

namespace {

struct FaultKindName {
  FaultKind kind;
  const char* name;
};

constexpr std::array<FaultKindName, 11> kFaultKindNames = {{
    {FaultKind::drop, "drop"},
    {FaultKind::delay, "delay"},
    {FaultKind::corrupt, "corrupt"},
    {FaultKind::silent, "silent"},
    {FaultKind::bus_off, "bus_off"},
    {FaultKind::emcy, "emcy"},
    {FaultKind::encoder_jump, "encoder_jump"},
    {FaultKind::lost_sync, "lost_sync"},
    {FaultKind::reboot, "reboot"},
    {FaultKind::clear, "clear"},
    {FaultKind::push, "push"},
}};

constexpr std::string_view kFaultKindList =
    "drop, delay, corrupt, silent, bus_off, emcy, encoder_jump, lost_sync, reboot, clear, push";

std::string_view trim_spaces(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r' ||
                           text.back() == '\n')) {
    text.remove_suffix(1);
  }
  return text;
}

// Decimal or 0x-hex, optionally negative; false when not a whole number in range.
bool parse_whole(std::string_view text, std::int64_t low, std::int64_t high, std::int64_t& out) {
  bool negative = false;
  if (!text.empty() && text.front() == '-') {
    negative = true;
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  if (text.empty()) return false;
  std::uint64_t magnitude = 0;
  const auto [end, error] =
      std::from_chars(text.data(), text.data() + text.size(), magnitude, base);
  if (error != std::errc{} || end != text.data() + text.size()) return false;
  if (magnitude > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()))
    return false;
  const auto value =
      negative ? -static_cast<std::int64_t>(magnitude) : static_cast<std::int64_t>(magnitude);
  if (value < low || value > high) return false;
  out = value;
  return true;
}

bool parse_seconds(std::string_view text, double& out) {
  const std::string copy(text);
  char* end = nullptr;
  const double value = std::strtod(copy.c_str(), &end);
  if (copy.empty() || end != copy.c_str() + copy.size() || !std::isfinite(value) || value < 0.0 ||
      value > 1.0e6) {
    return false;
  }
  out = value;
  return true;
}

bool kind_has_node(FaultKind kind) {
  return kind != FaultKind::bus_off;
}
// A corruption or a lost SYNC lasts one SYNC unless told; the others until cleared.
std::uint32_t default_count(FaultKind kind) noexcept {
  return kind == FaultKind::corrupt || kind == FaultKind::lost_sync ? 1U : 0U;
}
bool kind_needs_node(FaultKind kind) {
  return kind != FaultKind::bus_off && kind != FaultKind::clear;
}

}  // namespace

const char* to_string(FaultKind kind) noexcept {
  for (const FaultKindName& entry : kFaultKindNames) {
    if (entry.kind == kind) return entry.name;
  }
  return "?";
}

core::Expected<FaultSpec> parse_fault_spec(std::string_view text) {
  text = trim_spaces(text);
  const std::string quoted = "fault '" + std::string(text) + "': ";
  const std::size_t colon = text.find(':');
  const std::string_view kind_text = trim_spaces(text.substr(0, colon));
  FaultSpec spec;
  bool known = false;
  for (const FaultKindName& entry : kFaultKindNames) {
    if (kind_text == entry.name) {
      spec.kind = entry.kind;
      known = true;
    }
  }
  if (!known) {
    return core::make_error(quoted + "unknown kind '" + std::string(kind_text) +
                            "': expected one of " + std::string(kFaultKindList));
  }
  spec.count = default_count(spec.kind);

  bool delay_given = false;
  std::string_view rest =
      colon == std::string_view::npos ? std::string_view{} : text.substr(colon + 1);
  while (!rest.empty()) {
    const std::size_t comma = rest.find(',');
    const std::string_view item = trim_spaces(rest.substr(0, comma));
    rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    if (item.empty()) continue;
    const std::size_t equals = item.find('=');
    if (equals == std::string_view::npos) {
      return core::make_error(quoted + "'" + std::string(item) + "' is not KEY=VALUE");
    }
    const std::string key(trim_spaces(item.substr(0, equals)));
    const std::string_view value = trim_spaces(item.substr(equals + 1));
    const std::string bad = quoted + key + " = '" + std::string(value) + "'";
    std::int64_t number = 0;
    if (key == "node") {
      if (!kind_has_node(spec.kind))
        return core::make_error(quoted + "bus_off concerns the whole bus: no node key");
      if (!parse_whole(value, 1, 127, number))
        return core::make_error(bad + ": expected a node id 1..127");
      spec.node_id = static_cast<std::uint8_t>(number);
    } else if (key == "at_sync") {
      if (!parse_whole(value, 1, std::numeric_limits<std::int64_t>::max(), number)) {
        return core::make_error(
            bad + ": expected a SYNC count >= 1 (1 = the first SYNC after NMT start)");
      }
      spec.at_sync = static_cast<std::uint64_t>(number);
    } else if (key == "at_s") {
      double seconds = 0.0;
      if (!parse_seconds(value, seconds))
        return core::make_error(bad + ": expected seconds 0..1e6");
      spec.at_ns = std::llround(seconds * 1e9);
    } else if (key == "count") {
      if (!parse_whole(value, 0, std::numeric_limits<std::uint32_t>::max(), number)) {
        return core::make_error(bad + ": expected a SYNC count (0 = until cleared)");
      }
      spec.count = static_cast<std::uint32_t>(number);
    } else if (key == "ms" && spec.kind == FaultKind::delay) {
      if (!parse_whole(value, 1, 10'000, number))
        return core::make_error(bad + ": expected 1..10000 ms");
      spec.delay_ns = number * 1'000'000;
      delay_given = true;
    } else if (key == "code" && spec.kind == FaultKind::emcy) {
      if (!parse_whole(value, 1, 0xFFFF, number)) {
        return core::make_error(bad + ": expected an emergency error code 0x0001..0xFFFF");
      }
      spec.code = static_cast<std::uint16_t>(number);
    } else if (key == "counts" && spec.kind == FaultKind::encoder_jump) {
      if (!parse_whole(value, std::numeric_limits<std::int32_t>::min(),
                       std::numeric_limits<std::int32_t>::max(), number) ||
          number == 0) {
        return core::make_error(bad + ": expected a non-zero number of encoder counts");
      }
      spec.counts = static_cast<std::int32_t>(number);
    } else if (key == "move" && spec.kind == FaultKind::push) {
      const std::string copy(value);
      char* end = nullptr;
      const double move = std::strtod(copy.c_str(), &end);
      if (copy.empty() || end != copy.c_str() + copy.size() || !std::isfinite(move) ||
          move == 0.0 || std::fabs(move) > 10.0) {
        return core::make_error(bad + ": expected a non-zero joint displacement, rad or m, "
                                      "within +-10");
      }
      spec.move = move;
    } else if (key == "mode" && spec.kind == FaultKind::corrupt) {
      if (value == "length") {
        spec.corrupt_mode = CorruptMode::length;
      } else if (value == "bits") {
        spec.corrupt_mode = CorruptMode::bits;
      } else {
        return core::make_error(bad + ": expected length or bits");
      }
    } else if (key == "byte" && spec.kind == FaultKind::corrupt) {
      if (!parse_whole(value, 0, 7, number))
        return core::make_error(bad + ": expected a data byte 0..7");
      spec.corrupt_byte = static_cast<std::uint8_t>(number);
    } else if (key == "mask" && spec.kind == FaultKind::corrupt) {
      if (!parse_whole(value, 1, 0xFF, number))
        return core::make_error(bad + ": expected an XOR mask 0x01..0xFF");
      spec.corrupt_mask = static_cast<std::uint8_t>(number);
    } else {
      return core::make_error(quoted + "unknown key '" + key + "' for " + to_string(spec.kind) +
                              " (keys: node, at_sync, at_s, count; delay: ms; emcy: code; "
                              "encoder_jump: counts; corrupt: mode, byte, mask; push: move)");
    }
  }
  if (spec.at_sync && spec.at_ns)
    return core::make_error(quoted + "at_sync and at_s both given: expected one");
  if (kind_needs_node(spec.kind) && spec.node_id == 0) {
    return core::make_error(quoted + "node=N missing: " + to_string(spec.kind) +
                            " concerns one drive");
  }
  if (spec.kind == FaultKind::delay && !delay_given)
    return core::make_error(quoted + "ms=D missing: how long to hold TPDOs back");
  if (spec.kind == FaultKind::encoder_jump && spec.counts == 0) {
    return core::make_error(quoted + "counts=N missing: by how many counts position actual jumps");
  }
  if (spec.kind == FaultKind::push && spec.move == 0.0) {
    return core::make_error(quoted + "move=D missing: how far the hand pushes the joint (rad or m)");
  }
  return spec;
}

std::size_t format_fault_spec(const FaultSpec& spec, std::span<char> out) noexcept {
  if (out.empty()) return 0;
  std::size_t used = 0;
  const auto append = [&](const char* format, auto... values) {
    if (used >= out.size()) return;
    const int written = std::snprintf(out.data() + used, out.size() - used, format, values...);
    if (written > 0) used = std::min(out.size() - 1, used + static_cast<std::size_t>(written));
  };
  append("%s", to_string(spec.kind));
  char separator = ':';
  const auto key = [&](const char* name) {
    append("%c%s=", separator, name);
    separator = ',';
  };
  if (spec.node_id != 0) {
    key("node");
    append("%u", static_cast<unsigned>(spec.node_id));
  }
  if (spec.at_sync) {
    key("at_sync");
    append("%llu", static_cast<unsigned long long>(*spec.at_sync));
  }
  if (spec.at_ns) {
    key("at_s");
    append("%.3f", static_cast<double>(*spec.at_ns) * 1e-9);
  }
  const bool lasting = spec.kind == FaultKind::drop || spec.kind == FaultKind::delay ||
                       spec.kind == FaultKind::corrupt || spec.kind == FaultKind::silent ||
                       spec.kind == FaultKind::lost_sync || spec.kind == FaultKind::bus_off ||
                       spec.kind == FaultKind::push;
  if (lasting && spec.count != default_count(spec.kind)) {
    key("count");
    append("%u", static_cast<unsigned>(spec.count));
  }
  switch (spec.kind) {
    case FaultKind::delay:
      key("ms");
      append("%lld", static_cast<long long>(spec.delay_ns / 1'000'000));
      break;
    case FaultKind::emcy:
      key("code");
      append("0x%04X", static_cast<unsigned>(spec.code));
      break;
    case FaultKind::encoder_jump:
      key("counts");
      append("%d", static_cast<int>(spec.counts));
      break;
    case FaultKind::push:
      key("move");
      append("%g", spec.move);
      break;
    case FaultKind::corrupt:
      key("mode");
      append("%s", spec.corrupt_mode == CorruptMode::length ? "length" : "bits");
      if (spec.corrupt_mode == CorruptMode::bits) {
        key("byte");
        append("%u", static_cast<unsigned>(spec.corrupt_byte));
        key("mask");
        append("0x%02X", static_cast<unsigned>(spec.corrupt_mask));
      }
      break;
    default: break;
  }
  return used;
}

std::string format_fault_spec(const FaultSpec& spec) {
  std::array<char, 128> text{};
  const std::size_t length = format_fault_spec(spec, text);
  return {text.data(), length};
}

}  // namespace trainer::hal::simdrive
