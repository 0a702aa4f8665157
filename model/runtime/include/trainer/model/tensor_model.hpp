// Cotin's precomputed tetrahedral elasticity at run time (Cotin et al. 1999 §4–5; METHODS.md
// §3): the linear static response of a fixed tetrahedral mesh to displacements imposed at its
// surface nodes, by superposing precomputed tensors instead of solving the FEM system.
//
// For a contact node k the image stores T(n, k) — the displacement of node n per unit
// displacement imposed at k, all other nodes free — for every stored node n, and F(k), the
// force that imposing it takes. One contact: u_n = T(n, k) u*_k, f_k = F(k) u*_k. Several
// contacts k_1..k_m: superposing those over-deforms (each elementary solution also moves the
// other contact nodes), so solve() first finds the corrected constraints d_j from the
// mutual-influence system  Σ_j T(k_i, k_j) d_j = u*_i  (3m × 3m, LU with partial pivoting),
// then u_n = Σ_j T(n, k_j) d_j and f_i = F(k_i) d_i (each elementary solution loads only its
// own contact node and the fixed nodes).
//
// Quasi-non-linear correction (Cotin §4.3): a node's linear displacement is split into the
// part colinear with the constraint direction and the part orthogonal to it, and the two
// amplitudes are mapped through polynomials (the shape of measured force/displacement
// curves); the contact forces are split the same way, the map applied to their totals (what
// a compression test measures) and each contact keeping its linear share. The constraint
// direction is that of the summed imposed displacements — the push of the tool. For one
// contact this is exactly the paper's per-constraint rule; contacts of tools pushing in
// different directions are corrected along their resultant. With identity maps (the default)
// the model is the linear one. The paper maps the orthogonal displacement (the radial bulge
// of a compressed sample) and the colinear force; a non-identity colinear displacement map
// moves the contact nodes off their imposed positions.
//
// Data: views of the model image (which must outlive the model); state carved from a
// core::Arena at create(). Everything after create() is noexcept, allocation-free and returns
// core::Status. Precision: tensors and the field are float32; the mutual-influence system is
// assembled and solved in double (it is at most 3·kMaxContactsLimit unknowns).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/modal_model.hpp"  // Vec3

namespace trainer::model {

// Views of a tet_tensor image (tensor_image.hpp maps the sections onto it).
struct TensorModelData {
  std::uint32_t node_count = 0;
  std::span<const float> rest_positions;          // 3n, m
  std::span<const std::uint32_t> contact_nodes;   // s, strictly increasing: displaceable nodes
  std::span<const std::uint32_t> response_nodes;  // r, strictly increasing: stored responses
  std::span<const float> displacement_tensors;    // (s·r) × 9: row k·r + j = T(response j, k)
  std::span<const float> force_tensors;           // s × 9: F(k), N/m
};

// Amplitude map a ↦ Σ c_i a^i (c_0 = 0) on [0, max_amplitude]; beyond max_amplitude it goes
// on linearly with the slope it has there, so a deep press never meets a runaway polynomial.
// create() checks that the map is finite, starts at 0 and never decreases on [0, max]
// (sampled at 1024 points and through its derivative), so a larger linear amplitude always
// gives a larger non-linear one.
class AmplitudeMap {
 public:
  static constexpr std::size_t kMaxCoefficients = 8;  // degree ≤ 7

  // The identity a ↦ a (the linear model).
  AmplitudeMap() noexcept;
  // `what` names the map in errors (e.g. "nonlinear.force_colinear").
  static core::Expected<AmplitudeMap> create(std::span<const double> coefficients,
                                             double max_amplitude, std::string_view what);

  float evaluate(float amplitude) const noexcept;  // amplitude ≥ 0
  bool is_identity() const noexcept { return identity_; }
  std::span<const float> coefficients() const noexcept { return {coefficients_.data(), count_}; }
  float max_amplitude() const noexcept { return max_amplitude_; }

 private:
  std::array<float, kMaxCoefficients> coefficients_{};
  std::size_t count_ = 0;
  float max_amplitude_ = 0.0F;
  float value_at_max_ = 0.0F;
  float slope_at_max_ = 1.0F;
  bool identity_ = true;
};

struct QuasiNonLinearMaps {
  AmplitudeMap displacement_colinear;    // m → m
  AmplitudeMap displacement_orthogonal;  // m → m
  AmplitudeMap force_colinear;           // N → N
  AmplitudeMap force_orthogonal;         // N → N
};

struct TensorSettings {
  std::uint32_t max_contacts = 8;  // 1..TensorModel::kMaxContactsLimit; sizes the solver state
  QuasiNonLinearMaps nonlinear;    // identity maps = linear elasticity
};

struct TensorContact {
  std::uint32_t node = 0;              // a contact node of the image
  Vec3 displacement_m = Vec3::Zero();  // imposed, from the rest position
};

class TensorModel {
 public:
  static constexpr std::uint32_t kMaxContactsLimit = 64;

