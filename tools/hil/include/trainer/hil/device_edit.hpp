// Corrections written into a device file: each key's line edited in place (value replaced,
// the rest of the line — indentation, alignment, trailing comment — kept), or, for a key the
// table does not have yet, a line added at the end of that table. Only the table the
// correction names is touched: [instrument.<joint>] of the [[instrument]] whose name matches,
// or a top-level table ([canopen]). Refused (an error naming file:line and why): a table or
// instrument the file does not have, a key whose value spans lines, two different values for
// one key. The text is edited, never re-serialised, so comments and layout survive.
#pragma once

#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/hil/step.hpp"

namespace trainer::hil {

struct LineChange {
  std::size_t line = 0;  // 1-based, in the edited text
  bool inserted = false;
  std::string before;  // the line as it was ("" when inserted)
  std::string after;   // the line as written
  const Correction* correction = nullptr;
  // "device.toml:42: [instrument.yaw] of \"left\" encoder_direction 1 -> -1 (why)"
  std::string describe(std::string_view file_name) const;
};

struct EditedFile {
  std::string text;
  std::vector<LineChange> changes;
};

core::Expected<EditedFile> apply_corrections(std::string_view text, std::string_view file_name,
                                             std::span<const Correction> corrections);

}  // namespace trainer::hil
