// Forceps–catheter contact and grasping: the rules are in forceps_catheter.hpp.
#include "trainer/model/forceps_catheter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace trainer::model {
namespace {

bool finite_shape(const ForcepsShape& shape) noexcept {
  return shape.shaft_start_m.allFinite() && shape.hinge_m.allFinite() && shape.jaw_tips_m[0].allFinite() &&
         shape.jaw_tips_m[1].allFinite() && shape.direction.allFinite() && shape.opening_direction.allFinite() &&
         std::isfinite(shape.grip_rad) && shape.velocity_m_per_s.allFinite();
}

// The tool's three segments: shaft start → hinge, hinge → jaw tip 0, hinge → jaw tip 1.
struct ToolAxis {
  Vec3 start;
  Vec3 end;
  float radius_m;
};

std::array<ToolAxis, 3> tool_axes(const ForcepsShape& shape, const ForcepsContactSettings& settings) noexcept {
  return {ToolAxis{shape.shaft_start_m, shape.hinge_m, settings.shaft_radius_m},
          ToolAxis{shape.hinge_m, shape.jaw_tips_m[0], settings.jaw_radius_m},
          ToolAxis{shape.hinge_m, shape.jaw_tips_m[1], settings.jaw_radius_m}};
}

// A unit vector from the tool's axis towards the catheter's; when the axes cross, one normal
// to both (the jaws then push the catheter sideways out of the way), else any normal to the tool.
Vec3 contact_normal(const SegmentSegmentClosest& closest, const Vec3& tool_direction,
                    const Vec3& catheter_direction) noexcept {
  constexpr float kMinDistanceM = 1e-7F;
  if (closest.distance_m > kMinDistanceM) return (closest.on_second - closest.on_first) / closest.distance_m;
  Vec3 normal = tool_direction.cross(catheter_direction);
  if (normal.norm() > 1e-6F) return normal.normalized();
  normal = tool_direction.unitOrthogonal();
  return normal;
}

}  // namespace

core::Expected<ForcepsCatheterContact> ForcepsCatheterContact::create(const ForcepsContactSettings& settings) {
  const auto refuse = [](const char* name, float value, const char* expected) {
    return core::make_error(std::string("forceps-catheter contact: ") + name + " = " +
                            std::to_string(value) + ": expected " + expected);
  };
  const auto non_negative = [](float value) { return std::isfinite(value) && value >= 0.0F; };
  const auto positive = [](float value) { return std::isfinite(value) && value > 0.0F; };
  if (!non_negative(settings.shaft_radius_m)) return refuse("shaft_radius_m", settings.shaft_radius_m, ">= 0");
  if (!non_negative(settings.jaw_radius_m)) return refuse("jaw_radius_m", settings.jaw_radius_m, ">= 0");
  if (!positive(settings.stiffness_n_per_m)) return refuse("stiffness_n_per_m", settings.stiffness_n_per_m, "> 0");
  if (!non_negative(settings.damping_n_s_per_m)) {
    return refuse("damping_n_s_per_m", settings.damping_n_s_per_m, ">= 0");
  }
  if (!positive(settings.max_force_n)) return refuse("max_force_n", settings.max_force_n, "> 0");
  if (!non_negative(settings.detection_margin_m)) {
    return refuse("detection_margin_m", settings.detection_margin_m, ">= 0");
  }
  if (!positive(settings.grasp_stiffness_n_per_m)) {
    return refuse("grasp_stiffness_n_per_m", settings.grasp_stiffness_n_per_m, "> 0");
  }
  if (!positive(settings.max_grasp_force_n)) return refuse("max_grasp_force_n", settings.max_grasp_force_n, "> 0");
  if (!non_negative(settings.friction_coefficient)) {
    return refuse("friction_coefficient", settings.friction_coefficient, ">= 0");
  }
  ForcepsCatheterContact contact;
  contact.settings_ = settings;
  return contact;
}

void ForcepsCatheterContact::drop_grasp(Catheter& catheter) noexcept {
  if (grasping_) {
    (void)catheter.release(grasped_segment_);
    (void)catheter.release(grasped_segment_ + 1);
  }
  grasping_ = false;
  squeeze_n_ = {0.0F, 0.0F};
}

void ForcepsCatheterContact::release(Catheter& catheter) noexcept {
  drop_grasp(catheter);
  plane_count_ = 0;
  force_count_ = 0;
}

