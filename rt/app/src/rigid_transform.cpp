#include "trainer/app/rigid_transform.hpp"

#include <numbers>

#include <Eigen/Geometry>

namespace trainer::app {

RigidTransform RigidTransform::from_placement(const std::array<double, 3>& position_m,
                                              const std::array<double, 3>& rotation_deg) noexcept {
  constexpr double kRadiansPerDegree = std::numbers::pi / 180.0;
  // Intrinsic X-Y-Z: each later rotation is about an axis already turned by the earlier ones,
  // which composes by right-multiplication.
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(rotation_deg[0] * kRadiansPerDegree, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(rotation_deg[1] * kRadiansPerDegree, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(rotation_deg[2] * kRadiansPerDegree, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  const Eigen::Vector3d translation(position_m[0], position_m[1], position_m[2]);
  return {rotation.cast<float>(), translation.cast<float>()};
}

}  // namespace trainer::app
