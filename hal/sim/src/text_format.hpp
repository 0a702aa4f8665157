// A number as text for a setup-path message ("0.25", "1e-09"). Private to hal/sim.
#pragma once

#include <sstream>
#include <string>

namespace trainer::hal::sim::detail {

inline std::string format_number(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace trainer::hal::sim::detail
