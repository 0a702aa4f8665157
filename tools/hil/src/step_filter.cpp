#include "trainer/hil/step_filter.hpp"

namespace trainer::hil {


bool StepFilter::wants(std::string_view id) const {
  if (only_.empty()) return true;
  for (const std::string& entry : only_) {
    const std::size_t slash = entry.find('/');
    const std::string part = entry.substr(0, slash);
    if (!id.starts_with(part + ".")) continue;
    if (slash == std::string::npos) return true;
    const std::string name = entry.substr(slash + 1);
    const std::string_view rest = id.substr(part.size() + 1);
    // A step name ("heartbeat_loss") matches the last component; anything else is a prefix of
    // the id after the part ("left.pitch", "left.pitch.encoder_direction", "bus").
    const std::size_t dot = rest.rfind('.');
    const std::string_view last = dot == std::string_view::npos ? rest : rest.substr(dot + 1);
    if (last == name) return true;
    if (rest == name || rest.starts_with(name + ".")) return true;
  }
  return false;
}

bool StepFilter::wants_any_under(std::string_view prefix,
                                 std::initializer_list<const char*> steps) const {
  if (only_.empty()) return true;
  for (const char* step : steps) {
    if (wants(std::string(prefix) + "." + step)) return true;
  }
  return false;
}

bool StepFilter::wants_part(std::string_view part) const {
  if (only_.empty()) return true;
  for (const std::string& entry : only_) {
    if (entry.substr(0, entry.find('/')) == part) return true;
  }
  return false;
}

}  // namespace trainer::hil