  // Setup path: checks every size and index against the data (which the image loader already
  // validated, but the data may come from elsewhere), builds the node → contact and
  // contact → response index maps, and carves the field and solver state from `arena`.
  static core::Expected<TensorModel> create(const TensorModelData& data,
                                            const TensorSettings& settings, core::Arena& arena);

  // ---- RT path: noexcept, no heap ----

  // Imposes `contacts` (replacing the previous set) and computes the corrected constraints
  // and the contact forces: O(m³). An empty span releases every contact (zero field).
  // Refused, with the previous solution kept: more than max_contacts (capacity_exceeded), a
  // node that is not a contact node or appears twice (invalid_argument), a non-finite
  // displacement (numeric_error), and contacts so close together that their mutual-influence
  // system is singular to working precision (numeric_error).
  core::Status solve(std::span<const TensorContact> contacts) noexcept;

  // Force on the tissue at contact i of the last solve (N), non-linear map applied; the tool
  // feels the opposite. total_force() is their sum.
  Vec3 contact_force(std::size_t index) const noexcept;
  Vec3 total_force() const noexcept;
  std::size_t contact_count() const noexcept { return contact_count_; }
  // The contacts of the last accepted solve as they were imposed: node and displacement (m,
  // from rest). solve() on them again reproduces the solution (a graphics host rebuilding the
  // field from the telemetry stream does exactly that).
  std::uint32_t contact_node(std::size_t index) const noexcept {
    return index < contact_count_ ? data_.contact_nodes[slot_contact_[index]] : 0;
  }
  Vec3 imposed_displacement(std::size_t index) const noexcept {
    if (index >= contact_count_) return Vec3::Zero();
    return {slot_imposed_[3 * index], slot_imposed_[3 * index + 1], slot_imposed_[3 * index + 2]};
  }

  // Displacement of one stored node from the last solve, computed on demand in O(m); zero for
  // a node without a stored response (fixed nodes, or interior nodes of a boundary-only
  // image) and with no contacts.
  Vec3 node_displacement(std::uint32_t node) const noexcept;
  // Recomputes every stored node's displacement into displacements() (3r floats, response
  // order): O(m·r), the graphics/collision update.
  void update_field() noexcept;
  std::span<const float> displacements() const noexcept { return field_; }
  // Unit direction of the summed imposed displacements of the last solve (zero if none).
  const Vec3& constraint_direction() const noexcept { return direction_; }

  // -1 when `node` is not a contact node.
  std::int32_t contact_index_of(std::uint32_t node) const noexcept;
  std::int32_t response_index_of(std::uint32_t node) const noexcept;
  std::span<const std::uint32_t> response_nodes() const noexcept { return data_.response_nodes; }
  std::span<const std::uint32_t> contact_nodes() const noexcept { return data_.contact_nodes; }
  std::uint32_t max_contacts() const noexcept { return max_contacts_; }
  // Conditioning of the last accepted solve: its smallest elimination pivot over the largest
  // entry of its system (about 1 for well-separated contacts; solve() refuses < 1e-7).
  double last_pivot_ratio() const noexcept { return last_pivot_ratio_; }

 private:
  TensorModel() = default;
  const float* tensor(std::uint32_t contact, std::uint32_t response) const noexcept {
    return data_.displacement_tensors.data() +
           9 * (static_cast<std::size_t>(contact) * data_.response_nodes.size() + response);
  }
  Vec3 linear_contribution(std::size_t slot, std::uint32_t response) const noexcept;

  TensorModelData data_;
  QuasiNonLinearMaps maps_;
  bool nonlinear_ = false;
  std::uint32_t max_contacts_ = 0;
  std::span<std::int32_t> contact_response_;  // s: response index of each contact node
  std::span<double> system_;                  // (3M)², row-major, M = max_contacts
  std::span<double> rhs_;                     // 3M
  // The last accepted solve.
  std::span<std::uint32_t> slot_contact_;   // M: contact index per slot
  std::span<float> slot_corrected_;         // 3M: d_j
  std::span<float> slot_imposed_;           // 3M: u*_j as imposed
  std::span<float> slot_force_;             // 3M: f_j, non-linear map applied
  Vec3 direction_ = Vec3::Zero();           // unit summed imposed displacement (0 if none)
  std::span<float> field_;                  // 3r
  std::size_t contact_count_ = 0;
  double last_pivot_ratio_ = 1.0;
};

}  // namespace trainer::model
