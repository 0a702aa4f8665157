// A modal model's contact surface reconstructed lazily at haptic rate (issue 19;
// docs/collision.md "Lazy reconstruction"): only the vertices the collision queries touch are
// computed, each once per model step, and the broad phase (the surface's TriangleBvh) is left
// unrefitted while TriangleBvh::refit would itself skip the work; the hierarchy, and so every
// query's candidate list, is always the one the full path (every vertex, then refit) has.
//
// Why it is exact: the full path refits the hierarchy iff some vertex coordinate is farther
// than the slack s from the hierarchy's reference positions. The nodes are split at setup into
// spatial clusters of ≤ kClusterNodes; for each cluster c a reference state (q_c, F_c: the
// modal coordinates and static-correction loads at which its vertices were last computed
// exactly) and d_c, those vertices' largest coordinate distance from the hierarchy's
// reference. Vertex i's displacement is u_i = Φ_i q + Σ_l R_il F_l (R_il = 0 off the surface),
// so since q_c, F_c each coordinate of a vertex of c moved at most
//   min(max_{row} ‖Φ_row‖ ‖Δq‖₂, Σ_j max_{row} |Φ_row,j| |Δq_j|) + Σ_l max_{row} ‖R_row,l‖ ‖ΔF_l‖
// (rows: the cluster's 3 rows per node; precomputed per cluster) plus both computations' float
// rounding (bounded). A cluster whose d_c + bound is below 0.999 s cannot trigger the refit. Per
// step: every cluster within → lazy, nothing computed; otherwise the vertices of the clusters
// beyond are computed exactly and compared with the hierarchy's reference as refit() compares
// them: none beyond s → still no refit (those clusters take this state as their reference);
// one beyond s → the full path (every vertex, the refit). Each vertex is computed by the same
// kernel the full path runs (ModalModel::shape_rows, the one reconstruct() runs, then the
// static correction summed as reconstruct() sums it), so the positions the narrow phases read
// are bit-identical to a full reconstruction.
//
// Round 4 (lazy_modal_surface_all.cpp): a cluster beyond its bound gets a tighter one about its
// mean rows before it is checked; with more than a fifth of the nodes to check, every vertex is
// computed in one fused pass and every cluster compared exactly, and without a refit this state
// becomes every cluster's reference (as after a full step whose refit skipped).
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
  // For a caller that queries the hierarchy itself (the tools' cached segment queries,
  // stages/modal_targets.cpp): this step's bound on every vertex's distance from the
  // hierarchy's reference, per coordinate (< 0 unknown: the slack), as query_segment() states
  // it, and the vertices of the triangles it got made this step's, as query_segment() does.
  float stated_deviation_m() const noexcept { return within_m_; }
  void make_current(std::span<const std::uint32_t> ids) noexcept { ensure_candidates(ids); }

  core::Status query(const model::Aabb& box, std::span<std::uint32_t> out_ids,
                     std::size_t& out_count) noexcept override;
  core::Status query_segment(const model::Vec3& p0, const model::Vec3& p1, float margin_m,
                             std::span<std::uint32_t> out_ids,
                             std::size_t& out_count) noexcept override;

  // Nodes per cluster (the bound's unit; a spatial median split of the rest positions).
  static constexpr std::uint32_t kClusterNodes = 8;
  // Reference states kept at once: the last full refresh's, and a ring of the states clusters
  // were checked at (the oldest's clusters move to the newest). Measured on the cbd duct: 2
  // (a ring of one) costs less per step than 4 and checks about as many clusters.
  static constexpr std::uint32_t kEpochs = 2;
  // After a step that computed every vertex, the next one whose common bound is beyond the
  // budget computes every vertex again without the per-cluster pass.
  static constexpr bool kAllAfterAll = true;

  // Since create(): steps taken lazily (some clusters' vertices maybe checked, no refit), of
  // them the ones that checked clusters, full reconstructions, vertices computed lazily.
  std::uint64_t lazy_steps() const noexcept { return lazy_steps_; }
  std::uint64_t checked_steps() const noexcept { return checked_steps_; }
  std::uint64_t full_steps() const noexcept { return full_steps_; }
  // Of the checked steps, those that computed every vertex and took this state as every
  // cluster's reference (each cluster's exact deviation; no refit): the 1 kHz held contact.
  std::uint64_t rebased_steps() const noexcept { return rebased_steps_; }
  // Clusters beyond the per-cluster bound that the refined bound (mean rows) kept unchecked.
  std::uint64_t refined_clusters() const noexcept { return refined_clusters_; }
  std::uint64_t vertices_computed() const noexcept { return vertices_computed_; }
  std::size_t cluster_count() const noexcept { return cluster_start_.size() - 1; }
  // The clusters' nodes: cluster c is cluster_nodes()[cluster_start(c) .. cluster_start(c+1)).
  std::span<const std::uint32_t> cluster_nodes() const noexcept { return cluster_nodes_; }
  std::uint32_t cluster_start(std::size_t cluster) const noexcept { return cluster_start_[cluster]; }
  // Before begin(), when the surface is needed this cycle: asks for the next kWarmShapeLines
  // cache lines of the mode-shape matrix and kWarmGridLines of the hierarchy's refit arrays
  // (TriangleBvh::keep_warm), round robin (prefetches into L2: no value changes). A full step
  // reads all of them at once, rarely (cbd at 1 kHz: 5 of 11,000 steps), and found them evicted
  // from L2 between full steps (Φq of the duct 4-7 µs instead of 3, the refit's boxes 3.5-6 instead
  // of 2); the sweep keeps them there for ~10-20 ns per near cycle (16 and 8 lines: the same
  // effect at twice the cost). docs/collision.md "Full steps".
  void keep_warm(ContactSurface& surface) noexcept;
  static constexpr std::size_t kWarmShapeLines = 8;
  static constexpr std::size_t kWarmGridLines = 4;

  // The last begin()'s bound for `cluster` (m: its reference's distance from the hierarchy's
  // reference + the motion bound + rounding), and the budget (0.999 s). NaN before a full step.
  double last_cluster_bound_m(std::size_t cluster) const noexcept { return bound_[cluster]; }
  double budget_m() const noexcept { return budget_m_; }

  // Vertex `node` from the snapshot (rest + Φ_node q + static correction) into out[0..2] by
  // the kernel both paths use. For the tests.
  void reconstruct_node(std::uint32_t node, float* out) noexcept;

 private:
  struct Load {
    std::uint32_t node;
    std::int32_t surface_index;
    float force_n[3];
  };
  // A state some clusters take as their reference: q, the loads, and (per step, scratch) the
  // loads' changes since it as (surface index, ‖ΔF‖) pairs.
  struct Epoch {
    std::span<float> modes;
    std::span<Load> loads;
    std::size_t load_count = 0;
    double magnitude = 0.0;  // the rounding margin's magnitude of this state
    double max_used_m = 0.0;  // the largest d_c of its clusters
    double bound_m = 0.0;     // this step: epoch_bound()
    std::span<double> abs_dq;  // per step (scratch): |q − this q| per mode, and its 2-norm
    std::span<float> abs_dq_f;  // idem in float (rounded up)
    std::span<float> dq_f;      // q − this q per mode, signed, in float (rounded to nearest)
    double dq_norm = 0.0;
    std::uint32_t users = 0;  // clusters referring to it
    std::span<std::int32_t> delta_index;
    std::span<double> delta_norm;
    std::span<float> delta_norm_f;  // idem in float (rounded up)
    std::size_t delta_count = 0;
    std::uint64_t delta_step = 0;  // the step the deltas are for
  };

  LazyModalSurface() = default;
  // A non-negative double as a float at least as large, and at least 2^-100 (no product of the
  // bound's float passes is then subnormal: subnormal arithmetic is ~100 times slower). No libm
  // call: (1 + 2^-22) more than covers the two roundings.
  static float float_up(double value) noexcept {
    const float rounded = static_cast<float>(value) * (1.0F + 0x1p-22F);
    return rounded < 0x1p-100F ? 0x1p-100F : rounded;  // NaN stays NaN
  }
  // Computes the listed nodes not yet current this step (stamps them): Φ q by the model's
  // kernel, then the static correction and the rest position.
  void compute_nodes(const std::uint32_t* nodes, std::size_t count) noexcept;
  // A vertex not yet current this step joins pending_ (and is stamped); compute_pending then
  // computes the first `pending` of them.
  void mark_pending(std::uint32_t node, std::size_t& pending) noexcept;
  void compute_pending(std::size_t pending) noexcept;
  void finish_node(std::uint32_t node) noexcept;
  void compute_remaining() noexcept;  // every node not yet current this step
  void compute_all_fused() noexcept;  // every node, one pass (see compute_remaining)
  // After compute_remaining: every cluster's deviation from the hierarchy's reference into
  // checked_deviation_[cluster] (as refit compares); false when one is beyond the slack or
  // not finite.
  bool all_cluster_deviations(float slack_m) noexcept;
  // This state (every vertex computed, none beyond the slack) becomes every cluster's
  // reference (epoch 0) with its exact deviation: what finish_full does when the refit skips.
  // Epoch 0 := the current state (q, loads, magnitude), every cluster's epoch; the users reset.
  void restart_epochs() noexcept;
  void rebase_all() noexcept;
  void ensure_candidates(std::span<const std::uint32_t> ids) noexcept;
  void prepare_epoch(Epoch& epoch) noexcept;
  // The bound of every cluster of `epoch` into bound_ (in packets over the clusters):
  // d_c + min(‖Φ‖ ‖Δq‖, Σ_j max|Φ_j| |Δq_j|) + Σ_l max‖R_l‖ ‖ΔF_l‖ + rounding.
  void epoch_cluster_pass(std::uint32_t epoch) noexcept;
  double epoch_bound(const Epoch& epoch) const noexcept;  // every cluster of the epoch at once
  // A cluster beyond the budget after epoch_cluster_pass: the bound again with the modes' part
  // split at the cluster's mean rows Φ̄ (per axis): |Φ̄ Δq| computed (float, with its rounding
  // bound) + the rows' spread about it, min(max‖Φ_row − Φ̄‖ ‖Δq‖, Σ_j max|Φ_row,j − Φ̄_j| |Δq_j|).
  double refined_bound(std::size_t cluster) const noexcept;
  double rounding_m(const Epoch& epoch) const noexcept;
  double state_magnitude(std::span<const float> modes, std::span<const Load> loads) const noexcept;
  // The next epoch of the ring, holding this step's snapshot; the clusters that referred to
  // it move to it with their bound of this step as d_c (triangle inequality through this
  // state: conservative, looser).
  std::uint32_t take_snapshot_epoch() noexcept;
  void anchor(std::size_t cluster, std::uint32_t epoch, double deviation) noexcept;
  void update_max_used() noexcept;
  float cluster_deviation(std::size_t cluster) const noexcept;

  ContactSurface* surface_ = nullptr;  // bound by begin() for this step
  const model::ModalModel* modal_ = nullptr;  // idem
  std::span<const float> rest_;
  std::span<const float> shapes_;   // the mode-shape matrix (keep_warm)
  std::size_t warm_line_ = 0;       // keep_warm's next cache line of it
  std::span<const float> residual_;     // 3s × 3s, row-major (empty without static correction)
  std::span<const std::int32_t> surface_index_;  // per node, −1 off the surface
  std::uint32_t node_count_ = 0;
  std::uint32_t stored_modes_ = 0;
  std::uint32_t active_modes_ = 0;
  std::uint32_t surface_count_ = 0;
  bool static_correction_ = false;
  bool lazy_allowed_ = true;  // false: static correction over fewer modes than stored

  // Clusters (setup): nodes, and per cluster the maxima the bound uses.
  std::span<std::uint32_t> cluster_nodes_;
  std::span<std::uint32_t> cluster_start_;  // cluster count + 1
  // Transposed (mode- or load-major, a row of cluster_stride_ floats per mode or surface
  // node, rounded up), so that one pass bounds every cluster at once in packets.
  std::size_t cluster_stride_ = 0;
  std::span<float> shape_max_t_;            // active × stride: max over the rows |Φ_row,j|
  std::span<float> residual_max_t_;         // s × stride: max over the rows ‖R_row,l‖₂ (rounded up)
  std::span<double> row_norm_max_;          // cluster: max over rows ‖Φ_row‖₂ (active columns)
  std::span<float> centre_rows_;            // cluster × 3 × active: the mean row Φ̄ per axis
  std::span<float> spread_max_t_;           // active × stride: max over rows |Φ_row,j − Φ̄_j| (rounded up)
  std::span<double> spread_norm_max_;       // cluster: max over rows ‖Φ_row − Φ̄‖₂ (rounded up)
  // Per cluster, this step's epoch_cluster_pass parts: Σ_j max|Φ_row,j| |Δq_j| and the loads'
  // part (float sums, with their covering factor).
  std::span<double> mode_sum_;
  std::span<double> load_part_;
  std::span<double> all_shape_max_;         // active: the maxima over every cluster
  double all_row_norm_max_ = 0.0;
  std::span<double> all_residual_max_;      // s: idem
  double max_shape_entry_ = 0.0;            // max |Φ| (rounding margin)
  double max_rest_abs_ = 0.0;               // max |rest coordinate| (rounding margin)
  double max_residual_entry_ = 0.0;         // max |R| (rounding margin)

  // Per cluster: its reference epoch, its reference's distance from the hierarchy's reference,
  // and the last bound.
  std::span<std::uint32_t> cluster_epoch_;
  std::span<double> used_m_;
  std::span<double> bound_;
  std::span<Epoch> epochs_;  // kEpochs, a ring: the clusters' references
  std::uint32_t latest_epoch_ = 0;
  std::span<std::uint32_t> checked_;  // scratch: clusters beyond the budget this step
  std::span<float> checked_deviation_;
  double budget_m_ = 0.0;

  // The snapshot of this step.
  std::span<float> modes_;
  std::span<Load> loads_;
  std::size_t load_count_ = 0;
  double magnitude_ = 0.0;
  bool reference_valid_ = false;
  bool full_failed_ = false;
  // This step's bound on every vertex's distance (per coordinate) from the hierarchy's
  // reference positions, for TriangleBvh::query_within / query_segment_within; < 0 unknown
  // (the queries then take the slack).
  float within_m_ = -1.0F;

  std::span<float> full_residual_;  // the full path's Σ_l R_kl F_l over the surface, 3s
  bool full_residual_valid_ = false;
  // The surface nodes are one run of nodes in order: node surface_first_node_ + k is surface
  // node k, every other node off the surface (the duct: nodes 16..335).
  bool surface_run_ = false;
  std::uint32_t surface_first_node_ = 0;
  bool all_last_ = false;          // the last step computed every vertex (and did not refit)
  std::span<float> coordinate_deviation_;
  std::span<const float*> load_rows_;  // scratch, 3 per load: compute_all_fused's R rows
  std::span<float> load_forces_;       // and their force components  // scratch, 3n: |now − the hierarchy's reference|
  std::span<std::uint64_t> stamp_;  // per vertex: the step it was computed for
  std::span<std::uint32_t> pending_;  // scratch: nodes to compute
  std::uint64_t step_ = 0;

  std::uint64_t lazy_steps_ = 0;
  std::uint64_t checked_steps_ = 0;
  std::uint64_t full_steps_ = 0;
  std::uint64_t rebased_steps_ = 0;
  std::uint64_t refined_clusters_ = 0;
  std::uint64_t vertices_computed_ = 0;
};

}  // namespace trainer::app
