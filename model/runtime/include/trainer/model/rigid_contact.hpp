// Rigid virtual objects rendered by a penalty spring-damper at a single tool point: the
// minimal haptic scene that exercises the whole chain before the soft-tissue models.
//
// Force on the tool: F = max(0, k·depth − b·v_n) n, where depth is the penetration along the
// outward normal n and v_n = v·n. The max() keeps the damper from pulling the tool back into
// the object when it withdraws quickly (a sticky wall is a classic active-rendering artefact).
// Runtime code: float, noexcept, no heap.
#pragma once

#include <Eigen/Core>

namespace trainer::model {

using Vec3 = Eigen::Vector3f;

struct PointContact {
  bool in_contact = false;
  float depth_m = 0.0F;          // penetration, >= 0
  Vec3 normal = Vec3::Zero();    // outward unit normal at the contact
  Vec3 force_n = Vec3::Zero();   // force on the tool
};

struct PenaltyMaterial {
  float stiffness_n_per_m = 0.0F;
  float damping_n_s_per_m = 0.0F;
};

// Half-space behind a plane. `normal` points to the free side (where the tool comes from).
class RigidPlane {
 public:
  RigidPlane() = default;
  RigidPlane(const Vec3& point_m, const Vec3& normal, PenaltyMaterial material) noexcept;
  PointContact contact(const Vec3& point_m, const Vec3& velocity_m_per_s) const noexcept;

 private:
  Vec3 point_m_ = Vec3::Zero();
  Vec3 normal_ = Vec3::UnitZ();
  PenaltyMaterial material_{};
};

// Solid ball; the tool is pushed out radially.
class RigidSphere {
 public:
  RigidSphere() = default;
  RigidSphere(const Vec3& center_m, float radius_m, PenaltyMaterial material) noexcept;
  PointContact contact(const Vec3& point_m, const Vec3& velocity_m_per_s) const noexcept;

 private:
  Vec3 center_m_ = Vec3::Zero();
  float radius_m_ = 0.0F;
  PenaltyMaterial material_{};
};

// Spring-damper force for a penetration `depth_m` along `normal` (shared by the shapes).
PointContact penalty_response(float depth_m, const Vec3& normal, const Vec3& velocity_m_per_s,
                              const PenaltyMaterial& material) noexcept;

}  // namespace trainer::model
