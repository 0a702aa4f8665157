#include "trainer/app/contact_surface.hpp"

#include <algorithm>
#include <limits>

#include "trainer/app/lazy_modal_surface.hpp"

namespace trainer::app {

using Vec3 = Eigen::Vector3f;

bool ContactSurface::near(const Vec3& world_m) const noexcept {
  const Vec3 local = transform.to_model(world_m);
  return (local.array() >= near_box.min_m.array()).all() &&
         (local.array() <= near_box.max_m.array()).all();
}

model::TriangleBroadPhase& ContactSurface::broad_phase() noexcept {
  if (lazy != nullptr) return *lazy;
  return *grid;
}

bool ContactSurface::refit_grid() noexcept {
  // A non-finite surface is refused (and the surface is not ready) by refit().
  surface_ready = grid->refit(deformed, grid_slack_m).is_ok();
  return surface_ready;
}

std::size_t ContactSurface::tip_targets(std::size_t instrument, const InstrumentFrame& frame,
                                        std::span<model::ImposedDisplacement> out,
                                        std::uint64_t& errors) noexcept {
  model::DisplacementContact& contact = *contacts[instrument];
  // A held contact reads its triangle without a query: make its vertices this step's.
  if (lazy != nullptr && contact.in_contact()) lazy->ensure_triangle(contact.triangle());
  const model::TriangleMeshView mesh = view();
  const Vec3 tip = transform.to_model(frame.pose.tip_m);
  const Vec3 previous = frame.has_previous_tip ? transform.to_model(frame.previous_tip_m) : tip;
  if (!contact.update(mesh, broad_phase(), previous, tip).is_ok()) ++errors;
  return contact.targets(mesh, rest_positions, tip, out);
}

bool ContactSurface::observe_tip_forces(std::span<const Vec3> on_tissue_n) noexcept {
  const model::TriangleMeshView mesh = view();
  bool released = false;
  for (std::size_t i = 0; i < on_tissue_n.size(); ++i) {
    if (!contacts[i] || !contacts[i]->in_contact()) continue;
    contacts[i]->observe_force(mesh, on_tissue_n[i]);
    released = released || !contacts[i]->in_contact();
  }
  return released;
}

Vec3 ContactSurface::apply_tip_reactions(std::span<const Vec3> on_tissue_n,
                                         std::span<InstrumentFrame> instruments,
                                         bool& any) const noexcept {
  Vec3 total = Vec3::Zero();
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    if (!contacts[i] || !contacts[i]->in_contact()) continue;
    instruments[i].model_force_n -= transform.vector_to_world(on_tissue_n[i]);
    instruments[i].model_contact = true;
    total += on_tissue_n[i];
    any = true;
  }
  return total;
}

void ContactSurface::release_all() noexcept {
  for (auto& contact : contacts) {
    if (contact) contact->release();
  }
}

namespace {

// The broad phase of a surface (a hierarchy over the rest mesh), its slack, and the rest
// surface's box grown by kSurfaceMarginM into `near_box`.
core::Expected<model::TriangleBvh> make_surface_grid(ContactSurface& surface, core::Arena& arena) {
  const std::span<const float> rest = surface.rest_positions;
  const std::span<const std::uint32_t> triangles = surface.triangles;
  const auto vertex = [&](std::uint32_t node) {
    const std::size_t base = 3 * static_cast<std::size_t>(node);
    return Vec3(rest[base], rest[base + 1], rest[base + 2]);
  };
  const std::size_t vertex_count = rest.size() / 3;
  const std::size_t triangle_count = triangles.size() / 3;
  model::Aabb& box = surface.near_box;
  box.min_m = Vec3::Constant(std::numeric_limits<float>::max());
  box.max_m = Vec3::Constant(-std::numeric_limits<float>::max());
  for (std::size_t node = 0; node < vertex_count; ++node) {
    box.min_m = box.min_m.cwiseMin(vertex(static_cast<std::uint32_t>(node)));
    box.max_m = box.max_m.cwiseMax(vertex(static_cast<std::uint32_t>(node)));
  }
  box.min_m.array() -= kSurfaceMarginM;
  box.max_m.array() += kSurfaceMarginM;
  float longest_edge = 0.0F;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    for (std::size_t e = 0; e < 3; ++e) {
      const Vec3 a = vertex(triangles[3 * t + e]);
      const Vec3 b = vertex(triangles[3 * t + (e + 1) % 3]);
      longest_edge = std::max(longest_edge, (a - b).norm());
    }
  }
  surface.grid_slack_m = kGridSlackEdges * longest_edge;
  auto bvh = model::TriangleBvh::create(rest, triangles, arena);
  if (!bvh) return core::make_error("contact surface: " + bvh.error().message);
  return bvh;
}

}  // namespace

core::Expected<ContactSurface> make_contact_surface(const config::SceneModelConfig& entry,
                                                    std::span<const float> rest_positions,
                                                    std::span<const std::uint32_t> triangles,
                                                    bool with_grid, core::Arena& arena) {
  ContactSurface surface;
  surface.transform = RigidTransform::from_placement(entry.position_m, entry.rotation_deg);
  for (const std::size_t instrument : entry.touched_by) {
    surface.touched_by_mask |= 1U << static_cast<unsigned>(instrument);
  }
  surface.rest_positions = rest_positions;
  surface.triangles = triangles;
  auto deformed = arena.allocate_array<float>(rest_positions.size(), "deformed surface");
  if (!deformed) return std::move(deformed).error();
  surface.deformed = deformed.value();
  std::copy(rest_positions.begin(), rest_positions.end(), surface.deformed.begin());
  if (surface.touched_by_mask == 0 && !with_grid) return surface;  // nothing collides: no grid
  auto grid = make_surface_grid(surface, arena);
  if (!grid) return std::move(grid).error();
  surface.grid.emplace(std::move(grid).value());
  return surface;
}

core::Expected<model::DisplacementContact> make_tip_contact(
    const ContactSurface& surface, std::span<const std::uint32_t> held_nodes, core::Arena& arena) {
  model::DisplacementContactSettings settings;
  settings.tip_radius_m = kForcepsTipRadiusM;
  settings.max_candidates = static_cast<std::uint32_t>(surface.triangles.size() / 3);
  return model::DisplacementContact::create(settings, held_nodes, arena);
}

}  // namespace trainer::app
