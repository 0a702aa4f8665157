// candecode: reads a `candump -l` log (or `candump -L` lines) and prints every frame decoded
// as CANopen: NMT, SYNC, heartbeat/boot-up, EMCY with its error code's meaning, SDO requests
// and responses (command, object, data, abort code meaning), SocketCAN error frames, and the
// PDOs of the trainer's CiA 402 layout (hal_socketcan/canopen_device.hpp). With --device the
// nodes are named after the joints of that device file.
//
// Exit status: 0 every frame decoded, 1 a line could not be parsed or a frame is malformed for
// its COB-ID (the count is printed), 2 usage error. --summary prints counts per frame kind only.
#include <linux/can.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "trainer/config/device.hpp"
#include "trainer/hal_canopen/bus_error.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/sdo.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace co = trainer::hal::canopen;

namespace {

struct LogLine {
  std::string time;       // "(1700000000.123456)" as written, or ""
  std::string interface;  // "vcan0"
  can_frame frame{};
};

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// "(time) iface ID#DATA" (candump -l / -L). ID: 3 hex digits = 11-bit, 8 = 29-bit or an error
// frame (CAN_ERR_FLAG written in the id). DATA: hex byte pairs, or R for a remote frame.
std::optional<LogLine> parse_line(const std::string& text) {
  std::istringstream in(text);
  LogLine line;
  std::string token;
  if (!(in >> token)) return std::nullopt;
  if (token.front() == '(') {
    line.time = token;
    if (!(in >> line.interface)) return std::nullopt;
  } else {
    line.interface = token;
  }
  std::string frame_text;
  if (!(in >> frame_text)) return std::nullopt;
  const auto hash = frame_text.find('#');
  if (hash == std::string::npos || frame_text.find("##") != std::string::npos) return std::nullopt;
  const std::string id = frame_text.substr(0, hash);
  const std::string data = frame_text.substr(hash + 1);
  if (id.size() != 3 && id.size() != 8) return std::nullopt;
  canid_t value = 0;
  for (char c : id) {
    const int digit = hex_value(c);
    if (digit < 0) return std::nullopt;
    value = (value << 4) | static_cast<canid_t>(digit);
  }
  if (id.size() == 8 && (value & CAN_ERR_FLAG) == 0U) value |= CAN_EFF_FLAG;
  line.frame.can_id = value;
  if (!data.empty() && (data[0] == 'R' || data[0] == 'r')) {
    line.frame.can_id |= CAN_RTR_FLAG;
    line.frame.len = data.size() > 1 ? static_cast<std::uint8_t>(hex_value(data[1])) : 0;
    return line;
  }
  if (data.size() % 2 != 0 || data.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < data.size(); i += 2) {
    const int high = hex_value(data[i]);
    const int low = hex_value(data[i + 1]);
    if (high < 0 || low < 0) return std::nullopt;
    line.frame.data[i / 2] = static_cast<std::uint8_t>(high * 16 + low);
  }
  line.frame.len = static_cast<std::uint8_t>(data.size() / 2);
  return line;
}

std::uint32_t le(const can_frame& f, std::size_t at, std::size_t bytes) {
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < bytes; ++i) value |= static_cast<std::uint32_t>(f.data[at + i]) << (8 * i);
  return value;
}

std::string hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

std::string object(const can_frame& f) {
  return hex(le(f, 1, 2), 4) + ":" + hex(f.data[3], 2).substr(2);
}

