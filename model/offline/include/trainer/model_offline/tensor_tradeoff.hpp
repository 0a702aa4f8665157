// The speed/accuracy trade of Cotin's tensor model, measured: the knob is the contact cap m,
// the most contact nodes the runtime imposes at once (TensorSettings::max_contacts; the solve
// is O(m³), docs/tensor-model.md). A spherical probe tip pressed into the tissue covers some
// contact nodes; the reference imposes ALL of them, the configuration with cap m only the m
// deepest, through the runtime trainer::model::TensorModel (float32 image, mutual-influence
// solve, the quasi-non-linear force maps if given) as the trainer does. The error is of the
// total force the probe feels.
//
// A press: the probe (radius R) touches the surface at `surface_point_m` and is pushed `depth`
// along `inward`, so its centre is c = surface_point + (depth − R)·inward. Every contact node
// x strictly inside the sphere is covered and put on its surface by the nearest-point (radial)
// projection, imposed displacement u = c + R (x − c)/|x − c| − x; its depth is R − |x − c|.
// Nodes outside stay free. Imposing every covered node glues the tissue to the probe: a covered
// node near the rim, which the pressed tissue would carry away from the sphere, is held on it
// and pulls (on the liver block the probe-centre press then needs less force 6.7 mm deep than
// 2.7 mm deep). So, by default, as the trainer releases a contact whose force would pull the
// surface outward (docs/tensor-model.md), a node whose force has a component towards the
// probe's centre is released and the rest solved again until none pulls; the pushing nodes
// left are the press's contact set. (release_pulling_nodes = false keeps every covered node.)
// Static, linear geometry, frictionless; a node the probe does not cover is never added even
// if the deformed surface would meet the sphere.
//
// Reference: solve_imposed_displacements — a direct sparse solve in double of the full
// tetrahedral system with the contact set imposed, its own factorisation (it shares only the
// assembly with the precompute; the runtime model only proposes which nodes pull, the direct
// solve confirms it) — and, when the spec has quasi-non-linear maps, the runtime's force rule
// applied to its total (the push direction being the direction of the summed imposed
// displacements; TensorModel::solve). A configuration with cap m imposes the m deepest nodes of
// the contact set through the runtime model and releases pulling ones the same way; with m at
// least the size of the contact set it imposes the same set and agrees to float rounding.
//
// Cost: TensorModel::solve with m contacts (the contact set of the press with the largest one,
// deepest first, completed by the nearest other contact nodes held in place when it has fewer
// than m), depths varying by ±10 % from cycle to cycle, one solve per cycle, warm-up then
// repetitions: CycleCost::haptic_median/p99 = solve (what the haptic loop needs every cycle),
// median/p99 = solve + update_field (the stored field for graphics and collision).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model_offline/gmsh_reader.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"  // CycleCostOptions, CycleCost
#include "trainer/model_offline/tet_elasticity.hpp"

