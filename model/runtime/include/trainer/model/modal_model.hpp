// The reduced-modal duct at run time (NIRMS, Basdogan §V-C-1 and Appendix B; METHODS.md §1):
// r decoupled modal oscillators integrated with average-acceleration Newmark, nodal forces
// projected on the modes through the rows of the loaded nodes only, displacements read back
// per node (haptic rate, O(r)) or for the whole mesh (graphics rate, O(n r)), optional static
// correction by the residual compliance, and displacement-driven contact (the forces that
// put contact nodes at imposed positions).
//
// Data: plain views of the model image (mode shapes, ω², damping, residual compliance), which
// must outlive the model; every piece of state is carved from a core::Arena at create().
// Everything after create() is noexcept, allocation-free and returns a core::Status. One
// thread owns the model (the haptic thread): reconstruct() reads the live state, so another
// thread wanting the field rebuilds it from published modal coordinates (DESIGN.md).
//
// Precision: `Scalar` is the precision of the stored data (rest positions, mode shapes, ω²,
// damping, residual compliance) and of the interface (time step, forces, imposed and returned
// displacements, the reconstructed field). ModalModel (float) is what the appliance runs on a
// float32 model image; ModalModelDouble runs the same algorithms on double data (a build held
// in memory, offline::DoubleModalData), so the speed/accuracy trade can measure what float32
// storage costs. In both, the modal state (x, v, a per mode), the Newmark constants and the
// accumulated nodal forces are double, and every sum is accumulated in double. Measured at
// Δt = 1 ms, 10 Hz..1.6 kHz: with a float state an undamped oscillator's amplitude drifts by
// 7e-6..5e-5 in 1000 steps and 3e-5..5e-3 in 100,000 steps (one hour of use is 3.6 million
// steps at 1 kHz); with the double state the runtime test measures 2.5e-8 after 100,000 steps.
// The state is r values per array; the per-step work is the same count of operations.
// What float storage itself costs (modal_model_double_test.cpp, 40 Hz undamped mode,
// 100,000 steps, against the scheme's closed form): ω² and Δt rounded to float shift the
// phase by 1.3e-3 of the amplitude (ModalModel) against 5e-11 with double data
// (ModalModelDouble); one step of static correction differs by R's rounding, 5e-8 vs 1e-16.
//
// Units: SI. Mode shapes are M-orthonormal (kg^-1/2), modal coordinates kg^1/2·m, modal
// damping α_i in 1/s (ẍ + α ẋ + ω² x = f), residual compliance m/N.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"

namespace trainer::model {

using Vec3 = Eigen::Vector3f;

// Views of the stored model; the lead maps the model image's sections onto it (float), or
// offline code a build held in memory (float or double).
template <typename Scalar>
struct BasicModalModelData {
  std::uint32_t node_count = 0;
  std::uint32_t mode_count = 0;                  // stored modes r
  std::span<const Scalar> rest_positions;        // 3n, m
  std::span<const Scalar> mode_shapes;           // 3n × r row-major: row node*3 + axis
  std::span<const Scalar> omega_squared;         // r, rad²/s², ascending, > 0
  std::span<const Scalar> modal_damping;         // r, α_i (1/s), ≥ 0
  std::span<const std::uint32_t> surface_nodes;  // s nodes tools may touch (rows of R)
  std::span<const Scalar> residual_compliance;   // 3s × 3s row-major, m/N; may be empty
};

template <typename Scalar>
struct BasicModalSettings {
  Scalar time_step_s = Scalar{0};
  std::uint32_t active_modes = 0;  // first modes integrated, ≤ stored; 0 = all
  bool static_correction = false;  // add R·F (needs residual_compliance)
};

template <typename Scalar>
struct BasicImposedDisplacement {
  std::uint32_t node = 0;
  // From the rest position, at the end of the next step.
  Eigen::Matrix<Scalar, 3, 1> displacement_m = Eigen::Matrix<Scalar, 3, 1>::Zero();
};

template <typename Scalar>
class BasicModalModel {
  static_assert(std::is_same_v<Scalar, float> || std::is_same_v<Scalar, double>,
                "the modal model is instantiated for float (images) and double (offline)");

 public:
  using Vector3 = Eigen::Matrix<Scalar, 3, 1>;

  static constexpr std::size_t kMaxContacts = 8;      // simultaneous imposed displacements
  static constexpr std::size_t kMaxLoadedNodes = 64;  // distinct nodes carrying a force
  static constexpr std::size_t kFactorisations = 4;   // contact factorisations kept (LRU)

