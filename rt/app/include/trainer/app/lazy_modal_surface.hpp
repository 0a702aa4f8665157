// A modal model's contact surface reconstructed lazily at haptic rate (issue 19;
// docs/collision.md "Lazy reconstruction"): only the vertices the collision queries touch are
// computed, each once per model step, and the broad phase (the surface's TriangleBvh) is left
// unrefitted while a bound on every vertex's motion since its last refit, computed from the
// modal state alone, stays within the refit slack.
//
// Why it is exact: the hierarchy's boxes are the triangles' AABBs at the positions of its last
// refit grown by the slack s (TriangleBvh::refit). Vertex i's displacement is
//   u_i = Φ_i q + Σ_l R_il F_l   (R_il = 0 off the surface),
// so since that refit it moved at most
//   min(max_i ‖Φ_i‖_F ‖Δq‖₂, Σ_j max_i ‖φ_ij‖ |Δq_j|) + Σ_l max_k ‖R_kl‖_F ‖ΔF_l‖₂
// (+ both reconstructions' float rounding, bounded) from the state of the last full refresh,
// and while that stays below s minus that refresh's distance from the hierarchy's reference
// (TriangleBvh::last_deviation_m), TriangleBvh::refit would itself skip the work: the
// hierarchy and every query's candidate list are the ones of the full path. Each candidate triangle's
// vertices are computed by the same kernel (reconstruct_node) the full path runs for every
// node, so the positions the narrow phases read are bit-identical to a full reconstruction.
//
// Use: begin() after every model step (it snapshots q and the static-correction loads; the
// vertices are computed from the snapshot, so nothing later in the cycle can make them
// disagree), then hand broad_phase() to the narrow phases: query() and query_segment() make the
// vertices of every triangle they return current. A reader of a triangle it did not get from a
// query this step (a tip contact's held triangle) calls ensure_triangle() first.
//
// RT path: noexcept, no heap (every array from the arena at create()). A non-finite state is
// never taken lazily: its bound is not finite, the full path runs and TriangleBvh::refit
// refuses it as before.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/broad_phase.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace trainer::app {

struct ContactSurface;

class LazyModalSurface final : public model::TriangleBroadPhase {
 public:
  // Setup: the model's data (the image's views, must outlive this) and the surface's vertex
  // count; precomputes the per-node mode-shape norms and, with static correction, the
  // per-loaded-node column maxima of the residual compliance's block norms.
  static core::Expected<LazyModalSurface> create(const model::ModalModelData& data,
                                                 const model::ModalModel& modal,
                                                 core::Arena& arena);

  // After a step (or when the surface is first needed): snapshots the model's state, then either
  // stays lazy (returns true, surface ready: the hierarchy is conservative for the new
  // positions, nothing is reconstructed yet) or reconstructs every vertex into surface.deformed
  // (returns false: call finish_full()). Binds `surface` for the queries of this step.
  bool begin(ContactSurface& surface, const model::ModalModel& modal) noexcept;
  // After a full begin(): refits surface.grid as the full path always did (the work only when
  // a coordinate moved beyond the slack) and takes this state as the bound's reference, with
  // the slack left (TriangleBvh::last_deviation_m).
  // Returns surface_ready (false on a refusal, e.g. a non-finite surface).
  bool finish_full(ContactSurface& surface) noexcept;

  // The vertices of `triangle` computed for this step (each vertex once).
  void ensure_triangle(std::uint32_t triangle) noexcept;

  core::Status query(const model::Aabb& box, std::span<std::uint32_t> out_ids,
                     std::size_t& out_count) noexcept override;
  core::Status query_segment(const model::Vec3& p0, const model::Vec3& p1, float margin_m,
                             std::span<std::uint32_t> out_ids,
                             std::size_t& out_count) noexcept override;

  // Since create(): steps taken lazily, and full reconstructions.
  std::uint64_t lazy_steps() const noexcept { return lazy_steps_; }
  std::uint64_t full_steps() const noexcept { return full_steps_; }
  std::uint64_t vertices_computed() const noexcept { return vertices_computed_; }
  // The last begin()'s motion bound (m) and the budget it was compared with (m).
  double last_bound_m() const noexcept { return last_bound_m_; }
  double last_budget_m() const noexcept { return last_budget_m_; }

  // Vertex `node` from the snapshot (rest + Φ_node q + static correction) into out[0..2]: the
  // kernel both paths use. Public for the tests.
  void reconstruct_node(std::uint32_t node, float* out) const noexcept;

 private:
  struct Load {
    std::uint32_t node;
    std::int32_t surface_index;
    float force_n[3];
  };

  LazyModalSurface() = default;
  void ensure_vertex(std::uint32_t node) noexcept;
  void ensure_candidates(std::span<const std::uint32_t> ids) noexcept;
  double motion_bound() const noexcept;
  double rounding_margin() const noexcept;

  ContactSurface* surface_ = nullptr;  // bound by begin() for this step
  std::span<const float> rest_;
  std::span<const float> mode_shapes_;  // 3n × stored, row-major
  std::span<const float> residual_;     // 3s × 3s, row-major (empty without static correction)
  std::span<const std::int32_t> surface_index_;  // per node, −1 off the surface
  std::uint32_t node_count_ = 0;
  std::uint32_t stored_modes_ = 0;
  std::uint32_t active_modes_ = 0;
  std::uint32_t surface_count_ = 0;
  bool static_correction_ = false;
  bool lazy_allowed_ = true;  // false: static correction over fewer modes than stored

  double max_shape_norm_ = 0.0;           // max_i ‖Φ_i‖_F over the active columns
  std::span<double> mode_column_max_;    // per active mode j: max_i ‖φ_ij‖ (3 rows)
  double max_shape_entry_ = 0.0;          // max |Φ| (rounding margin)
  double max_rest_abs_ = 0.0;             // max |rest coordinate| (rounding margin)
  double max_residual_entry_ = 0.0;       // max |R| (rounding margin)
  std::span<double> residual_column_max_;  // per surface node l: max_k ‖R_kl‖_F

  // The snapshot of this step, and the state at the hierarchy's last refit.
  std::span<float> modes_;
  std::span<float> reference_modes_;
  std::span<Load> loads_;
  std::span<Load> reference_loads_;
  std::size_t load_count_ = 0;
  std::size_t reference_load_count_ = 0;
  bool reference_valid_ = false;
  double used_slack_m_ = 0.0;  // the reference positions' distance from the hierarchy's
  // This step's bound on every vertex's distance (per coordinate) from the hierarchy's
  // reference positions, for TriangleBvh::query_segment_within; < 0 unknown (the slack).
  float within_m_ = -1.0F;
  bool full_failed_ = false;

  std::span<float> full_residual_;  // the full path's Σ_l R_kl F_l over the surface, 3s
  bool full_residual_valid_ = false;
  std::span<std::uint64_t> stamp_;  // per vertex: the step it was computed for
  std::uint64_t step_ = 0;

  std::uint64_t lazy_steps_ = 0;
  std::uint64_t full_steps_ = 0;
  std::uint64_t vertices_computed_ = 0;
  double last_bound_m_ = 0.0;
  double last_budget_m_ = 0.0;
};

}  // namespace trainer::app