void ForcepsCatheterContact::update_squeeze(const ForcepsShape& shape, const Vec3& grasped_point_m,
                                            float jaw_reach_m) noexcept {
  for (std::size_t jaw = 0; jaw < 2; ++jaw) {
    const SegmentSegmentClosest closest =
        closest_points_segments(shape.hinge_m, shape.jaw_tips_m[jaw], grasped_point_m, grasped_point_m);
    squeeze_along_m_[jaw] = closest.s * (shape.jaw_tips_m[jaw] - shape.hinge_m).norm();
    // The catheter pushes the jaw away from the grasped point (along ±n if the point is on
    // the jaw's axis).
    const Vec3 away = closest.on_first - grasped_point_m;
    const float length = away.norm();
    squeeze_direction_[jaw] = length > 1e-7F ? Vec3(away / length)
                                             : (jaw == 0 ? shape.opening_direction : Vec3(-shape.opening_direction));
    const float overlap_m = jaw_reach_m - closest.distance_m;  // catheter + jaw radius past touching
    squeeze_n_[jaw] = std::clamp(settings_.grasp_stiffness_n_per_m * overlap_m, 0.0F, settings_.max_grasp_force_n);
  }
}

core::Status ForcepsCatheterContact::prepare(const ForcepsShape& shape, Catheter& catheter,
                                             std::span<ContactPlane> planes, std::size_t& count) noexcept {
  count = 0;
  plane_count_ = 0;
  if (!finite_shape(shape)) {
    drop_grasp(catheter);
    return {core::StatusCode::numeric_error, "forceps-catheter contact: non-finite instrument pose"};
  }
  if (regrasp_wait_ > 0) --regrasp_wait_;
  const Vec3 d = shape.direction;
  const Vec3 n = shape.opening_direction;
  const Vec3 b = d.cross(n);
  const std::span<const Vec3> particles = catheter.positions_m();
  const std::size_t particle_count = particles.size();
  const float catheter_radius = catheter.radius_m();
  const float jaw_reach = catheter_radius + settings_.jaw_radius_m;
  const std::array<ToolAxis, 3> axes = tool_axes(shape, settings_);

  if (grasping_) {
    // The held particles ride in the jaw frame.
    std::array<Vec3, 2> targets{};
    for (std::size_t k = 0; k < 2; ++k) {
      targets[k] = shape.hinge_m + local_m_[k].x() * d + local_m_[k].y() * n + local_m_[k].z() * b;
      (void)catheter.hold(grasped_segment_ + static_cast<std::uint32_t>(k), targets[k]);
    }
    const Vec3 point = (1.0F - grasped_weight_) * targets[0] + grasped_weight_ * targets[1];
    update_squeeze(shape, point, jaw_reach);
    if (squeeze_n_[0] <= 0.0F || squeeze_n_[1] <= 0.0F) {  // a jaw let go: the jaws are opening
      drop_grasp(catheter);
      regrasp_wait_ = settings_.regrasp_delay_cycles;  // no re-grasp flicker while they open
    }
  } else if (regrasp_wait_ == 0 && particle_count >= 2 && shape.grip_rad < previous_grip_rad_) {
    // Both jaws on the catheter (same or neighbouring segments): grasp what jaw 0 touches.
    std::array<float, 2> best_distance{std::numeric_limits<float>::max(), std::numeric_limits<float>::max()};
    std::array<std::uint32_t, 2> best_segment{0, 0};
    std::array<float, 2> best_t{0.0F, 0.0F};
    for (std::size_t jaw = 0; jaw < 2; ++jaw) {
      const ToolAxis& axis = axes[jaw + 1];
      for (std::size_t i = 0; i + 1 < particle_count; ++i) {
        const SegmentSegmentClosest closest =
            closest_points_segments(axis.start, axis.end, particles[i], particles[i + 1]);
        if (closest.distance_m < best_distance[jaw]) {
          best_distance[jaw] = closest.distance_m;
          best_segment[jaw] = static_cast<std::uint32_t>(i);
          best_t[jaw] = closest.t;
        }
      }
    }
    const std::uint32_t gap = best_segment[0] > best_segment[1] ? best_segment[0] - best_segment[1]
                                                                : best_segment[1] - best_segment[0];
    if (best_distance[0] < jaw_reach && best_distance[1] < jaw_reach && gap <= 1) {
      grasping_ = true;
      grasp_age_cycles_ = 0;
      ++grasp_count_;
      grasped_segment_ = best_segment[0];
      grasped_weight_ = best_t[0];
      for (std::size_t k = 0; k < 2; ++k) {
        const Vec3 offset = particles[grasped_segment_ + k] - shape.hinge_m;
        local_m_[k] = Vec3(offset.dot(d), offset.dot(n), offset.dot(b));
        (void)catheter.hold(grasped_segment_ + static_cast<std::uint32_t>(k), particles[grasped_segment_ + k]);
      }
      const Vec3 point = (1.0F - grasped_weight_) * particles[grasped_segment_] +
                         grasped_weight_ * particles[grasped_segment_ + 1];
      update_squeeze(shape, point, jaw_reach);
    }
  }

  previous_grip_rad_ = shape.grip_rad;
  core::Status status = core::Status::ok();
  const std::size_t capacity = std::min(planes.size(), kMaxPlanes);
  for (std::size_t s = 0; s < axes.size(); ++s) {
    const ToolAxis& axis = axes[s];
    const Vec3 tool_vector = axis.end - axis.start;
    const float tool_length = tool_vector.norm();
    const float reach = catheter_radius + axis.radius_m;
    for (std::size_t i = 0; i + 1 < particle_count; ++i) {
      // The grasped segment and its neighbours are held by the jaws, not pushed by them.
      if (grasping_ && i + 1 >= grasped_segment_ && i <= grasped_segment_ + 1) continue;
      const SegmentSegmentClosest closest =
          closest_points_segments(axis.start, axis.end, particles[i], particles[i + 1]);
      if (closest.distance_m >= reach + settings_.detection_margin_m) continue;
      if (closest.t >= 1.0F - 1e-6F && i + 2 < particle_count) continue;  // the next segment's t = 0
      if (count >= capacity) {
        status = {core::StatusCode::capacity_exceeded, "forceps-catheter contact: more planes than capacity"};
        continue;
      }
      ContactPlane& plane = planes[count];
      plane.particle_a = static_cast<std::uint32_t>(i);
      plane.particle_b = static_cast<std::uint32_t>(i + 1);
      plane.weight_b = std::clamp(closest.t, 0.0F, 1.0F);
      plane.point_m = closest.on_first;
      plane.normal = contact_normal(closest, tool_vector, particles[i + 1] - particles[i]);
      plane.surface_velocity_m_per_s = shape.velocity_m_per_s;
      plane.reach_m = reach;
      plane.stiffness_n_per_m = settings_.stiffness_n_per_m;
      plane.damping_n_s_per_m = settings_.damping_n_s_per_m;
      plane.max_force_n = settings_.max_force_n;
      owners_[count] = PlaneOwner{static_cast<ToolSegment>(s), closest.s * tool_length};
      ++count;
    }
  }
  plane_count_ = count;
  return status;
}