  // Setup path: checks every size, value and index, carves the state from `arena`, and
  // precomputes the Newmark constants per mode. `data`'s arrays must outlive the model.
  static core::Expected<BasicModalModel> create(const BasicModalModelData<Scalar>& data,
                                                core::Arena& arena,
                                                const BasicModalSettings<Scalar>& settings);

  // ---- RT path: noexcept, no heap ----

  // Adds `force_n` (N) on `node` for the next step(s). Forces accumulate per node and stay
  // applied until clear_forces(). Refuses (nothing applied): unknown node, non-finite force
  // (numeric_error), more than kMaxLoadedNodes distinct nodes, and — with static correction —
  // a node outside surface_nodes (its residual compliance is unknown).
  core::Status add_node_force(std::uint32_t node, const Vector3& force_n) noexcept;
  void clear_forces() noexcept;

  // One Newmark step of Δt with the applied forces acting at its end (F_{n+1}).
  core::Status step() noexcept;

  // Displacement (m) of `node` after the last step: Φ_node x, plus — with static correction
  // and a surface node — Σ_l R_node,l F_l over the forces of the last step. Zero for an
  // unknown node.
  Vector3 displacement(std::uint32_t node) const noexcept;
  Vector3 rest_position(std::uint32_t node) const noexcept;

  // Forces (N, written to forces_out[k]) that make the displacement of targets[k].node after
  // the next step() equal targets[k].displacement_m, given the forces already applied; they
  // are added to the applied forces, the caller then calls step(). Solves the 3c × 3c system
  // (c ≤ kMaxContacts) of the contact compliance of the next step
  //   u_k(F) = Φ_k diag(1/k̂) (Φᵀ F + a0 x + a2 v + a) [+ R_kl F_l].
  // Work per call: the compliance block of two nodes is a constant of the model, so it is
  // computed once when a node enters the contact cache (kMaxContacts nodes, the most recently
  // contacted) and gathered from there afterwards; a factorisation is reused whenever the
  // target nodes (in order) are those of one of the last kFactorisations factorised (a held
  // contact that releases every step alternates between two lists); the free response of a
  // node (its next-step displacement without contact forces) is kept for the step, so a
  // re-solve after a release (clear_forces() and fewer targets, in the same step) only
  // gathers the kept rows (and factorises them when that list is new). Every value is computed by the same operations as a solve from scratch:
  // the forces are bit-identical to a cold solve (modal_model_test checks it).
  // Refuses (nothing applied): more than kMaxContacts targets, a repeated or unknown node,
  // forces_out shorter than targets, non-finite targets, a non-surface node with static
  // correction, fewer active modes than 3c without static correction, and a singular contact
  // compliance (a fixed node).
  core::Status solve_imposed(std::span<const BasicImposedDisplacement<Scalar>> targets,
                             std::span<Vector3> forces_out) noexcept;

  // Full displacement field (graphics rate, and the contact surface every cycle a tool is
  // near): out[3i + axis] for node i, including the static correction when enabled. Refuses a
  // span shorter than 3n. Computed as one Scalar matrix–vector product Φ q plus, with static
  // correction, one row of R per loaded dof (R is symmetric): within Scalar rounding of
  // displacement(i) (which sums in double), not bit-identical. With static correction over
  // fewer modes than stored and a load, it falls back to displacement() per node (exact, slow).
  core::Status reconstruct(std::span<Scalar> out_3n) const noexcept;

  // Φ_node q for `count` nodes (nodes[k], or node k when `nodes` is null) into
  // out_3n[3·node + axis], with `modes` the active modal coordinates in Scalar (reconstruct()
  // uses x rounded to Scalar). The kernel reconstruct() itself runs (one compiled function):
  // a caller computing some nodes gets reconstruct()'s bits for them (before its static
  // correction), on any vector level. No checks (RT hot path): nodes < node_count(), modes
  // active_mode_count() long.
  void shape_rows(const std::uint32_t* nodes, std::size_t count, const Scalar* modes,
                  Scalar* out_3n) const noexcept;

  void reset() noexcept;  // back to rest, forces cleared