namespace trainer::model::offline {

// One probe position, pressed to several depths (each a static press).
struct TensorProbeScenario {
  std::string name;
  std::string description;
  bool tuning = false;  // true: a configuration is chosen on it; false: held out (validation)
  Eigen::Vector3d surface_point_m = Eigen::Vector3d::Zero();  // where the probe first touches
  Eigen::Vector3d inward = -Eigen::Vector3d::UnitZ();         // unit push direction
  double radius_m = 0.005;
  std::vector<double> depths_m;  // each in (0, radius)
};

// The defaults for a mesh whose top (largest z) face is free, like the generators' boxes and
// cylinders resting on z = 0 (liver.toml): with h the spacing of the top face's contact nodes
// (median nearest-neighbour distance), all pressing along −z —
//   tuning:   a small probe (R = 0.55 h) centred on the top node nearest the face's centre,
//             0.3 R and 0.6 R deep (it covers that node only); a probe of R = 1.6 h at the
//             face's centre, 0.2, 0.35, 0.5 R deep;
//   held out: R = 1.6 h off the nodes (centre shifted 0.37 h, 0.23 h), 0.25 and 0.45 R deep; a
//             wide probe R = 2.7 h at the centre, 0.2 and 0.4 R deep; R = 1.6 h 0.3 h inside
//             the +x edge (the sphere overlaps the side face), 0.25 and 0.45 R deep.
// For the liver block (h = 8.3 mm) the radii are 4.6, 13.3 and 22.5 mm. Fails when the mesh has
// fewer than two contact nodes on its top face.
core::Expected<std::vector<TensorProbeScenario>> default_tensor_scenarios(
    const TetMesh& mesh, std::span<const int> contact_nodes);

struct TensorStudySpec {
  TetMesh mesh;
  TetMaterial material;
  std::vector<TetNodeFix> fixes;
  std::string contact_set = "surface";  // node set the probe may displace (fixed nodes dropped)
  QuasiNonLinearMaps nonlinear;         // identity maps (default): the linear model
  bool release_pulling_nodes = true;    // no adhesion (see above); false: every covered node
  int contacts_per_block = 128;         // precompute memory (TensorPrecomputeOptions)
};

struct TensorTradeConfig {
  std::uint32_t max_contacts = 8;  // the cap m, 1..TensorModel::kMaxContactsLimit
  std::string label() const;       // e.g. "m8"
};

struct TensorScenarioError {
  std::string scenario;
  bool tuning = false;
  double radius_m = 0.0;
  int covered_nodes = 0;  // nodes inside the probe at its deepest press
  int contact_nodes = 0;  // of those, the reference's contact set (pushing) at that press
  int imposed_nodes = 0;  // imposed by this configuration there, after its own releases
  double force_error = 0.0;          // max over depths |F − F_ref| / |F_ref|
  double direction_error_rad = 0.0;  // max over depths of the angle between F and F_ref
  double reference_force_n = 0.0;    // |F_ref| at the deepest press
};

struct TensorTradePoint {
  TensorTradeConfig config;
  CycleCost cost;
  std::size_t state_bytes = 0;  // arena bytes TensorModel::create took (solver state + field)
  std::vector<TensorScenarioError> errors;
  double tuning_error = 0.0;      // worst force error over the tuning scenarios
  double validation_error = 0.0;  // worst over the held-out scenarios
  double worst_error = 0.0;       // worst over all
};

class TensorTradeStudy {
 public:
  // One press of one scenario: the covered nodes deepest first (ties: lower node first) with
  // their imposed displacements, which of them form the contact set, and the reference's
  // total force on the tissue.
  struct Press {
    double depth_m = 0.0;
    Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
    std::vector<std::uint32_t> nodes;
    std::vector<Eigen::Vector3d> displacements_m;
    std::vector<std::size_t> contact_set;  // indices into nodes, deepest first
    Eigen::Vector3d reference_force_n = Eigen::Vector3d::Zero();
    int reference_solves = 0;  // direct solves it took (1 unless the runtime's guess was off)
  };

  // Assembles and factorises the mesh, precomputes the tensors of every contact node (stored:
  // the "surface" node set and the contacts), serialises and parses the image as the trainer
  // loads it, then finds every press's covered nodes and solves its reference. Errors: the
  // builders' (mesh, material, fixes), an unknown contact set or one without free nodes, a
  // scenario with a non-unit direction, a radius ≤ 0, a depth outside (0, R), or a press
  // covering no contact node.
  static core::Expected<std::unique_ptr<TensorTradeStudy>> create(
      TensorStudySpec spec, std::vector<TensorProbeScenario> scenarios);

  // One cap m: a TensorModel with max_contacts = m on the study's image, every press with the
  // m deepest covered nodes, then the timing loop. Errors: m outside 1..kMaxContactsLimit or
  // above the number of contact nodes, a solve the runtime refuses, bad cost options.
  core::Expected<TensorTradePoint> measure(const TensorTradeConfig& config,
                                           const CycleCostOptions& cost_options) const;

  const TensorStudySpec& spec() const { return spec_; }
  const std::vector<TensorProbeScenario>& scenarios() const { return scenarios_; }
  const std::vector<std::vector<Press>>& presses() const { return presses_; }  // per scenario
  std::span<const int> contact_nodes() const { return contact_nodes_; }
  std::size_t stored_node_count() const { return stored_node_count_; }
  std::size_t image_bytes() const { return image_bytes_; }
  double precompute_s() const { return precompute_s_; }  // assembly to parsed image
  double reference_solve_s() const { return reference_solve_s_; }  // every press's direct solve
  std::size_t largest_contact_set() const;  // most nodes one press's contact set holds

 private:
  TensorTradeStudy() = default;

  TensorStudySpec spec_;
  std::vector<TensorProbeScenario> scenarios_;
  std::vector<std::vector<Press>> presses_;
  std::vector<int> contact_nodes_;
  std::size_t stored_node_count_ = 0;
  std::size_t image_bytes_ = 0;
  double precompute_s_ = 0.0;
  double reference_solve_s_ = 0.0;
  std::unique_ptr<core::Arena> image_arena_;  // the parsed image's 64-byte-aligned bytes
  ModelImage image_;
};

}  // namespace trainer::model::offline
