// Kinematics of a laparoscopic instrument on a trocar pivot (Basdogan §V-B, Fig. 6) and the
// mapping of contact forces and torques on its three segments to joint efforts (Basdogan §VII:
// ray-based rendering gives forces anywhere on the shaft and jaws, plus torques).
//
// Joints: pitch θ and yaw ψ tilt the shaft about the fixed pivot, insertion d slides it
// (d = distance from the pivot to the closed jaws' tip), roll φ turns it about its own axis,
// grip g is the jaw opening angle. Frame: s = shaft axis at θ=ψ=0 (into the body), u = up
// axis (yaw turns about it), l = u × s. Shaft direction:
//   d̂(θ,ψ) = cosθ (cosψ s + sinψ l) + sinθ u
// Tip p = pivot + d·d̂. The jaws hinge at p − L_j d̂ and open symmetrically by ±g/2 in the
// plane of d̂ and the opening direction n(φ): e = ∂d̂/∂θ (the transported "up") turned by φ
// about +d̂ (right hand), n = cosφ e + sinφ (d̂ × e).
//
// Rotation axes of the joints (angular velocity per unit rate, used for torques):
//   pitch: d̂ × e (the pivot stays fixed),   yaw: u,   roll: +d̂,
//   grip: ±½ (d̂ × n) about the hinge for jaw 0 / jaw 1 (jaw 0 opens toward +n).
// Sign of grip: positive grip opens the jaws, so a force pushing the jaws closed gives a
// NEGATIVE grip effort (the handle actuator must push the handle open to resist it).
//
// The tool's force at a point maps to joint efforts with the transposed Jacobian of that
// point: τ_j = (∂x/∂q_j) · F (virtual work). For a point x on the instrument and the moment
// m = (x − pivot) × F about the pivot:
//   τ_θ = (d̂ × e)·m,  τ_ψ = u·m,  τ_d = d̂·F,  τ_φ = d̂·m (zero on the shaft axis),
//   τ_g = (∂x/∂g)·F = a·½(−sin(g/2) d̂ ± cos(g/2) n)·F for a point a metres along jaw 0 / 1.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products

namespace trainer::kinematics {

using Vec3 = Eigen::Vector3f;

enum JointIndex : std::size_t { kPitch = 0, kYaw = 1, kInsertion = 2, kRoll = 3, kGrip = 4 };
constexpr std::size_t kJointCount = 5;
using JointVector = std::array<float, kJointCount>;  // rad, rad, m, rad, rad

// The three line segments of the forceps' computational model (Basdogan Fig. 6a).
enum class Segment : std::uint8_t { shaft, jaw0, jaw1 };

// A point on the instrument. `along_m` is measured on the segment: from the shaft start
// (handle end) toward the hinge for the shaft, from the hinge toward the jaw tip for a jaw.
// On the segment means 0 ≤ along_m ≤ shaft_length_m − jaw_length_m (shaft) or ≤ jaw_length_m
// (jaw); values outside extrapolate the segment's line and are not clamped.
struct InstrumentPoint {
  Segment segment = Segment::shaft;
  float along_m = 0.0F;
};

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
  // Unit vectors hinge → jaw tip: cos(g/2) d̂ ± sin(g/2) n.
  std::array<Vec3, 2> jaw_directions{Vec3::UnitZ(), Vec3::UnitZ()};
  Vec3 opening_direction = Vec3::UnitY();  // n, unit, ⟂ d̂; jaw 0 opens toward it
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
  // For a shaft point this equals add_wrench_efforts except for one term: yaw turns the
  // instrument about u, which has a component sinθ along d̂, so an axial torque also loads
  // yaw by u·T; this shortcut leaves that out (exact when the torque is zero).
  static void add_joint_efforts(const InstrumentPose& pose, float distance_m, const Vec3& force_n,
                                const Vec3& torque_nm, JointVector& efforts) noexcept;

  // World position (m) of `point` on the instrument in `pose`.
  static Vec3 position(const InstrumentPose& pose, const InstrumentPoint& point) noexcept;

  // Adds the exact virtual-work efforts τ_j = (∂x/∂q_j)·F of a force `force_n` (N, world) at
  // `point` to all five joints of `efforts`: pitch, yaw, roll and grip in N·m, insertion in N.
  // `pose` must come from forward() of this object: it carries n and the jaw directions, so
  // no joint vector is taken (pose and joints could otherwise disagree).
  void add_point_force_efforts(const InstrumentPose& pose, const InstrumentPoint& point,
                               const Vec3& force_n, JointVector& efforts) const noexcept;

  // Force at `point` plus a pure torque `torque_nm` (N·m, world) acting on the body of
  // `point.segment`: the torque maps through the rotational Jacobian, τ_j += ω_j · T, with the
  // joint axes of the header comment (the grip axis only for a jaw; a pure torque on the
  // shaft loads pitch, yaw and roll).
  void add_wrench_efforts(const InstrumentPose& pose, const InstrumentPoint& point,
                          const Vec3& force_n, const Vec3& torque_nm,
                          JointVector& efforts) const noexcept;

 private:
  TrocarGeometry geometry_{};
  Vec3 lateral_axis_ = Vec3::UnitX();  // u × s
};

}  // namespace trainer::kinematics
