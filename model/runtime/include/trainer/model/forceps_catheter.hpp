// Forceps against the particle catheter (Basdogan §VII, METHODS.md §4): ray-based contact of
// the instrument's three line segments (shaft and two jaws, each a capsule) with the
// catheter's centreline segments, and grasping.
//
// Contact: every catheter segment (particles i, i+1, radius r_c) within reach + margin of a
// tool segment (radius r_s) gives one model::ContactPlane at the closest points: the plane
// through the point on the tool's axis with the normal towards the catheter, reach r_c + r_s,
// evaluated by the catheter at every substep. A closest point at the far particle of a segment
// is left to the next segment (t = 0 there), so a particle is not pushed twice. After the step
// the plane's mean force, reversed, acts on the tool at its closest point (segment + distance
// along it): that is what the instrument's Jacobian maps to joint efforts, so a catheter
// pressing on the shaft loads pitch and yaw through the lever about the trocar (the paper's
// coupling moments).
//
// Grasping: when the jaws are closing (the grip angle fell since the last cycle) and both touch the catheter (within reach, on the same or neighbouring
// catheter segments) the segment jaw 0 touches is grasped: its two particles are held in the
// jaw frame (origin the hinge, axes d̂, n, d̂ × n) where they were, so the catheter follows the
// jaws. The squeeze on each jaw is k_g·(r_c + r_j − distance from the grasped point to the jaw
// axis), clipped to [0, max_grasp_force_n]: the jaws stop where they touch and the handle
// feels the grasp force (through the grip joint's Jacobian). The catheter's pull on the held
// particles goes to the jaws too. The grasp ends when a jaw no longer squeezes (opened) or when
// the pull exceeds friction_coefficient × the total squeeze (the catheter slips out; judged
// from grasp_settle_cycles after the grasp began); a slip blocks re-grasping for
// regrasp_delay_cycles, and so does an opening (the jaws pass the touching angle on their way
// open and must not grasp again on the way).
//
// Runtime code: float, noexcept, no heap after create(), fixed capacities (the planes one
// tool may add per cycle, the tool forces). Trainer frame throughout. One thread owns it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/geometry.hpp"

namespace trainer::model {

// The instrument's segments this cycle (what kinematics::InstrumentPose carries).
struct ForcepsShape {
  Vec3 shaft_start_m = Vec3::Zero();  // handle end of the shaft
  Vec3 hinge_m = Vec3::Zero();        // end of the shaft, jaw hinge
  std::array<Vec3, 2> jaw_tips_m{Vec3::Zero(), Vec3::Zero()};
  Vec3 direction = Vec3::UnitZ();          // d̂, unit, shaft direction into the body
  Vec3 opening_direction = Vec3::UnitY();  // n, unit ⟂ d̂: jaw 0 opens toward it
  float grip_rad = 0.0F;                   // jaw opening angle g (jaws at ±g/2)
  Vec3 velocity_m_per_s = Vec3::Zero();    // of the jaws, for the contact damper
};

struct ForcepsContactSettings {
  float shaft_radius_m = 2.5e-3F;       // ≥ 0: a 5 mm instrument
  float jaw_radius_m = 1.0e-3F;         // ≥ 0
  float stiffness_n_per_m = 300.0F;     // > 0 (and within the catheter's contact limit)
  float damping_n_s_per_m = 0.0F;       // ≥ 0
  float max_force_n = 4.0F;             // > 0, per plane
  float detection_margin_m = 2.0e-3F;   // ≥ 0: planes found this far before touching
  float grasp_stiffness_n_per_m = 3000.0F;  // > 0: squeeze per metre of jaw closure past touch
  float max_grasp_force_n = 10.0F;          // > 0, per jaw
  float friction_coefficient = 0.6F;        // ≥ 0: slip when pull > μ × total squeeze
  std::uint32_t regrasp_delay_cycles = 50;  // after a slip or an opening
  // Cycles after a grasp starts before slipping is judged: the jaws have only just touched
  // (the squeeze is near zero) and the catheter is still moving from being pushed by them.
  std::uint32_t grasp_settle_cycles = 20;
};

enum class ToolSegment : std::uint8_t { shaft = 0, jaw0 = 1, jaw1 = 2 };

// A force on the instrument (N, trainer frame) at a point `along_m` on `segment`: from the
// shaft start towards the hinge for the shaft, from the hinge towards the tip for a jaw
// (kinematics::InstrumentPoint's convention).
struct ToolForce {
  ToolSegment segment = ToolSegment::shaft;
  float along_m = 0.0F;
  Vec3 force_n = Vec3::Zero();
};

class ForcepsCatheterContact {
 public:
  static constexpr std::size_t kMaxPlanes = 24;      // planes one tool adds per cycle
  static constexpr std::size_t kMaxToolForces = kMaxPlanes + 4;

