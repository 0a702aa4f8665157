// Writing the corrections of a run into a device file (the program's --write-device / --fix):
// every correction listed, every line change shown (file:line, old and new line, why), then
// confirmed through the Operator; overwriting the input file needs its own confirmation; the
// corrected text must load (config::load_device) before it replaces anything, and goes through
// a temporary file renamed into place. On success the report records the file and changes.
#pragma once

#include <ostream>
#include <string>

#include "trainer/hil/report.hpp"
#include "trainer/hil/step.hpp"

namespace trainer::hil {

struct WriteRequest {
  std::string device_file;  // the file the run read
  std::string target;       // where to write; "" = only list the corrections
};

// True when nothing had to be written or the file was written (or the operator declined the
// write itself); false on an error or a refused overwrite of the input (messages on `err`).
bool write_corrections(const WriteRequest& request, Operator& op, Report& report,
                       std::ostream& out, std::ostream& err);

std::string read_whole_file(const std::string& path);

}  // namespace trainer::hil