  std::uint32_t node_count() const noexcept { return node_count_; }
  std::uint32_t active_mode_count() const noexcept { return active_modes_; }
  // Contact-matrix factorisations solve_imposed has computed (the others were reused).
  std::uint64_t contact_factorisations() const noexcept { return factorisations_->computed; }
  Scalar time_step_s() const noexcept { return time_step_s_; }
  bool static_correction() const noexcept { return static_correction_; }
  std::size_t applied_load_count() const noexcept { return pending_count_; }
  std::span<const double> modal_displacement() const noexcept { return {x_.data(), active_modes_}; }
  // The nodal forces of the last step (what displacement() and reconstruct() add the static
  // correction of): count, then each load's node and force (N). Another thread rebuilding the
  // field from published modal coordinates needs them too (the telemetry stream).
  std::size_t stepped_load_count() const noexcept { return stepped_count_; }
  std::uint32_t stepped_load_node(std::size_t index) const noexcept {
    return index < stepped_count_ ? stepped_loads_[index].node : 0;
  }
  Vector3 stepped_load_force(std::size_t index) const noexcept {
    if (index >= stepped_count_) return Vector3::Zero();
    const NodeLoad& load = stepped_loads_[index];
    return Vector3(static_cast<Scalar>(load.force_n[0]), static_cast<Scalar>(load.force_n[1]),
                   static_cast<Scalar>(load.force_n[2]));
  }
  std::span<const double> modal_velocity() const noexcept { return {v_.data(), active_modes_}; }
  std::span<const double> modal_acceleration() const noexcept { return {a_.data(), active_modes_}; }

 private:
  // One nodal load; plain arrays so the arena can hold it (trivially destructible). Kept in
  // double: forces solved by solve_imposed() go into the dynamics unrounded, so an
  // ill-conditioned contact compliance (few modes, no static correction) still reaches its
  // targets; callers see Scalar forces.
  struct NodeLoad {
    std::uint32_t node;
    std::int32_t surface_index;  // row block in R, −1 if not a surface node
    double force_n[3];
  };

  BasicModalModel() = default;

  const Scalar* shape_row(std::uint32_t node, int axis) const noexcept {
    return mode_shapes_.data() +
           (static_cast<std::size_t>(node) * 3 + static_cast<std::size_t>(axis)) * stored_modes_;
  }
  const Scalar* compliance_block(std::int32_t row_surface,
                                 std::int32_t column_surface) const noexcept;
  // Σ over `loads` of R_{surface,l} F_l (m); zero when static correction is off.
  // Static response at `node` to `loads` through the residual compliance of the ACTIVE basis:
  // the stored R (the residual of all stored modes) plus the static part of the stored modes
  // left inactive, Σ_{i ≥ active} φ_i φ_iᵀ / ω_i². Without the second term, running fewer
  // modes than stored would silently lose their static contribution.
  Eigen::Vector3d static_response(std::uint32_t node, std::span<const NodeLoad> loads) const noexcept;
  double residual_entry(std::uint32_t node_k, int axis_k, std::uint32_t node_l,
                        int axis_l) const noexcept;
  // Modal force Φᵀ F of the pending loads into modal_force_, incrementally: loads already
  // projected since the last clear (and unchanged) are not projected again, so the contact
  // solve's projection of the applied loads is reused by step(). The sum runs over the loads
  // in the same order either way (bit-identical to projecting all of them).
  void project_pending_forces() noexcept;
  // Puts every target node in the contact cache (slot_of[k]: its slot), computing the
  // compliance blocks of the nodes that enter it.
  void gather_contact_slots(std::span<const BasicImposedDisplacement<Scalar>> targets,
                            std::span<std::uint32_t> slot_of) noexcept;
  // Modal part of the compliance of node_a (row axis) to a unit force at node_b (column axis)
  // in the next step: Σ_i φ_a,i φ_b,i / k̂_i (symmetric to the bit: products commute).
  void modal_compliance_block(std::uint32_t node_a, std::uint32_t node_b,
                              double (&block)[3][3]) const noexcept;
  void fill_cache_blocks(std::uint32_t slot_a, std::uint32_t slot_b) noexcept;
  // The free responses of the nodes in three contact-cache slots (repeats allowed).
  void free_responses(std::uint32_t slot_a, std::uint32_t slot_b, std::uint32_t slot_c) noexcept;
  std::size_t find_pending(std::uint32_t node) const noexcept;
  core::Status add_force(std::uint32_t node, const Eigen::Vector3d& force_n) noexcept;

  std::uint32_t node_count_ = 0;
  std::uint32_t stored_modes_ = 0;
  std::uint32_t active_modes_ = 0;
  std::uint32_t surface_count_ = 0;
  Scalar time_step_s_ = Scalar{0};
  bool static_correction_ = false;
  std::span<const Scalar> rest_positions_;
  std::span<const Scalar> mode_shapes_;
  std::span<const Scalar> residual_compliance_;
  std::span<const std::int32_t> surface_index_;  // per node: index in surface_nodes or −1

