#include "trainer/hil/report.hpp"

#include <sys/utsname.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

namespace trainer::hil {

Tally tally(const Report& report) {
  Tally t;
  const auto count = [&t](const StepResult& step) {
    switch (step.outcome) {
      case Outcome::pass: ++t.pass; break;
      case Outcome::fail: ++t.fail; break;
      case Outcome::skip: ++t.skip; break;
    }
  };
  for (const ScanSection& scan : report.scans)
    for (const StepResult& step : scan.comparison) count(step);
  for (const CheckSection& check : report.checks)
    for (const StepResult& step : check.steps) count(step);
  return t;
}

int exit_status(const Report& report) { return tally(report).fail > 0 ? 1 : 0; }

std::vector<Correction> all_corrections(const Report& report) {
  std::vector<Correction> out;
  const auto add = [&out](const Correction& correction) {
    for (const Correction& seen : out) {
      if (seen.table == correction.table && seen.instrument == correction.instrument &&
          seen.key == correction.key && seen.new_value == correction.new_value) {
        return;
      }
    }
    out.push_back(correction);
  };
  for (const ScanSection& scan : report.scans)
    for (const Correction& c : scan.corrections) add(c);
  for (const CheckSection& check : report.checks)
    for (const Correction& c : check.corrections) add(c);
  return out;
}

nlohmann::json step_to_json(const StepResult& step) {
  nlohmann::json figures = nlohmann::json::array();
  for (const Figure& figure : step.figures) {
    figures.push_back({{"name", figure.name}, {"value", figure.value}, {"unit", figure.unit}});
  }
  return {{"id", step.id},         {"title", step.title},     {"outcome", to_string(step.outcome)},
          {"reason", step.reason}, {"figures", figures},      {"details", step.details}};
}

nlohmann::json correction_to_json(const Correction& c) {
  return {{"table", c.table},         {"instrument", c.instrument}, {"key", c.key},
          {"old_value", c.old_value}, {"new_value", c.new_value},   {"why", c.why}};
}

nlohmann::json to_json(const Report& report) {
  const RunInfo& run = report.run;
  nlohmann::json scans = nlohmann::json::array();
  for (const ScanSection& scan : report.scans) {
    nlohmann::json found = nlohmann::json::array();
    for (const ScanItem& item : scan.found) {
      found.push_back({{"kind", item.kind}, {"name", item.name}, {"properties", item.properties}});
    }
    nlohmann::json steps = nlohmann::json::array();
    for (const StepResult& step : scan.comparison) steps.push_back(step_to_json(step));
    nlohmann::json scan_corrections = nlohmann::json::array();
    for (const Correction& c : scan.corrections) scan_corrections.push_back(correction_to_json(c));
    scans.push_back({{"part", scan.part},
                     {"found", found},
                     {"comparison", steps},
                     {"corrections", scan_corrections}});
  }
  nlohmann::json checks = nlohmann::json::array();
  for (const CheckSection& check : report.checks) {
    nlohmann::json steps = nlohmann::json::array();
    for (const StepResult& step : check.steps) steps.push_back(step_to_json(step));
    nlohmann::json corrections = nlohmann::json::array();
    for (const Correction& c : check.corrections) corrections.push_back(correction_to_json(c));
    nlohmann::json bench = nlohmann::json::array();
    for (const ScanItem& item : check.bench) {
      bench.push_back({{"kind", item.kind}, {"name", item.name}, {"properties", item.properties}});
    }
    checks.push_back(
        {{"part", check.part}, {"bench", bench}, {"steps", steps}, {"corrections", corrections}});
  }
  nlohmann::json corrections = nlohmann::json::array();
  for (const Correction& c : all_corrections(report)) corrections.push_back(correction_to_json(c));
  const Tally t = tally(report);
  nlohmann::json device = nullptr;
  if (run.device_path) device = {{"path", *run.device_path}, {"sha256", run.device_sha256}};
  nlohmann::json corrected = nullptr;
  if (report.corrected_file) {
    corrected = {{"path", *report.corrected_file}, {"changes", report.applied_changes}};
  }
  return {{"schema_version", kReportSchemaVersion},
          {"tool", {{"name", "hil"}, {"version", run.tool_version}, {"git_describe", run.git_describe}}},
          {"command", run.command},
          {"arguments", run.arguments},
          {"date_utc", run.date_utc},
          {"host", run.host},
          {"device_file", device},
          {"slow_motion", run.slow_motion},
          {"torque_limit_fraction", run.torque_limit_fraction},
          {"scans", scans},
          {"checks", checks},
          {"corrections", corrections},
          {"corrected_device_file", corrected},
          {"summary", {{"pass", t.pass}, {"fail", t.fail}, {"skip", t.skip}}},
          {"exit_status", exit_status(report)}};
}

namespace {

std::string figure_text(const Figure& figure) {
  char text[96];
  const double magnitude = std::fabs(figure.value);
  if (magnitude != 0.0 && (magnitude >= 1e6 || magnitude < 1e-3)) {
    std::snprintf(text, sizeof text, "%.3g", figure.value);
  } else if (figure.value == std::floor(figure.value) && magnitude < 1e6) {
    std::snprintf(text, sizeof text, "%.0f", figure.value);
  } else {
    std::snprintf(text, sizeof text, "%.4g", figure.value);
  }
  std::string out = figure.name + " " + text;
  if (!figure.unit.empty()) out += " " + figure.unit;
  return out;
}

std::string figures_text(const StepResult& step, const char* separator) {
  std::string out;
  for (const Figure& figure : step.figures) {
    if (!out.empty()) out += separator;
    out += figure_text(figure);
  }
  return out;
}

// Markdown table cells: no line breaks, no bare pipes.
std::string cell(std::string text) {
  std::string out;
  for (const char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '\n') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

std::string upper(Outcome outcome) {
  switch (outcome) {
    case Outcome::pass: return "PASS";
    case Outcome::fail: return "FAIL";
    case Outcome::skip: return "SKIP";
  }
  return "?";
}

void step_table(std::ostringstream& md, const std::vector<StepResult>& steps) {
  md << "| step | outcome | reason | figures |\n|---|---|---|---|\n";
  for (const StepResult& step : steps) {
    md << "| `" << step.id << "` | " << upper(step.outcome) << " | " << cell(step.reason) << " | "
       << cell(figures_text(step, "; ")) << " |\n";
  }
  md << '\n';
}

void item_table(std::ostringstream& md, const std::vector<ScanItem>& items, const char* header) {
  md << "| " << header << " | properties |\n|---|---|\n";
  for (const ScanItem& item : items) {
    std::string properties;
    for (const auto& [key, value] : item.properties.items()) {
      if (!properties.empty()) properties += ", ";
      properties += key + " " + (value.is_string() ? value.get<std::string>() : value.dump());
    }
    md << "| " << cell(item.name) << " | " << cell(properties) << " |\n";
  }
  md << '\n';
}

}  // namespace

std::string human_line(const StepResult& step) {
  std::string line = upper(step.outcome) + " " + step.id;
  if (!step.reason.empty()) line += "  " + step.reason;
  const std::string figures = figures_text(step, ", ");
  if (!figures.empty()) line += "  [" + figures + "]";
  return line;
}

std::string to_markdown(const Report& report) {
  const RunInfo& run = report.run;
  const Tally t = tally(report);
  std::ostringstream md;
  md << "# Commissioning report: hil " << run.command << "\n\n";
  md << "| | |\n|---|---|\n";
  md << "| date (UTC) | " << run.date_utc << " |\n";
  md << "| host | " << cell(run.host) << " |\n";
  md << "| tool | hil " << run.tool_version << " (" << run.git_describe << ") |\n";
  md << "| command | `" << cell(run.arguments) << "` |\n";
  if (run.device_path) {
    md << "| device file | `" << cell(*run.device_path) << "` sha256 `" << run.device_sha256
       << "` |\n";
  }
  md << "| torque limit | " << run.torque_limit_fraction * 100.0 << " % of each axis's current "
     << "limit |\n";
  if (run.slow_motion > 1) md << "| slow motion | " << run.slow_motion << " |\n";
  md << "| result | " << t.pass << " pass, " << t.fail << " fail, " << t.skip << " skip |\n\n";
  for (const ScanSection& scan : report.scans) {
    md << "## Scan: " << scan.part << "\n\n";
    if (scan.found.empty()) {
      md << "Nothing found.\n\n";
    } else {
      item_table(md, scan.found, "found");
    }
    if (!scan.comparison.empty()) {
      md << "### Compared with the device file\n\n";
      step_table(md, scan.comparison);
    }
  }
  for (const CheckSection& check : report.checks) {
    md << "## Check: " << check.part << "\n\n";
    if (!check.bench.empty()) item_table(md, check.bench, "checked");
    step_table(md, check.steps);
  }
  const std::vector<Correction> corrections = all_corrections(report);
  if (!corrections.empty()) {
    md << "## Corrections of the device file\n\n| table | key | now | measured | why |\n"
          "|---|---|---|---|---|\n";
    for (const Correction& c : corrections) {
      md << "| " << cell(c.instrument.empty() ? "[" + c.table + "]"
                                              : "[" + c.table + "] of " + c.instrument)
         << " | `" << c.key << "` | " << cell(c.old_value.empty() ? "(absent)" : c.old_value)
         << " | " << cell(c.new_value) << " | " << cell(c.why) << " |\n";
    }
    md << '\n';
  }
  if (report.corrected_file) {
    md << "Written to `" << cell(*report.corrected_file) << "`:\n\n";
    for (const std::string& change : report.applied_changes) md << "- " << change << '\n';
    md << '\n';
  }
  return md.str();
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  ::gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::string host_description() {
  utsname name{};
  if (::uname(&name) != 0) return "unknown";
  return std::string(name.nodename) + " " + name.sysname + " " + name.release + " " + name.machine;
}

// ------------------------------------------------------------------------------ SHA-256

namespace {

constexpr std::array<std::uint32_t, 64> kSha256Round = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

constexpr std::uint32_t rotr(std::uint32_t x, unsigned n) { return (x >> n) | (x << (32U - n)); }

void sha256_block(std::array<std::uint32_t, 8>& h, const std::uint8_t* block) {
  std::array<std::uint32_t, 64> w{};
  for (std::size_t i = 0; i < 16; ++i) {
    w[i] = (static_cast<std::uint32_t>(block[4 * i]) << 24) |
           (static_cast<std::uint32_t>(block[4 * i + 1]) << 16) |
           (static_cast<std::uint32_t>(block[4 * i + 2]) << 8) | block[4 * i + 3];
  }
  for (std::size_t i = 16; i < 64; ++i) {
    const std::uint32_t s0 = rotr(w[i - 15], 7) ^ rotr(w[i - 15], 18) ^ (w[i - 15] >> 3);
    const std::uint32_t s1 = rotr(w[i - 2], 17) ^ rotr(w[i - 2], 19) ^ (w[i - 2] >> 10);
    w[i] = w[i - 16] + s0 + w[i - 7] + s1;
  }
  std::array<std::uint32_t, 8> v = h;
  for (std::size_t i = 0; i < 64; ++i) {
    const std::uint32_t s1 = rotr(v[4], 6) ^ rotr(v[4], 11) ^ rotr(v[4], 25);
    const std::uint32_t ch = (v[4] & v[5]) ^ (~v[4] & v[6]);
    const std::uint32_t t1 = v[7] + s1 + ch + kSha256Round[i] + w[i];
    const std::uint32_t s0 = rotr(v[0], 2) ^ rotr(v[0], 13) ^ rotr(v[0], 22);
    const std::uint32_t maj = (v[0] & v[1]) ^ (v[0] & v[2]) ^ (v[1] & v[2]);
    const std::uint32_t t2 = s0 + maj;
    v[7] = v[6];
    v[6] = v[5];
    v[5] = v[4];
    v[4] = v[3] + t1;
    v[3] = v[2];
    v[2] = v[1];
    v[1] = v[0];
    v[0] = t1 + t2;
  }
  for (std::size_t i = 0; i < 8; ++i) h[i] += v[i];
}

}  // namespace

std::string sha256_hex(std::string_view bytes) {
  std::array<std::uint32_t, 8> h = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                    0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
  std::string data(bytes);
  const std::uint64_t bits = static_cast<std::uint64_t>(bytes.size()) * 8U;
  data.push_back(static_cast<char>(0x80));
  while (data.size() % 64 != 56) data.push_back('\0');
  for (int i = 7; i >= 0; --i) data.push_back(static_cast<char>((bits >> (8 * i)) & 0xFFU));
  for (std::size_t offset = 0; offset < data.size(); offset += 64) {
    sha256_block(h, reinterpret_cast<const std::uint8_t*>(data.data() + offset));
  }
  std::string out;
  char text[9];
  for (const std::uint32_t word : h) {
    std::snprintf(text, sizeof text, "%08x", word);
    out += text;
  }
  return out;
}

}  // namespace trainer::hil