  // Setup path: checks every setting (the message names it and the expected range).
  static core::Expected<ForcepsCatheterContact> create(const ForcepsContactSettings& settings);

  // ---- RT path: noexcept, no heap ----

  // Before the catheter's step: updates the grasp (holds, releases on `catheter`) and writes
  // this tool's contact planes to planes[0 .. count). Planes beyond the span's size or
  // kMaxPlanes are dropped (the nearest kept first is not guaranteed) and capacity_exceeded
  // returned; a non-finite shape gives numeric_error, nothing added and the grasp released.
  core::Status prepare(const ForcepsShape& shape, Catheter& catheter, std::span<ContactPlane> planes,
                       std::size_t& count) noexcept;

  // After the step: the forces on the tool from this tool's planes (their mean forces from
  // the catheter, in the order prepare() wrote them) and from the grasp; a slip releases the
  // held particles here. plane_forces_n must hold plane_count() forces (invalid_argument).
  core::Status collect(Catheter& catheter, std::span<const Vec3> plane_forces_n) noexcept;

  // Drops the grasp (releases the held particles): e-stop, a fault, the model's removal.
  void release(Catheter& catheter) noexcept;

  std::span<const ToolForce> tool_forces() const noexcept { return {forces_.data(), force_count_}; }
  bool grasping() const noexcept { return grasping_; }
  std::uint32_t grasped_segment() const noexcept { return grasped_segment_; }
  float squeeze_force_n() const noexcept { return squeeze_n_[0] + squeeze_n_[1]; }  // both jaws
  std::uint64_t grasp_count() const noexcept { return grasp_count_; }
  std::uint64_t slip_count() const noexcept { return slip_count_; }
  std::size_t plane_count() const noexcept { return plane_count_; }
  const ForcepsContactSettings& settings() const noexcept { return settings_; }

 private:
  struct PlaneOwner {
    ToolSegment segment;
    float along_m;
  };
  ForcepsCatheterContact() = default;
  // Squeeze of each jaw on the grasped point (N, ≥ 0) for the current shape, where on each
  // jaw it acts and its direction; jaw_reach_m = catheter radius + jaw radius.
  void update_squeeze(const ForcepsShape& shape, const Vec3& grasped_point_m, float jaw_reach_m) noexcept;
  void drop_grasp(Catheter& catheter) noexcept;

  ForcepsContactSettings settings_{};
  std::array<PlaneOwner, kMaxPlanes> owners_{};
  std::size_t plane_count_ = 0;
  std::array<ToolForce, kMaxToolForces> forces_{};
  std::size_t force_count_ = 0;

  bool grasping_ = false;
  std::uint32_t grasped_segment_ = 0;  // particles grasped_segment_ and grasped_segment_ + 1
  float grasped_weight_ = 0.0F;        // where on that segment the jaws hold it
  std::array<Vec3, 2> local_m_{Vec3::Zero(), Vec3::Zero()};  // held particles in the jaw frame
  std::array<float, 2> squeeze_n_{0.0F, 0.0F};
  std::array<float, 2> squeeze_along_m_{0.0F, 0.0F};  // where on each jaw
  std::array<Vec3, 2> squeeze_direction_{Vec3::Zero(), Vec3::Zero()};  // on each jaw, unit
  std::uint32_t regrasp_wait_ = 0;
  std::uint32_t grasp_age_cycles_ = 0;
  float previous_grip_rad_ = std::numeric_limits<float>::max();  // a grasp needs closing jaws
  std::uint64_t grasp_count_ = 0;
  std::uint64_t slip_count_ = 0;
};

}  // namespace trainer::model
