// Stability of Cotin's tensor model at the extremes (docs/stability.md): Young's modulus over
// ten decades, Poisson's ratio up to 0.4999 (linear tetrahedra lock: measured, not hidden),
// imposed displacements up to twice the block's depth with the liver scene's quasi-non-linear
// maps — through the real precompute (tet4 FEM, CHOLMOD, tensors), the float32 image and the
// runtime TensorModel, checked against the direct sparse solve, the contact force passed
// through the safety chain. The model is static (no state between solves), so "energy never
// grows" has no meaning here; what is checked is that every displacement and force is finite,
// that the float32 runtime keeps agreeing with the double direct solve, and that the force
// after SafetySupervisor::limit_force stays within max_force_n and its slew limit.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model_offline/image_writer.hpp"
#include "trainer/model_offline/tensor_build.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"
#include "safety_chain_probe.hpp"  // tests/support

namespace trainer::model {
namespace {

// A 60 × 40 × 30 mm block on 4 × 3 × 2 cells (60 nodes, 144 tetrahedra), clamped on its base.
constexpr double kBlockDepthM = 0.03;
constexpr double kLiverYoungPa = 1.5e4;
constexpr double kLiverPoisson = 0.45;
constexpr std::uint32_t kMaxContacts = 4;

struct Block {
  offline::TetMesh mesh;
  offline::AssembledTet assembled;
  offline::TensorPrecompute tensors;
  std::vector<std::byte> bytes;
  double reciprocal_condition = 0.0;
  core::Arena arena = core::Arena::create(std::size_t{4} << 20).value();
  ModelImage image;
};

std::vector<int> sorted_unique(std::vector<int> nodes) {
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

std::unique_ptr<Block> build_block(double young_pa, double poisson) {
  auto block = std::make_unique<Block>();
  block->mesh = offline::make_tet_box(0.06, 0.04, kBlockDepthM, 4, 3, 2).value();
  const offline::TetMaterial material{young_pa, poisson, 1060.0};
  const std::vector<int> base = sorted_unique(block->mesh.node_sets.at("z0"));
  auto assembled = offline::assemble_tet(block->mesh, material, {{base, {true, true, true}}});
  EXPECT_TRUE(assembled) << assembled.error().message;
  if (!assembled) return nullptr;
  block->assembled = std::move(assembled).value();
  auto solver = offline::TetStaticSolver::create(block->assembled);
  EXPECT_TRUE(solver) << solver.error().message;
  if (!solver) return nullptr;
  block->reciprocal_condition = solver->reciprocal_condition_estimate();
  offline::TensorPrecomputeOptions options;
  std::set_difference(block->mesh.node_sets.at("surface").begin(),
                      block->mesh.node_sets.at("surface").end(), base.begin(), base.end(),
                      std::back_inserter(options.contact_nodes));
  options.contact_nodes = sorted_unique(options.contact_nodes);
  options.response_nodes = sorted_unique(block->mesh.node_sets.at("all"));
  auto tensors = offline::precompute_tensors(block->assembled, *solver, options);
  EXPECT_TRUE(tensors) << tensors.error().message;
  if (!tensors) return nullptr;
  block->tensors = std::move(tensors).value();
  offline::TensorImageInputs inputs;
  inputs.mesh = &block->mesh;
  inputs.boundary_triangles = offline::boundary_triangles(block->mesh);
  inputs.material = material;
  inputs.fixed_nodes = offline::partly_fixed_nodes(block->assembled.dofs);
  inputs.time_step_s = 1e-3;
  auto bytes = offline::serialize_tensor_image(inputs, block->tensors);
  EXPECT_TRUE(bytes) << bytes.error().message;
  if (!bytes) return nullptr;
  block->bytes = std::move(bytes).value();
  // parse_model_image wants 64-byte-aligned bytes, as load_model_image gives it.
  auto aligned = block->arena.allocate_array<std::byte>(block->bytes.size(), "image");
  EXPECT_TRUE(aligned);
  std::memcpy(aligned.value().data(), block->bytes.data(), block->bytes.size());
  auto image = parse_model_image(aligned.value(), "block.img", ModelKind::tet_tensor,
                                 offline::ImageWriter::permissive_limits());
  EXPECT_TRUE(image) << image.error().message;
  if (!image) return nullptr;
  block->image = std::move(image).value();
  return block;
}

TensorModel make_model(Block& block, const QuasiNonLinearMaps& maps = {}) {
  TensorSettings settings;
  settings.max_contacts = kMaxContacts;
  settings.nonlinear = maps;
  auto model = TensorModel::create(tensor_model_data(block.image), settings, block.arena);
  EXPECT_TRUE(model) << model.error().message;
  return std::move(model).value();
}

std::uint32_t node_nearest(const offline::TetMesh& mesh, const Eigen::Vector3d& point) {
  Eigen::Index best = 0;
  (mesh.nodes.rowwise() - point.transpose()).rowwise().squaredNorm().minCoeff(&best);
  return static_cast<std::uint32_t>(best);
}

// The middle of the top face and its neighbours along x and y: a tool tip's triangle and more.
std::vector<std::uint32_t> top_patch(const offline::TetMesh& mesh) {
  return {node_nearest(mesh, {0.03, 0.02, kBlockDepthM}), node_nearest(mesh, {0.045, 0.02, kBlockDepthM}),
          node_nearest(mesh, {0.03, 0.0333, kBlockDepthM}), node_nearest(mesh, {0.015, 0.02, kBlockDepthM})};
}

bool field_finite(const TensorModel& model) {
  return std::all_of(model.displacements().begin(), model.displacements().end(),
                     [](float value) { return std::isfinite(value); });
}

// The liver scene's quasi-non-linear maps (config/models/liver.toml).
QuasiNonLinearMaps liver_maps() {
  QuasiNonLinearMaps maps;
  const double force[] = {0.0, 1.0, 0.5, 0.1};
  const double orthogonal[] = {0.0, 1.0, 50.0};
  maps.force_colinear = AmplitudeMap::create(force, 5.0, "force_colinear").value();
  maps.displacement_orthogonal =
      AmplitudeMap::create(orthogonal, 0.01, "displacement_orthogonal").value();
  return maps;
}


// Float32 runtime against the double direct solve: what tensor_model_test asserts on the
// liver-like block at ν = 0.45 (2e-5 of the largest displacement / force).
constexpr double kAgreementTolerance = 2e-5;

TEST(TensorStability, YoungsModulusOverTenDecades) {
  // 100 Pa to 1 TPa. The displacement tensors T = C F are dimensionless (C ∝ 1/E, F ∝ E), so
  // the field of a given press must not change with E, and the force must scale with E.
  std::vector<float> reference_field;
  double reference_force_per_pa = 0.0;
  for (double young_pa = 1e2; young_pa <= 1e12 * 1.0001; young_pa *= 10.0) {
    SCOPED_TRACE(young_pa);
    auto block = build_block(young_pa, kLiverPoisson);
    ASSERT_TRUE(block);
    TensorModel model = make_model(*block);
    const auto patch = top_patch(block->mesh);
    const std::array<TensorContact, 2> contacts{{{patch[0], Vec3(0.0F, 0.0F, -0.002F)},
                                                 {patch[1], Vec3(0.0F, 0.0F, -0.001F)}}};
    ASSERT_TRUE(model.solve(contacts).is_ok());
    model.update_field();
    ASSERT_TRUE(field_finite(model));
    const Vec3 force = model.total_force();
    ASSERT_TRUE(force.allFinite());
    const double force_per_pa = static_cast<double>(force.z()) / young_pa;
    const std::vector<float> field(model.displacements().begin(), model.displacements().end());
    if (reference_field.empty()) {
      reference_field = field;
      reference_force_per_pa = force_per_pa;
    }
    double field_change = 0.0;
    for (std::size_t i = 0; i < field.size(); ++i) {
      field_change = std::max(field_change,
                              static_cast<double>(std::abs(field[i] - reference_field[i])) / 0.002);
    }
    auto agreement = offline::measure_tensor_agreement(block->mesh, block->assembled, block->bytes,
                                                       kMaxContacts);
    ASSERT_TRUE(agreement) << agreement.error().message;
    double worst_agreement = 0.0;
    for (const auto& a : *agreement) {
      worst_agreement = std::max({worst_agreement, a.displacement_error, a.force_error});
    }
    test::SafetyChainProbe safety;
    for (int cycle = 0; cycle < 10; ++cycle) safety.pass(-force, 1e-3F);
    std::printf("E %8.1e Pa: force %11.4g N (F/E x%.7f of E = 100 Pa), field change %.1e of the "
                "press, vs direct solve %.1e, T(k,k) = I to %.1e, after safety %.3f N\n",
                young_pa, static_cast<double>(force.norm()), force_per_pa / reference_force_per_pa,
                field_change, worst_agreement, block->tensors.self_tensor_error,
                static_cast<double>(safety.peak_n));
    EXPECT_NEAR(force_per_pa / reference_force_per_pa, 1.0, 1e-5);
    EXPECT_LT(field_change, 1e-5);
    EXPECT_LT(worst_agreement, kAgreementTolerance);
    safety.expect_within_limits(1e-3F);
  }
}

// Mean tip deflection of a 100 × 10 × 10 mm tet4 cantilever (20 × 2 × 2 cells) under an end
// shear, over Timoshenko's: how far linear tetrahedra lock at a given ν.
double cantilever_locking(double poisson) {
  const double length = 0.1, side = 0.01, force = 1e-3, young = 1e6;
  const double inertia = side * side * side * side / 12.0, area = side * side;
  const double shear = young / (2.0 * (1.0 + poisson));
  const double reference = force * length * length * length / (3.0 * young * inertia) +
                           force * length / (5.0 / 6.0 * shear * area);
  const offline::TetMesh mesh = offline::make_tet_box(length, side, side, 20, 2, 2).value();
  auto assembled = offline::assemble_tet(mesh, {young, poisson, 1000.0},
                                         {{mesh.node_sets.at("x0"), {true, true, true}}});
  EXPECT_TRUE(assembled) << assembled.error().message;
  auto solver = offline::TetStaticSolver::create(*assembled);
  EXPECT_TRUE(solver) << solver.error().message;
  offline::TetNodalLoads loads = offline::TetNodalLoads::Zero(mesh.nodes.rows(), 3);
  EXPECT_TRUE(offline::add_tet_group_force(mesh, "x1", Eigen::Vector3d(0, 0, force), loads));
  const auto u = solver->solve_nodal(loads).value();
  double tip = 0.0;
  for (const int node : mesh.node_sets.at("x1")) tip += u(node, 2);
  return tip / static_cast<double>(mesh.node_sets.at("x1").size()) / reference;
}

TEST(TensorStability, PoissonRatioUpTo0_4999LocksButStaysAccurateToTheFem) {
  // As ν → 0.5 the bulk modulus λ + 2μ/3 grows without bound against the shear modulus and
  // linear tetrahedra lock: the FEM itself becomes too stiff (the cantilever's deflection
  // falls to a fraction of the beam's; the press force rises). That is the element's accuracy,
  // not the runtime's: the float32 tensors keep matching the direct double solve of the same
  // FEM, K_ff stays factorisable (CHOLMOD's condition estimate falls ~ (1 − 2ν)), and nothing
  // below 0.5 is refused; ν = 0.5 is (division by 1 − 2ν).
  double previous_locking = 1.0;
  double reference_force_n = 0.0;
  for (const double poisson : {0.3, 0.45, 0.49, 0.499, 0.4999}) {
    SCOPED_TRACE(poisson);
    auto block = build_block(kLiverYoungPa, poisson);
    ASSERT_TRUE(block);
    TensorModel model = make_model(*block);
    const TensorContact press{top_patch(block->mesh)[0], Vec3(0.0F, 0.0F, -0.002F)};
    ASSERT_TRUE(model.solve(std::span(&press, 1)).is_ok());
    model.update_field();
    ASSERT_TRUE(field_finite(model));
    const float force_n = model.total_force().norm();
    ASSERT_TRUE(std::isfinite(force_n));
    if (reference_force_n == 0.0) reference_force_n = static_cast<double>(force_n);
    auto agreement = offline::measure_tensor_agreement(block->mesh, block->assembled, block->bytes,
                                                       kMaxContacts);
    ASSERT_TRUE(agreement) << agreement.error().message;
    double worst_agreement = 0.0;
    for (const auto& a : *agreement) {
      worst_agreement = std::max({worst_agreement, a.displacement_error, a.force_error});
    }
    const double locking = cantilever_locking(poisson);
    std::printf("nu %.4f: 2 mm press %.4f N (x%.3f of nu = 0.3), cantilever %.3f of Timoshenko, "
                "condition estimate %.2e, T(k,k) = I to %.1e, vs direct solve %.1e\n",
                poisson, static_cast<double>(force_n),
                static_cast<double>(force_n) / reference_force_n, locking,
                block->reciprocal_condition, block->tensors.self_tensor_error, worst_agreement);
    EXPECT_LT(locking, previous_locking);  // monotone: locking only worsens towards 0.5
    previous_locking = locking;
    EXPECT_LT(worst_agreement, kAgreementTolerance);
    EXPECT_LT(block->tensors.self_tensor_error, 1e-9);
  }
  // ν = 0.5 itself is refused, naming the value and the range.
  const offline::TetMesh mesh = offline::make_tet_box(0.01, 0.01, 0.01, 1, 1, 1).value();
  auto refused = offline::assemble_tet(mesh, {kLiverYoungPa, 0.5, 1000.0},
                                       {{mesh.node_sets.at("z0"), {true, true, true}}});
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("poisson_ratio is 0.5"), std::string::npos)
      << refused.error().message;
}

TEST(TensorStability, PressUpToTwiceTheBlockDepthWithTheLiverMaps) {
  // The top-centre node (and a 4-node patch) driven down 1 mm .. 60 mm, twice the 30 mm block
  // depth (the linear model lets the surface pass the clamped base), with the liver scene's
  // quasi-non-linear maps, each depth ramped over 50 cycles of 1 ms. Beyond the maps' fitted
  // range they go on linearly, so the force keeps growing with the depth, finite; after the
  // safety chain it stays within 8 N and its slew.
  auto block = build_block(kLiverYoungPa, kLiverPoisson);
  ASSERT_TRUE(block);
  TensorModel model = make_model(*block, liver_maps());
  const auto patch = top_patch(block->mesh);
  for (const std::size_t contacts : {std::size_t{1}, patch.size()}) {
    float previous_force_n = 0.0F;
    for (const float depth_m : {0.001F, 0.005F, 0.01F, 0.02F, 0.03F, 0.06F}) {
      SCOPED_TRACE(testing::Message() << contacts << " contacts, depth " << depth_m << " m");
      test::SafetyChainProbe safety;
      float force_n = 0.0F;
      for (int cycle = 0; cycle < 50; ++cycle) {
        const float reached = depth_m * static_cast<float>(cycle + 1) / 50.0F;
        std::array<TensorContact, kMaxContacts> set{};
        for (std::size_t i = 0; i < contacts; ++i) set[i] = {patch[i], Vec3(0.0F, 0.0F, -reached)};
        ASSERT_TRUE(model.solve(std::span(set.data(), contacts)).is_ok());
        model.update_field();
        ASSERT_TRUE(field_finite(model));
        const Vec3 total = model.total_force();
        ASSERT_TRUE(total.allFinite());
        force_n = total.norm();
        safety.pass(-total, 1e-3F);
      }
      // Every contact node sits where it was put (the colinear displacement map is identity).
      for (std::size_t i = 0; i < contacts; ++i) {
        EXPECT_NEAR(model.node_displacement(patch[i]).z(), -depth_m, 1e-5F * depth_m);
      }
      std::printf("%zu contact(s), depth %4.0f mm: force on the tissue %9.3f N, after safety %.3f N, "
                  "pivot ratio %.2e\n",
                  contacts, 1e3 * static_cast<double>(depth_m), static_cast<double>(force_n),
                  static_cast<double>(safety.peak_n), model.last_pivot_ratio());
      EXPECT_GT(force_n, previous_force_n);
      previous_force_n = force_n;
      safety.expect_within_limits(1e-3F);
    }
  }
}

}  // namespace
}  // namespace trainer::model
