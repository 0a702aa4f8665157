// Parsing of modelc's compound option values ("GROUP=DOFS", "GROUP=FX,FY,FZ",
// "R,L,RINGS,SEGMENTS", element names). Tool code: errors are thrown as std::invalid_argument
// whose message names the option, the text and what was expected.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"

#include "trainer/model_offline/shell_model.hpp"

namespace trainer::tools::modelc {

// A setup result or an exception carrying its message (tools may throw; main reports it).
template <class T>
T value_or_throw(core::Expected<T> result) {
  if (!result) throw std::runtime_error(result.error().message);
  return std::move(result).value();
}

// --fix GROUP=DOFS, DOFS a comma list of x, y, z, rx, ry, rz (ux, uy, uz accepted) or "all".
model::offline::DofFix parse_fix(const std::string& text);

// --load / --surface-load GROUP=X,Y,Z.
struct GroupVector {
  std::string group;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
};
GroupVector parse_group_vector(const std::string& text, const std::string& option);

// --tube R,L,RINGS,SEGMENTS (m, m, node rings ≥ 2, nodes per ring ≥ 3).
struct TubeSpec {
  double radius_m = 0.0;
  double length_m = 0.0;
  int rings = 0;
  int segments = 0;
};
TubeSpec parse_tube(const std::string& text);

// --element shell-rao | shell-dkt.
model::offline::BendingElement parse_element(const std::string& text);
const char* element_name(model::offline::BendingElement element);

}  // namespace trainer::tools::modelc
