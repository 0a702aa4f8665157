#include "stages/modal_targets.hpp"

#include "stages/cached_queries.hpp"

#include <algorithm>
#include <cmath>

namespace trainer::app {

using Vec3 = Eigen::Vector3f;

void ModalTargets::keep_holding(const ContactSurface& surface) noexcept {
  std::size_t kept = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const bool keep = segment_of[k] < 0 ? surface.contacts[owner[k]]->in_contact()
                                        : segments[static_cast<std::size_t>(segment_of[k])].active;
    if (keep) {
      targets[kept] = targets[k];
      owner[kept] = owner[k];
      segment_of[kept++] = segment_of[k];
    }
  }
  count = kept;
}

void gather_tip_targets(ModalModelState& state, std::span<InstrumentFrame> instruments,
                        ModalTargets& out, std::uint64_t& errors) noexcept {
  ContactSurface& surface = state.surface;
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!surface.contacts[i]) continue;
    InstrumentFrame& instrument = instruments[i];
    std::array<model::ImposedDisplacement, model::DisplacementContact::kMaxTargets> mine{};
    const std::size_t count = surface.tip_targets(i, instrument, mine, errors);
    if (out.count + count > out.targets.size()) {
      surface.contacts[i]->release();
      continue;
    }
    for (std::size_t k = 0; k < count; ++k) {
      out.targets[out.count] = mine[k];
      out.owner[out.count++] = i;
      instrument.model_indentation_m =
          std::max(instrument.model_indentation_m, mine[k].displacement_m.norm());
    }
  }
}

namespace {

// The shaft is tens of centimetres long: only its part inside the surface's box (grown by
// kSegmentClipMarginM) can touch it, and a query box along the whole shaft would cover most of
// the grid. Adds the clipped shaft capsule (if any part is inside) and returns its start's
// distance from the shaft's start (contacts measure along_m from the clipped start).
float add_clipped_shaft(const ContactSurface& surface, const Vec3& shaft_start, const Vec3& hinge,
                        const Vec3& velocity, std::array<model::ToolCapsule, 3>& capsules,
                        std::size_t& capsule_count) noexcept {
  const model::Aabb clip{surface.near_box.min_m.array() + (kSurfaceMarginM - kSegmentClipMarginM),
                         surface.near_box.max_m.array() - (kSurfaceMarginM - kSegmentClipMarginM)};
  const Vec3 axis = hinge - shaft_start;
  float enter = 0.0F;
  float leave = 1.0F;
  for (Eigen::Index k = 0; k < 3; ++k) {
    if (std::fabs(axis[k]) < 1e-12F) {
      if (shaft_start[k] < clip.min_m[k] || shaft_start[k] > clip.max_m[k]) leave = -1.0F;
      continue;
    }
    const float a = (clip.min_m[k] - shaft_start[k]) / axis[k];
    const float b = (clip.max_m[k] - shaft_start[k]) / axis[k];
    enter = std::max(enter, std::min(a, b));
    leave = std::min(leave, std::max(a, b));
  }
  if (enter > leave) return 0.0F;
  capsules[capsule_count++] =
      model::ToolCapsule{model::ToolSegment::shaft,  shaft_start + enter * axis,
                         shaft_start + leave * axis, kShaftRadiusM,
                         enter * velocity,           leave * velocity};
  return enter * axis.norm();
}

// One wall contact found for instrument i as imposed displacements of its triangle's free
// nodes: the wall point goes to where the capsule leaves it just inside its reach, and the
// free nodes share the displacement that puts it there (as for a tip).
void add_segment_target(const ModalModelState& state, std::size_t instrument,
                        const model::SegmentContact& found, float shaft_offset_m,
                        ModalTargets& out) noexcept {
  const Vec3 goal = found.mesh_point_m - (found.depth_m - kSegmentSkinM) * found.normal;
  const std::span<const float> rest_positions = state.surface.rest_positions;
  Vec3 rest = Vec3::Zero();
  for (std::size_t corner = 0; corner < 3; ++corner) {
    const std::size_t base = 3 * static_cast<std::size_t>(found.vertices[corner]);
    rest += found.barycentric[static_cast<Eigen::Index>(corner)] *
            Vec3(rest_positions[base], rest_positions[base + 1], rest_positions[base + 2]);
  }
  const Vec3 imposed = goal - rest;
  if (!imposed.allFinite()) return;
  // Nodes a tip (or an earlier segment) already imposes keep that target; a contact with no
  // node left, or beyond the model's capacity, is left out this cycle.
  std::array<std::uint32_t, 3> free{};
  std::size_t free_count = 0;
  bool shared = false;
  for (const std::uint32_t node : found.vertices) {
    if (std::binary_search(state.fixed_nodes.begin(), state.fixed_nodes.end(), node)) continue;
    for (std::size_t k = 0; k < out.count; ++k) shared = shared || out.targets[k].node == node;
    free[free_count++] = node;
  }
  if (shared || free_count == 0 || out.count + free_count > out.targets.size() ||
      out.segment_count >= out.segments.size()) {
    return;
  }
  const float along_m =
      found.along_m + (found.segment == model::ToolSegment::shaft ? shaft_offset_m : 0.0F);
  out.segments[out.segment_count] = SegmentTarget{
      instrument, found.segment, along_m, found.depth_m, found.normal, Vec3::Zero(), true};
  for (std::size_t k = 0; k < free_count; ++k) {
    out.targets[out.count] = model::ImposedDisplacement{free[k], imposed};
    out.owner[out.count] = instrument;
    out.segment_of[out.count++] = static_cast<std::int32_t>(out.segment_count);
  }
  ++out.segment_count;
}

}  // namespace

void gather_segment_targets(ModalModelState& state, std::span<const InstrumentFrame> instruments,
                            ModalTargets& out, std::uint64_t& errors) noexcept {
  ContactSurface& surface = state.surface;
  const RigidTransform& transform = surface.transform;
  for (std::size_t k = 0; k < out.count; ++k) out.segment_of[k] = -1;
  out.segment_count = 0;
  const model::TriangleMeshView view = surface.view();
  CachedQueries queries(surface);
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!state.segments[i]) continue;
    const kinematics::InstrumentPose& pose = instruments[i].pose;
    const Vec3 velocity = transform.vector_to_model(instruments[i].tip_velocity_m_per_s);
    const Vec3 hinge = transform.to_model(pose.hinge_m);
    std::array<model::ToolCapsule, 3> capsules{
        model::ToolCapsule{model::ToolSegment::jaw0, hinge, transform.to_model(pose.jaw_tips_m[0]),
                           kJawRadiusM, velocity, velocity},
        model::ToolCapsule{model::ToolSegment::jaw1, hinge, transform.to_model(pose.jaw_tips_m[1]),
                           kJawRadiusM, velocity, velocity},
        model::ToolCapsule{}};
    std::size_t capsule_count = 2;
    const float shaft_offset_m = add_clipped_shaft(surface, transform.to_model(pose.shaft_start_m),
                                                   hinge, velocity, capsules, capsule_count);
    model::SegmentSurfaceContact& contact = *state.segments[i];
    if (!contact.update(std::span(capsules.data(), capsule_count), view, {}, queries).is_ok())
      ++errors;
    for (const model::SegmentContact& found : contact.contacts()) {
      add_segment_target(state, i, found, shaft_offset_m, out);
    }
  }
}

}  // namespace trainer::app