  // Per mode (arena): Newmark constants and state.
  std::span<double> omega_squared_;
  std::span<double> inactive_inverse_omega_squared_;  // 1/ω_i² for stored modes i ≥ active
  std::span<double> a0_;             // (4 + 2 α Δt)/Δt²
  std::span<double> a2_;             // 4/Δt + α
  std::span<double> inverse_k_hat_;  // 1/(ω² + a0)
  std::span<double> x_;
  std::span<double> v_;
  std::span<double> a_;
  std::span<double> modal_force_;  // scratch: Φᵀ F
  std::span<double> predicted_;    // scratch for solve_imposed
  std::span<Scalar> reconstruct_modes_;     // scratch for reconstruct: x in Scalar
  std::span<Scalar> reconstruct_residual_;  // scratch for reconstruct: R F over the surface, 3s

  std::span<NodeLoad> pending_loads_;  // applied at the next step (kMaxLoadedNodes)
  std::span<NodeLoad> stepped_loads_;  // the forces of the last step (for the static part)
  std::size_t pending_count_ = 0;
  std::size_t stepped_count_ = 0;
  std::size_t projected_count_ = 0;  // pending loads [0, projected_count_) are in modal_force_

  // The contact cache (carved from the arena; plain arrays): up to kMaxContacts nodes in
  // slots, the compliance blocks of the pairs of them solved together so far (pair_valid) —
  // entry (3a + i, 3b + j) is the compliance of node a axis i to a force at node b axis j,
  // both orientations stored since the residual compliance is read row-first — and each
  // node's free response with the state epoch it belongs to (0: none).
  static constexpr std::size_t kContactRows = 3 * kMaxContacts;
  struct ContactCache {
    std::uint32_t slot_count;
    std::uint32_t nodes[kMaxContacts];
    std::uint64_t response_epoch[kMaxContacts];
    double free_response[kContactRows];
    double compliance[kContactRows * kContactRows];
    bool pair_valid[kMaxContacts * kMaxContacts];
  };
  using ContactMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor,
                                      static_cast<int>(kContactRows), static_cast<int>(kContactRows)>;
  ContactCache* contact_cache_ = nullptr;
  // The stored residual compliance is symmetric to the bit (checked at create()): a block's
  // transposed orientation then reads the same values, and only one orientation is read.
  bool residual_symmetric_ = false;
  std::uint64_t state_epoch_ = 0;  // counts steps and resets: the free responses' validity
  // The last kFactorisations accepted factorisations (arena), each with the target nodes (in
  // order) it was built for: the contact matrix of a node list is a constant of the model, so a
  // factorisation stays valid for good. Several are kept because a held contact alternates
  // between two lists within every step when it releases (the full set, then the kept rows)
  // — with one kept, both were factorised again every step. Least recently used replaced.
  struct Factorisation {
    Eigen::LDLT<ContactMatrix> ldlt;
    std::uint32_t nodes[kMaxContacts];
    std::size_t count;  // 0: empty
    std::uint64_t last_use;
  };
  struct FactorisationCache {
    Factorisation entries[kFactorisations];
    std::uint64_t clock;
    std::uint64_t computed;  // factorisations computed so far (tests, measurements)
  };
  // The entry factorising the contact matrix of `targets` (looked up, else computed and checked
  // for singularity); nullptr when it is singular.
  const Eigen::LDLT<ContactMatrix>* contact_factorisation(
      std::span<const BasicImposedDisplacement<Scalar>> targets,
      std::span<const std::uint32_t> slot_of) noexcept;
  FactorisationCache* factorisations_ = nullptr;
};

// Both instantiations live in modal_model.cpp.
extern template class BasicModalModel<float>;
extern template class BasicModalModel<double>;

// The appliance's model: float32 image data, float interface.
using ModalModelData = BasicModalModelData<float>;
using ModalSettings = BasicModalSettings<float>;
using ImposedDisplacement = BasicImposedDisplacement<float>;
using ModalModel = BasicModalModel<float>;

// The same model on double data with a double interface (offline precision measurements).
using ModalModelDataDouble = BasicModalModelData<double>;
using ModalSettingsDouble = BasicModalSettings<double>;
using ImposedDisplacementDouble = BasicImposedDisplacement<double>;
using ModalModelDouble = BasicModalModel<double>;

}  // namespace trainer::model
