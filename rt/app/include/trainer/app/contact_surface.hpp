// The deformable surface of one soft-tissue model (a modal duct or a Cotin tensor model) as the
// tools see it: its placement in the trainer frame, the deformed positions (model frame), the
// broad phase over them (a TriangleBvh refitted, docs/collision.md) and a displacement-driven tip contact per instrument that may touch it.
// The model stages (modal_stage, tensor_stage) own the surface of their models; the catheter
// stage reads the modal models' surfaces.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

#include <Eigen/Core>

#include "trainer/app/cycle_frame.hpp"
#include "trainer/app/rigid_transform.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/triangle_bvh.hpp"
#include "trainer/model/displacement_contact.hpp"

namespace trainer::app {

// The forceps tip as seen by soft-tissue contact: a sphere of this radius at the closed jaws'
// tip (jaws of a 5 mm instrument taper to about 2 mm).
inline constexpr float kForcepsTipRadiusM = 0.001F;
// The instrument's capsules against walls and catheters (a 5 mm instrument, jaws tapering to
// 2 mm).
inline constexpr float kShaftRadiusM = 0.0025F;
inline constexpr float kJawRadiusM = 0.001F;
// How far outside a model's rest mesh a tool tip must be for the model's surface to be left
// stale: more than the model deforms plus one cycle of tool travel.
inline constexpr float kSurfaceMarginM = 0.02F;
// Slack of the surfaces' broad phases, in units of the rest mesh's longest edge: a refit stores
// every triangle with its box grown by it, and the next refit is skipped while no coordinate
// has moved farther (TriangleBvh::refit). 0.75 edge (1.5 mm on the duct), up from the bucket
// grid's 0.375 (issue 19, round 4): at 1 kHz a held tool moves the duct's surface by a good part
// of 0.75 mm per step, so the lazy surface checked or recomputed most vertices and refitted; with
// 1.5 mm the cbd 1 kHz per-cycle-minimum p99.9 fell 23.7–24.2 → 19.2–20.4 µs for 14.6–14.7 →
// 15.3–16.1 µs at 10 kHz (larger boxes, more candidates), contacts bit-identical
// (docs/performance.md "After round 4").
inline constexpr float kGridSlackEdges = 0.75F;

class LazyModalSurface;

struct ContactSurface {
  RigidTransform transform;                  // model frame → trainer frame ([[model]] placement)
  std::uint32_t touched_by_mask = 0;         // bit per instrument that may touch the model
  std::span<const float> rest_positions;     // 3n, model frame (the image's)
  std::span<const std::uint32_t> triangles;  // 3 per triangle (the image's)
  std::span<float> deformed;                 // 3n, model frame
  std::optional<model::TriangleBvh> grid;    // none when nothing collides with the model
  std::array<std::optional<model::DisplacementContact>, kMaxInstruments> contacts{};
  // The rest mesh's box grown by kSurfaceMarginM: while no tool (or particle) is inside it and
  // no contact holds, the surface is not rebuilt (a tool far away costs nothing).
  model::Aabb near_box{};
  bool surface_ready = false;  // deformed and grid are this cycle's
  float grid_slack_m = 0.0F;   // kGridSlackEdges × the rest mesh's longest edge
  // A modal model's surface is reconstructed lazily (lazy_modal_surface.hpp): `deformed` holds
  // this step's position only for the vertices of triangles the broad phase returned, so the
  // narrow phases query broad_phase(), never `grid` directly. Bound by LazyModalSurface::begin
  // each step; null for tensor models (deformed always whole).
  LazyModalSurface* lazy = nullptr;

  std::size_t vertex_count() const noexcept { return rest_positions.size() / 3; }
  model::TriangleMeshView view() const noexcept { return {deformed, triangles}; }
  // What the narrow phases query: the lazy surface when bound, else the grid (must exist).
  model::TriangleBroadPhase& broad_phase() noexcept;
  // Is the trainer-frame point inside near_box (model frame)?
  bool near(const Eigen::Vector3f& world_m) const noexcept;
  // Makes the grid answer for `deformed`: refitted with a slack of grid_slack_m, and only
  // when some coordinate has moved farther than the slack since the last refit. Sets and
  // returns surface_ready (false on a refusal, e.g. a non-finite surface).
  bool refit_grid() noexcept;
  // Instrument i's tip contact this cycle: update() with the tip's path, then the imposed
  // displacements of its material point into `out`; returns how many (0 when free). A refused
  // update counts in `errors`.
  std::size_t tip_targets(std::size_t instrument, const InstrumentFrame& frame,
                          std::span<model::ImposedDisplacement> out,
                          std::uint64_t& errors) noexcept;
  // After a solve, `on_tissue_n[i]` the force (model frame) tip i's targets put on the tissue:
  // each holding tip checks it (a tip that would pull the tissue lets go). True when one did.
  bool observe_tip_forces(std::span<const Eigen::Vector3f> on_tissue_n) noexcept;
  // The holding tips feel the opposite of on_tissue_n (trainer frame) at the tip; returns the
  // sum on the tissue, `any` set when a tip holds.
  Eigen::Vector3f apply_tip_reactions(std::span<const Eigen::Vector3f> on_tissue_n,
                                      std::span<InstrumentFrame> instruments,
                                      bool& any) const noexcept;
  void release_all() noexcept;
};

// The placement, the deformed copy of the rest surface and — when an instrument may touch the
// model or `with_grid` (a catheter collides with it) — its broad phase (a TriangleBvh over the
// rest mesh, leaves of 4 triangles), near_box from the rest mesh. Contacts are added by the
// caller.
core::Expected<ContactSurface> make_contact_surface(const config::SceneModelConfig& entry,
                                                    std::span<const float> rest_positions,
                                                    std::span<const std::uint32_t> triangles,
                                                    bool with_grid, core::Arena& arena);

// A forceps tip on `surface` that never displaces `held_nodes` (strictly increasing). A grid
// query can never return more than every triangle: sized so, no contact is ever lost to a full
// candidate list (a few kB per contact on these meshes).
core::Expected<model::DisplacementContact> make_tip_contact(
    const ContactSurface& surface, std::span<const std::uint32_t> held_nodes, core::Arena& arena);

}  // namespace trainer::app
