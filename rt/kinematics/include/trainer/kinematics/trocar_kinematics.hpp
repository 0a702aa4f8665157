// Kinematics of a laparoscopic instrument on a trocar pivot (Basdogan §V-B, Fig. 6).
//
// Joints: pitch θ and yaw ψ tilt the shaft about the fixed pivot, insertion d slides it
// (d = distance from the pivot to the closed jaws' tip), roll φ turns it about its own axis,
// grip g is the jaw opening angle. Frame: s = shaft axis at θ=ψ=0 (into the body), u = up
// axis (yaw turns about it), l = u × s (pitch turns about it). Shaft direction:
//   d̂(θ,ψ) = cosθ (cosψ s + sinψ l) + sinθ u
// Tip p = pivot + d·d̂. The jaws hinge at p − L_j d̂ and open symmetrically by ±g/2 in the
// plane of d̂ and the rolled opening direction n(φ) = cosφ u' + sinφ l' (u', l' ⟂ d̂).
//
// The tool's force at a point a distance `s` beyond the pivot along the shaft maps to joint
// efforts with the transposed Jacobian of that point: τ = Jᵀ F, with columns
//   ∂x/∂θ = s ∂d̂/∂θ, ∂x/∂ψ = s ∂d̂/∂ψ, ∂x/∂d = d̂.
// A torque about the shaft axis maps to the roll joint.
#pragma once

#include <array>
#include <cstddef>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

namespace trainer::kinematics {

using Vec3 = Eigen::Vector3f;

enum JointIndex : std::size_t { kPitch = 0, kYaw = 1, kInsertion = 2, kRoll = 3, kGrip = 4 };
constexpr std::size_t kJointCount = 5;
using JointVector = std::array<float, kJointCount>;  // rad, rad, m, rad, rad

struct TrocarGeometry {
  Vec3 pivot_m = Vec3::Zero();
  Vec3 shaft_axis = Vec3::UnitZ();  // unit
  Vec3 up_axis = Vec3::UnitY();     // unit, orthogonal to shaft_axis
  float shaft_length_m = 0.36F;
  float jaw_length_m = 0.015F;
};

struct InstrumentPose {
  Vec3 direction = Vec3::UnitZ();  // unit shaft direction d̂, into the body
  Vec3 tip_m = Vec3::Zero();       // closed-jaw tip, the point the wall scene collides
  Vec3 hinge_m = Vec3::Zero();     // jaw hinge, end of the rigid shaft
  Vec3 shaft_start_m = Vec3::Zero();  // handle end of the shaft (outside the body)
  std::array<Vec3, 2> jaw_tips_m{Vec3::Zero(), Vec3::Zero()};
  Vec3 d_direction_d_pitch = Vec3::Zero();  // ∂d̂/∂θ
  Vec3 d_direction_d_yaw = Vec3::Zero();    // ∂d̂/∂ψ
  float insertion_m = 0.0F;
};

class TrocarKinematics {
 public:
  TrocarKinematics() = default;
  explicit TrocarKinematics(const TrocarGeometry& geometry) noexcept;

  const TrocarGeometry& geometry() const noexcept { return geometry_; }

  InstrumentPose forward(const JointVector& joints) const noexcept;

  // Velocity of the point `distance_m` beyond the pivot along the shaft for joint rates q̇.
  static Vec3 point_velocity(const InstrumentPose& pose, float distance_m,
                             const JointVector& joint_rates) noexcept;

  // Adds Jᵀ F for a force `force_n` applied at `distance_m` beyond the pivot to `efforts`
  // (pitch and yaw in N·m, insertion in N), and the shaft-axis component of `torque_nm` to roll.
  static void add_joint_efforts(const InstrumentPose& pose, float distance_m, const Vec3& force_n,
                                const Vec3& torque_nm, JointVector& efforts) noexcept;

 private:
  TrocarGeometry geometry_{};
  Vec3 lateral_axis_ = Vec3::UnitX();  // u × s
};

}  // namespace trainer::kinematics
