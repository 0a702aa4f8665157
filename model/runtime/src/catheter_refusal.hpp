// Private to model/runtime: how the catheter's setup code (catheter.cpp, catheter_chain.cpp)
// tests a parameter and words a refusal: "catheter: <what>", numbers to 6 significant digits.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "trainer/core/expected.hpp"

namespace trainer::model::detail {

inline bool catheter_positive_finite(float value) noexcept {
  return std::isfinite(value) && value > 0.0F;
}

inline std::string catheter_number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

inline core::Error catheter_refusal(const std::string& what) {
  return core::make_error("catheter: " + what);
}

}  // namespace trainer::model::detail
