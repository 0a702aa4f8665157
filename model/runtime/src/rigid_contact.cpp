#include "trainer/model/rigid_contact.hpp"

#include <algorithm>

namespace trainer::model {

PointContact penalty_response(float depth_m, const Vec3& normal, const Vec3& velocity_m_per_s,
                              const PenaltyMaterial& material) noexcept {
  PointContact contact;
  if (!(depth_m > 0.0F)) return contact;  // also rejects NaN depth
  contact.in_contact = true;
  contact.depth_m = depth_m;
  contact.normal = normal;
  const float normal_speed = velocity_m_per_s.dot(normal);  // < 0 while pressing in
  const float magnitude = std::max(
      0.0F, material.stiffness_n_per_m * depth_m - material.damping_n_s_per_m * normal_speed);
  contact.force_n = magnitude * normal;
  return contact;
}

RigidPlane::RigidPlane(const Vec3& point_m, const Vec3& normal, PenaltyMaterial material) noexcept
    : point_m_(point_m), normal_(normal.normalized()), material_(material) {}

PointContact RigidPlane::contact(const Vec3& point_m, const Vec3& velocity_m_per_s) const noexcept {
  const float depth = -(point_m - point_m_).dot(normal_);
  return penalty_response(depth, normal_, velocity_m_per_s, material_);
}

RigidSphere::RigidSphere(const Vec3& center_m, float radius_m, PenaltyMaterial material) noexcept
    : center_m_(center_m), radius_m_(radius_m), material_(material) {}

PointContact RigidSphere::contact(const Vec3& point_m,
                                  const Vec3& velocity_m_per_s) const noexcept {
  const Vec3 offset = point_m - center_m_;
  const float distance = offset.norm();
  const float depth = radius_m_ - distance;
  if (!(depth > 0.0F)) return {};
  // At the exact centre the direction is undefined: push along +z rather than produce NaN.
  const Vec3 normal = distance > 1e-9F ? Vec3(offset / distance) : Vec3(Vec3::UnitZ());
  return penalty_response(depth, normal, velocity_m_per_s, material_);
}

}  // namespace trainer::model