// SDO request (client -> server) or response; CiA 301 7.2.4.3.
std::string describe_sdo(const can_frame& f, bool request) {
  if (f.len != 8) return "SDO with length " + std::to_string(f.len) + " (expected 8)";
  const std::uint8_t command = f.data[0];
  const std::uint8_t cs = co::sdo_command_specifier(command);
  if (cs == co::kCsAbort) {
    const std::uint32_t code = le(f, 4, 4);
    return "abort " + object(f) + " " + hex(code, 8) + " (" + co::describe_sdo_abort(code) + ")";
  }
  const bool expedited = (command & 0x02U) != 0;
  const bool sized = (command & 0x01U) != 0;
  const unsigned unused = (command >> 2) & 0x03U;
  const auto expedited_data = [&] {
    const unsigned bytes = sized ? 4 - unused : 4;
    return hex(le(f, 4, bytes), static_cast<int>(2 * bytes));
  };
  const auto segment = [&](const char* what) {
    const unsigned unused_bytes = (command >> 1) & 0x07U;
    return std::string(what) + " segment toggle " + std::to_string((command >> 4) & 1U) + ", " +
           std::to_string(7 - unused_bytes) + " bytes" + ((command & 1U) != 0 ? ", last" : "");
  };
  if (request) {
    switch (cs) {
      case co::kCcsInitiateDownload:
        return "write " + object(f) + " = " +
               (expedited ? expedited_data()
                          : "(segmented, " + std::to_string(le(f, 4, 4)) + " bytes)");
      case co::kCcsInitiateUpload: return "read " + object(f);
      case co::kCcsDownloadSegment: return segment("write");
      case co::kCcsUploadSegment: return "read segment toggle " + std::to_string((command >> 4) & 1U);
      default: return "request with command specifier " + std::to_string(cs);
    }
  }
  switch (cs) {
    case co::kScsInitiateDownload: return "write " + object(f) + " ok";
    case co::kScsInitiateUpload:
      return "read " + object(f) + " = " +
             (expedited ? expedited_data()
                        : "(segmented, " + std::to_string(le(f, 4, 4)) + " bytes)");
    case co::kScsDownloadSegment: return "write segment ok, toggle " + std::to_string((command >> 4) & 1U);
    case co::kScsUploadSegment: return segment("read");
    default: return "response with command specifier " + std::to_string(cs);
  }
}

// The trainer's PDO layout (canopen_device.hpp).
std::string describe_pdo(const can_frame& f, const co::FrameClass& c) {
  char text[160];
  if (c.kind == co::FrameKind::rpdo && c.pdo_number == 1 && f.len == 4) {
    std::snprintf(text, sizeof text, "controlword 0x%04X, target torque %d permille", le(f, 0, 2),
                  static_cast<std::int16_t>(le(f, 2, 2)));
  } else if (c.kind == co::FrameKind::rpdo && c.pdo_number == 2 && f.len == 4) {
    std::snprintf(text, sizeof text, "digital outputs 0x%08X", le(f, 0, 4));
  } else if (c.kind == co::FrameKind::tpdo && c.pdo_number == 1 && f.len == 8) {
    std::snprintf(text, sizeof text, "statusword 0x%04X, position %d counts, torque %d permille",
                  le(f, 0, 2), static_cast<std::int32_t>(le(f, 2, 4)),
                  static_cast<std::int16_t>(le(f, 6, 2)));
  } else if (c.kind == co::FrameKind::tpdo && c.pdo_number == 2 && f.len == 8) {
    std::snprintf(text, sizeof text, "velocity %d, digital inputs 0x%08X",
                  static_cast<std::int32_t>(le(f, 0, 4)), le(f, 4, 4));
  } else {
    std::snprintf(text, sizeof text, "%u bytes (not the trainer's layout)", f.len);
  }
  return text;
}

struct Decoded {
  std::string text;
  bool ok = true;
};

