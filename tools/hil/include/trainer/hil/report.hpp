// The commissioning report of a `hil` run (docs/hil.md "Report"): what was found, every step with
// its figures, the corrections proposed (and which were written), and where it ran: as JSON (for
// tools; the format is documented in docs/hil.md), as Markdown (tables, for people) and as one
// human line per step. Setup path: allocates freely.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "trainer/hil/step.hpp"

namespace trainer::hil {

inline constexpr int kReportSchemaVersion = 1;

struct RunInfo {
  std::string command;       // "scan" or "check"
  std::string arguments;     // the command line, for the record
  std::string tool_version;  // the project's version
  std::string git_describe;  // of the source tree it was built from
  std::string date_utc;      // ISO 8601, when the run started
  std::string host;          // uname: node name, kernel release, machine
  std::optional<std::string> device_path;
  std::string device_sha256;  // of the device file as read ("" without one)
  std::int64_t slow_motion = 1;
  double torque_limit_fraction = 0.0;
};

struct Report {
  RunInfo run;
  std::vector<ScanSection> scans;
  std::vector<CheckSection> checks;
  // Set when corrections were written: the file written and what was changed, one line each.
  std::optional<std::string> corrected_file;
  std::vector<std::string> applied_changes;
};

struct Tally {
  int pass = 0;
  int fail = 0;
  int skip = 0;
};
Tally tally(const Report& report);
// 0 when nothing failed, 1 when a step failed (the program's exit status for a finished run).
int exit_status(const Report& report);
std::vector<Correction> all_corrections(const Report& report);

nlohmann::json step_to_json(const StepResult& step);
nlohmann::json correction_to_json(const Correction& correction);
nlohmann::json to_json(const Report& report);
std::string to_markdown(const Report& report);
// "PASS can.left.pitch.torque_limit  written 50 ‰, read back 50 ‰  [limit 50 permille]"
std::string human_line(const StepResult& step);

// "2026-11-27T19:20:33Z"
std::string utc_now_iso8601();
std::string host_description();
// Lower-case hex SHA-256 (FIPS 180-4) of `bytes`.
std::string sha256_hex(std::string_view bytes);

}  // namespace trainer::hil
