// A configuration triple (double, as the TOML reader gives it) as the cycle's float vector.
#pragma once

#include <array>

#include <Eigen/Core>

namespace trainer::app {

inline Eigen::Vector3f to_vec3(const std::array<double, 3>& v) {
  return {static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])};
}

}  // namespace trainer::app
