#include "trainer/hil/device_write.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/hil/device_edit.hpp"

namespace trainer::hil {

std::string read_whole_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Writes the corrections (if any, and if asked) into a device file: every change shown, then
// confirmed; the result must load before it replaces anything. Returns false on a setup error.
bool write_corrections(const WriteRequest& request, Operator& op, Report& report,
                       std::ostream& out, std::ostream& err) {
  const std::vector<Correction> corrections = all_corrections(report);
  if (corrections.empty()) return true;
  out << "corrections of " << request.device_file << ":\n";
  for (const Correction& c : corrections) {
    out << "  [" << c.table << "]" << (c.instrument.empty() ? "" : " of \"" + c.instrument + "\"")
        << " " << c.key << " " << (c.old_value.empty() ? "(absent)" : c.old_value) << " -> "
        << c.new_value << "  (" << c.why << ")\n";
  }
  if (request.target.empty()) {
    out << "  (not written: give --write-device FILE, or --fix to correct " << request.device_file
        << " itself)\n";
    return true;
  }
  const std::string& target = request.target;
  const std::string text = read_whole_file(request.device_file);
  auto edited = apply_corrections(text, request.device_file, corrections);
  if (!edited) {
    err << "hil: " << edited.error().message << '\n';
    return false;
  }
  for (const LineChange& change : edited->changes) {
    out << "  " << change.describe(target) << "\n    - " << (change.inserted ? "(new line)" : change.before)
        << "\n    + " << change.after << '\n';
  }
  std::error_code ignored;
  const bool overwrite_input = std::filesystem::equivalent(target, request.device_file, ignored);
  if (overwrite_input &&
      !op.confirm("Overwrite the input device file " + request.device_file + "?")) {
    err << "hil: the input device file is not overwritten without confirmation\n";
    return false;
  }
  if (!op.confirm("Write " + std::to_string(edited->changes.size()) + " change(s) to " + target + "?")) {
    out << "  not written (not confirmed)\n";
    return true;
  }
  const std::string temporary = target + ".hil-tmp";
  {
    std::ofstream file(temporary, std::ios::binary | std::ios::trunc);
    file << edited->text;
    if (!file) {
      err << "hil: cannot write " << temporary << '\n';
      return false;
    }
  }
  if (auto loaded = trainer::config::load_device(temporary); !loaded) {
    std::filesystem::remove(temporary, ignored);
    err << "hil: the corrected device file would not load, nothing written: "
              << loaded.error().message << '\n';
    return false;
  }
  std::filesystem::rename(temporary, target, ignored);
  if (ignored) {
    err << "hil: cannot replace " << target << ": " << ignored.message() << '\n';
    return false;
  }
  report.corrected_file = target;
  for (const LineChange& change : edited->changes) report.applied_changes.push_back(change.describe(target));
  out << "  written: " << target << '\n';
  return true;
}

}  // namespace trainer::hil