core::Status ForcepsCatheterContact::collect(Catheter& catheter,
                                             std::span<const Vec3> plane_forces_n) noexcept {
  force_count_ = 0;
  if (plane_forces_n.size() != plane_count_) {
    return {core::StatusCode::invalid_argument, "forceps-catheter contact: one force per plane expected"};
  }
  for (std::size_t k = 0; k < plane_count_; ++k) {
    if (plane_forces_n[k].isZero(0.0F)) continue;
    forces_[force_count_++] = ToolForce{owners_[k].segment, owners_[k].along_m, -plane_forces_n[k]};
  }
  if (!grasping_) return core::Status::ok();

  // The catheter's pull on the held particles, shared by the jaws, and each jaw's squeeze
  // pushing it away from the grasped point.
  const Vec3 pull = catheter.hold_forces_n()[grasped_segment_] + catheter.hold_forces_n()[grasped_segment_ + 1];
  const float total_squeeze = squeeze_n_[0] + squeeze_n_[1];
  const bool settled = grasp_age_cycles_ >= settings_.grasp_settle_cycles;
  if (grasp_age_cycles_ < settings_.grasp_settle_cycles) ++grasp_age_cycles_;
  if (!pull.allFinite() || (settled && pull.norm() > settings_.friction_coefficient * total_squeeze)) {
    drop_grasp(catheter);  // slips out of the jaws
    ++slip_count_;
    regrasp_wait_ = settings_.regrasp_delay_cycles;
    return core::Status::ok();
  }
  for (std::size_t jaw = 0; jaw < 2; ++jaw) {
    const auto segment = jaw == 0 ? ToolSegment::jaw0 : ToolSegment::jaw1;
    forces_[force_count_++] =
        ToolForce{segment, squeeze_along_m_[jaw], squeeze_n_[jaw] * squeeze_direction_[jaw] + 0.5F * pull};
  }
  return core::Status::ok();
}

}  // namespace trainer::model
