// The vocabulary every part of `hil` (tools/hil, docs/hil.md) shares: what a scan finds, what a
// check step concludes, the person (or script) at the bench, and a proposed device-file
// correction. The CAN, GPIO and USB parts each produce these; the program prints them, writes
// the commissioning report (JSON + Markdown) and offers the corrections.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "trainer/config/device.hpp"

namespace trainer::hil {

enum class Outcome : std::uint8_t { pass, fail, skip };

inline std::string_view to_string(Outcome outcome) {
  switch (outcome) {
    case Outcome::pass: return "pass";
    case Outcome::fail: return "fail";
    case Outcome::skip: return "skip";
  }
  return "?";
}

// One measured number with its unit ("ms", "us", "counts/rad", "frames", ...).
struct Figure {
  std::string name;
  double value = 0.0;
  std::string unit;
};

// One step of `hil check` (or one comparison of `hil scan` with the device file).
struct StepResult {
  std::string id;     // stable, dotted: "can.left.pitch.encoder_direction", "gpio.estop.edge_to_latch"
  std::string title;  // for people: "left pitch: encoder direction"
  Outcome outcome = Outcome::skip;
  std::string reason;  // fail/skip: why, with the numbers; pass: a one-line summary
  std::vector<Figure> figures;
  nlohmann::json details = nlohmann::json::object();  // samples, distributions, identities
};

// Something found on the bench by `hil scan`.
struct ScanItem {
  std::string kind;  // "can_node", "usb_device", "gpio_chip", "gpio_line"
  std::string name;  // "node 3", "1209:0001 serial TRN-0001", "gpiochip0", "gpiochip0:4 estop"
  nlohmann::json properties = nlohmann::json::object();  // device type, identity, firmware, ...
};

// A change of one key of the device file that a measurement calls for. Never applied without
// being shown and confirmed (or --yes); applied by editing that key's line in place.
struct Correction {
  std::string table;  // TOML path of the table: "instrument.pitch" of instrument "left"
  std::string instrument;  // "" for tables outside [[instrument]]
  std::string key;
  std::string old_value;  // as TOML text, "" when the key is absent
  std::string new_value;  // as TOML text
  std::string why;        // the measurement behind it
};

// The person at the bench. A step that needs a hand (press the e-stop, move a joint) asks
// through this; in the bench VM a script answers (the program's --yes / --act options).
class Operator {
 public:
  virtual ~Operator() = default;
  // Asks for an action ("press and release the e-stop"); `action` is a stable id
  // ("gpio.estop.press"). Returns once the action was started (a person pressed Enter, or
  // the scripted action was launched); false when declined: the step is skipped.
  virtual bool request(std::string_view action, std::string_view instruction) = 0;
  // A yes/no question before something that changes state (apply a correction, apply torque).
  virtual bool confirm(std::string_view question) = 0;
};

// What every part gets: the device file when one was given, the operator, safety limits.
struct BenchContext {
  std::optional<config::DeviceConfig> device;  // `--device FILE`
  Operator* op = nullptr;
  double max_torque_fraction = 0.05;  // of each axis's current limit; `--torque-limit`
  std::int64_t slow_motion = 1;       // time stretch of an emulator (the bench VM), as the trainer's
  int trials = 0;                     // repeat counts for timed steps (0 = the step's default)
  double action_timeout_s = 10.0;     // how long a step waits for an operator's action
};

// A part's scan: what it found, and its comparison with the device file (missing, extra,
// wrong identity) as steps.
struct ScanSection {
  std::string part;  // "can", "gpio", "usb"
  std::vector<ScanItem> found;
  std::vector<StepResult> comparison;
  // What the comparison calls for (e.g. a node_id when the drive answers under another id).
  std::vector<Correction> corrections;
};

// A part's checks and the corrections its measurements call for.
struct CheckSection {
  std::string part;
  std::vector<StepResult> steps;
  std::vector<Correction> corrections;
  // The identities of what was checked (drives, devices), for the commissioning report.
  std::vector<ScanItem> bench;
};

// A part's checks when none can run: one skipped step `<part>.check` saying why.
inline CheckSection skipped_checks(const std::string& part, const std::string& title,
                                   const std::string& reason) {
  CheckSection section;
  section.part = part;
  StepResult step;
  step.id = part + ".check";
  step.title = title;
  step.reason = reason;
  section.steps.push_back(std::move(step));
  return section;
}

}  // namespace trainer::hil
