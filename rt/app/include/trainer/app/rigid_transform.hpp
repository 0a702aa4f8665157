// Placement of a model in the trainer frame: a rotation and a translation, built once at
// create() from the scene's [[model]] position_m / rotation_deg (docs/config.md) and stored
// beside the model. Models are built in their own frame (the duct along +x from x = 0);
// contact code maps tool points into that frame and forces back out with this.
//
//   x_world = R · x_model + t,   x_model = Rᵀ · (x_world − t)
//   R = Rx(rx) · Ry(ry) · Rz(rz): intrinsic rotations, about x, then the turned y, then the
//   turned z (the same as extrinsic z, then y, then x about the fixed trainer axes).
//
// The mapping functions are RT-safe (float, noexcept, no heap); construction is setup-path.
#pragma once

#include <array>

#include <Eigen/Core>

namespace trainer::app {

class RigidTransform {
 public:
  using Vec3 = Eigen::Vector3f;
  using Mat3 = Eigen::Matrix3f;

  RigidTransform() = default;  // identity
  // `rotation` must be a proper rotation matrix (orthonormal, det +1); not checked here.
  RigidTransform(const Mat3& rotation, const Vec3& translation_m) noexcept
      : rotation_(rotation), translation_m_(translation_m) {}

  // From a scene's placement: translation in metres, [rx, ry, rz] in degrees as above.
  // Computed in double and rounded once to float.
  static RigidTransform from_placement(const std::array<double, 3>& position_m,
                                       const std::array<double, 3>& rotation_deg) noexcept;

  Vec3 to_world(const Vec3& model_point_m) const noexcept {
    return rotation_ * model_point_m + translation_m_;
  }
  Vec3 to_model(const Vec3& world_point_m) const noexcept {
    return rotation_.transpose() * (world_point_m - translation_m_);
  }
  // Free vectors (forces, normals, velocities): rotated, never translated.
  Vec3 vector_to_world(const Vec3& model_vector) const noexcept { return rotation_ * model_vector; }
  Vec3 vector_to_model(const Vec3& world_vector) const noexcept {
    return rotation_.transpose() * world_vector;
  }

  const Mat3& rotation() const noexcept { return rotation_; }
  const Vec3& translation_m() const noexcept { return translation_m_; }

 private:
  Mat3 rotation_ = Mat3::Identity();
  Vec3 translation_m_ = Vec3::Zero();
};

}  // namespace trainer::app