Decoded decode(const can_frame& f, const std::map<int, std::string>& names) {
  const co::FrameClass c = co::classify(f);
  const auto node = [&](int id) {
    const auto it = names.find(id);
    return "node " + std::to_string(id) + (it != names.end() ? " (" + it->second + ")" : "");
  };
  if (c.kind == co::FrameKind::error_frame) {
    const auto error = co::decode_bus_error(f);
    if (!error) return {"error frame, malformed", false};
    std::array<char, 200> buffer{};
    return {"ERROR FRAME " + std::string(co::format_bus_error(*error, buffer)), true};
  }
  if (!c.ok()) {
    return {std::string(co::to_string(c.kind)) + " " + co::to_string(c.problem), false};
  }
  switch (c.kind) {
    case co::FrameKind::nmt: {
      const auto nmt = co::decode_nmt(f);
      if (!nmt) return {"NMT malformed", false};
      return {std::string("NMT ") + co::to_string(nmt->command) + " " +
                  (nmt->node_id == 0 ? std::string("all nodes") : node(nmt->node_id)),
              true};
    }
    case co::FrameKind::sync: {
      const auto sync = co::decode_sync(f);
      if (!sync) return {"SYNC malformed", false};
      return {"SYNC" + (sync->counter ? " counter " + std::to_string(*sync->counter) : ""), true};
    }
    case co::FrameKind::heartbeat: {
      const auto beat = co::decode_heartbeat(f);
      if (!beat) return {"heartbeat malformed", false};
      return {(beat->state == co::NmtState::boot_up ? std::string("BOOT-UP ")
                                                    : std::string("heartbeat ")) +
                  node(beat->node_id) + " " + co::to_string(beat->state),
              true};
    }
    case co::FrameKind::emcy: {
      const auto emcy = co::decode_emcy(f);
      if (!emcy) return {"EMCY malformed", false};
      return {"EMCY " + node(emcy->node_id) + " " + hex(emcy->error_code, 4) + " (" +
                  co::describe_emcy_code(emcy->error_code) + "), error register " +
                  hex(emcy->error_register, 2),
              true};
    }
    case co::FrameKind::sdo_request: return {"SDO -> " + node(c.node_id) + " " + describe_sdo(f, true), f.len == 8};
    case co::FrameKind::sdo_response: return {"SDO <- " + node(c.node_id) + " " + describe_sdo(f, false), f.len == 8};
    case co::FrameKind::rpdo:
    case co::FrameKind::tpdo:
      return {std::string(c.kind == co::FrameKind::rpdo ? "RPDO" : "TPDO") +
                  std::to_string(c.pdo_number) + " " + node(c.node_id) + " " + describe_pdo(f, c),
              true};
    case co::FrameKind::time: return {"TIME", true};
    default: return {"unknown COB-ID " + hex(co::frame_id(f), 3), false};
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"Decodes a candump -l log of a CANopen bus (the trainer's CiA 402 layout)"};
  std::string log_file;
  std::string device_file;
  bool summary_only = false;
  cli.add_option("log", log_file, "candump -l log file ('-' = stdin)")->required();
  cli.add_option("--device", device_file, "Device file naming the nodes (backend canopen)")
      ->check(CLI::ExistingFile);
  cli.add_flag("--summary", summary_only, "Print only the counts per frame kind");
  CLI11_PARSE(cli, argc, argv);

  std::map<int, std::string> names;
  if (!device_file.empty()) {
    auto device = trainer::config::load_device(device_file);
    if (!device) {
      std::cerr << "candecode: " << device.error().message << "\n";
      return 2;
    }
    for (const auto& instrument : device->instruments) {
      for (std::size_t j = 0; j < instrument.joints.size(); ++j) {
        const int node = instrument.joints[j].canopen.node_id;
        if (node > 0) {
          names[node] = instrument.name + "." +
                        std::string(trainer::config::to_string(static_cast<trainer::config::JointId>(j)));
        }
      }
    }
  }
  std::ifstream file;
  if (log_file != "-") {
    file.open(log_file);
    if (!file) {
      std::cerr << "candecode: cannot read '" << log_file << "'\n";
      return 2;
    }
  }
  std::istream& in = log_file == "-" ? std::cin : file;
  std::map<std::string, std::uint64_t> counts;
  std::uint64_t frames = 0;
  std::uint64_t bad = 0;
  std::string text;
  std::uint64_t line_number = 0;
  while (std::getline(in, text)) {
    ++line_number;
    if (text.empty()) continue;
    const auto line = parse_line(text);
    if (!line) {
      ++bad;
      std::cout << "line " << line_number << ": cannot parse '" << text << "'\n";
      continue;
    }
    ++frames;
    const Decoded decoded = decode(line->frame, names);
    if (!decoded.ok) ++bad;
    const co::FrameClass c = co::classify(line->frame);
    ++counts[std::string(co::to_string(c.kind)) +
             (c.pdo_number != 0 ? std::to_string(c.pdo_number) : std::string())];
    if (!summary_only) {
      std::cout << line->time << (line->time.empty() ? "" : " ") << line->interface << " "
                << (decoded.ok ? "" : "MALFORMED ") << decoded.text << "\n";
    }
  }
  std::cout << "candecode: " << frames << " frames";
  for (const auto& [kind, count] : counts) std::cout << ", " << kind << " " << count;
  std::cout << "; " << bad << " undecodable\n";
  return bad == 0 ? 0 : 1;
}
