// The whole modal chain as the appliance uses it, on a small duct-like tube: build_modal_model
// → write_modal_image → load_model_image (into an arena, as rt/app does) → runtime ModalModel,
// checked against the exact static solution of the full shell (ShellStaticSolver), plus
// measure_modal_accuracy's trends, the same build run in float and in double
// (FloatModalData, DoubleModalData), and the builder's refusals.
//
// Why a steady state: under a constant force the damped modal oscillators settle at
// x = Ω⁻² Φᵀ F, so the runtime displacement becomes the modal static response, which with
// static correction (residual compliance R = K⁻¹ − Φ Ω⁻² Φᵀ at the surface nodes) is exactly
// K⁻¹ F. The 1e-3 relative tolerance covers the float32 image (mode shapes and R rounded to
// 2^-24 relative, sums in double) and the transient left after the settling time below (e^-14).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/dnios.hpp"
#include "trainer/model_offline/loads.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/modal_accuracy.hpp"
#include "trainer/model_offline/modal_build.hpp"
#include "trainer/model_offline/residual.hpp"
#include "trainer/model_offline/static_solve.hpp"

namespace trainer::model::offline {
namespace {

namespace fs = std::filesystem;

// A small cystic-duct-like tube (METHODS.md §1 scale): radius 4.3 mm, length 24.4 mm,
// 6 rings × 8 segments (48 nodes; the x = 0 ring clamped leaves 40 nodes, 120 translational
// dofs), soft tissue E = 0.3 MPa, ν = 0.45, wall 1 mm, ρ = 1000 kg/m³.
constexpr double kRadius = 0.0043, kLength = 0.0244;
constexpr int kRings = 6, kSegments = 8;
constexpr int kClampedNodes = kSegments;  // ring 0: nodes 0..7
constexpr int kTranslationalDofs = 3 * (kRings - 1) * kSegments;
constexpr int kStoredModes = 20;
constexpr double kTimeStep = 1e-3;

ModalBuildSpec tube_spec(int mode_count, bool static_correction) {
  auto mesh = make_tube(kRadius, kLength, kRings, kSegments);
  EXPECT_TRUE(mesh.has_value());
  ModalBuildSpec spec;
  spec.name = "test_tube";
  spec.mesh = std::move(mesh).value();
  spec.material = ShellMaterial{3.0e5, 0.45, 1.0e-3, 1000.0};
  spec.bending = BendingElement::dkt;
  spec.fixes = {{"clamped", {kUx, kUy, kUz, kRx, kRy, kRz}}};
  spec.mode_count = mode_count;
  spec.damping_ratio = 0.05;
  spec.time_step_s = kTimeStep;
  spec.static_correction = static_correction;
  spec.surface_set = "all";  // includes the clamped ring: the builder must drop it
  return spec;
}

ModalBuildResult build(const ModalBuildSpec& spec) {
  auto result = build_modal_model(spec);
  if (!result) {
    ADD_FAILURE() << result.error().message;
    return {};
  }
  return std::move(result).value();
}

// A per-test temporary image path.
fs::path image_path(const std::string& suffix) {
  return fs::temp_directory_path() /
         ("modal_build_test_" + std::to_string(::getpid()) + "_" +
          ::testing::UnitTest::GetInstance()->current_test_info()->name() + suffix + ".img");
}

// An image loaded the way the trainer loads it (rt/app/src/models/modal_setup.cpp), and its
// ModalModelData views.
struct LoadedImage {
  core::Arena arena;
  ModelImage image;
  ModalModelData data;
};

LoadedImage load(const fs::path& path) {
  auto arena = core::Arena::create(std::size_t{4} << 20);
  EXPECT_TRUE(arena.has_value());
  LoadedImage loaded{std::move(arena).value(), {}, {}};
  auto image = load_model_image(path, loaded.arena, ImageLimits{}, ModelKind::modal_shell);
  if (!image) {
    ADD_FAILURE() << image.error().message;
    return loaded;
  }
  loaded.image = *image;
  loaded.data = modal_model_data(loaded.image);
  return loaded;
}

// Steps for the slowest active mode's transient to decay by e^-14 (≈ 1e-6). Each mode's
// envelope decays as e^(-α t / 2) when underdamped (α < 2ω), as its slow root
// (α − sqrt(α² − 4ω²)) / 2 when overdamped.
int settling_steps(const ModalBuildResult& result, int active_modes) {
  double slowest_rate_per_s = std::numeric_limits<double>::infinity();
  for (int i = 0; i < active_modes; ++i) {
    const double alpha = result.modal_damping(i);
    const double omega_squared = result.basis.omega_squared(i);
    const double rate = alpha * alpha < 4.0 * omega_squared
                            ? alpha / 2.0
                            : (alpha - std::sqrt(alpha * alpha - 4.0 * omega_squared)) / 2.0;
    slowest_rate_per_s = std::min(slowest_rate_per_s, rate);
  }
  return static_cast<int>(std::ceil(14.0 / (slowest_rate_per_s * kTimeStep)));
}

// Runtime displacement of `node` after a constant `force_n` has acted there for `steps` steps.
Eigen::Vector3d settled_displacement(const ModalModelData& data, const ModalSettings& settings,
                                     int node, const Eigen::Vector3d& force_n, int steps) {
  auto arena = core::Arena::create(std::size_t{1} << 20);
  EXPECT_TRUE(arena.has_value());
  auto model = ModalModel::create(data, *arena, settings);
  if (!model) {
    ADD_FAILURE() << model.error().message;
    return Eigen::Vector3d::Constant(std::nan(""));
  }
  const auto index = static_cast<std::uint32_t>(node);
  EXPECT_TRUE(model->add_node_force(index, force_n.cast<float>()).is_ok());
  for (int step = 0; step < steps; ++step) EXPECT_TRUE(model->step().is_ok());
  return model->displacement(index).cast<double>();
}

// K⁻¹ F at `node` for a force at `node`, from the full shell.
Eigen::Vector3d exact_static(const ModalBuildSpec& spec, const ModalBuildResult& result, int node,
                             const Eigen::Vector3d& force_n) {
  Eigen::VectorXd loads = make_zero_loads(spec.mesh);
  loads.segment<3>(static_cast<Eigen::Index>(node) * kShellDofsPerNode) = force_n;
  auto solver = ShellStaticSolver::create(result.shell);
  EXPECT_TRUE(solver.has_value());
  auto solution = solver->solve(loads);
  EXPECT_TRUE(solution.has_value());
  return solution->node_displacements.row(node).head<3>().transpose();
}

// Loaded nodes: one on the free end, one at mid-length on another side. The force is in no
// symmetry plane, so every direction of the local compliance is exercised.
constexpr int kFreeEndNode = (kRings - 1) * kSegments + 2;
constexpr int kMidLengthNode = (kRings / 2) * kSegments + 5;
const Eigen::Vector3d kForce(2.0e-4, -5.0e-4, -1.0e-3);  // N

TEST(ModalBuild, SucceedsWithSurfaceNodesIncreasingAndWithoutTheClampedRing) {
  const ModalBuildSpec spec = tube_spec(kStoredModes, true);
  const ModalBuildResult result = build(spec);
  ASSERT_EQ(result.basis.mode_count(), kStoredModes);
  EXPECT_EQ(result.shell.dofs.free_count(), 6 * (kRings - 1) * kSegments);
  for (int i = 0; i < kStoredModes; ++i) {
    EXPECT_GT(result.basis.omega_squared(i), 0.0);
    if (i > 0) {
      EXPECT_GE(result.basis.omega_squared(i), result.basis.omega_squared(i - 1));
    }
    EXPECT_GT(result.modal_damping(i), 0.0);
  }
  // ζ = 0.05 exactly at ω_1 and ω_r (Rayleigh fit).
  const double omega_1 = std::sqrt(result.basis.omega_squared(0));
  const double omega_r = std::sqrt(result.basis.omega_squared(kStoredModes - 1));
  EXPECT_NEAR(result.modal_damping(0) / (2.0 * omega_1), 0.05, 1e-12);
  EXPECT_NEAR(result.modal_damping(kStoredModes - 1) / (2.0 * omega_r), 0.05, 1e-12);

  const std::vector<int>& surface = result.surface_nodes;
  ASSERT_EQ(surface.size(), static_cast<std::size_t>((kRings - 1) * kSegments));
  for (std::size_t k = 1; k < surface.size(); ++k) EXPECT_LT(surface[k - 1], surface[k]);
  for (const int node : surface) EXPECT_GE(node, kClampedNodes) << "clamped node on the surface";
  EXPECT_EQ(surface.front(), kClampedNodes);
  EXPECT_EQ(surface.back(), kRings * kSegments - 1);

  ASSERT_TRUE(result.residual.has_value());
  EXPECT_EQ(result.residual->nodes, surface);
  EXPECT_EQ(result.residual->compliance.rows(), 3 * static_cast<Eigen::Index>(surface.size()));
  EXPECT_EQ(result.residual->compliance.cols(), result.residual->compliance.rows());

  // A named subset keeps only its own movable nodes, in order; "" means every movable node.
  ModalBuildSpec free_end_spec = tube_spec(kStoredModes, false);
  free_end_spec.surface_set = "free_end";
  const ModalBuildResult free_end = build(free_end_spec);
  std::vector<int> expected_free_end;
  for (int s = 0; s < kSegments; ++s) expected_free_end.push_back((kRings - 1) * kSegments + s);
  EXPECT_EQ(free_end.surface_nodes, expected_free_end);
  EXPECT_FALSE(free_end.residual.has_value());
  ModalBuildSpec default_spec = tube_spec(kStoredModes, false);
  default_spec.surface_set.clear();
  EXPECT_EQ(build(default_spec).surface_nodes, surface);
}

TEST(ModalBuild, ImageCarriesTheBuildToTheLoader) {
  const ModalBuildSpec spec = tube_spec(kStoredModes, true);
  const ModalBuildResult result = build(spec);
  const fs::path path = image_path("");
  ASSERT_TRUE(write_modal_image(spec, result, path));
  const LoadedImage loaded = load(path);
  fs::remove(path);
  ASSERT_FALSE(loaded.image.empty());

  const ImageMetadataV1& metadata = loaded.image.metadata();
  EXPECT_EQ(metadata.node_count, static_cast<std::uint32_t>(kRings * kSegments));
  EXPECT_EQ(metadata.mode_count, static_cast<std::uint32_t>(kStoredModes));
  EXPECT_EQ(metadata.surface_node_count, result.surface_nodes.size());
  EXPECT_EQ(metadata.static_correction, 1U);
  EXPECT_EQ(metadata.element_type, static_cast<std::uint32_t>(FiniteElementType::shell_dkt));
  EXPECT_EQ(metadata.source_mesh_hash, spec.mesh.source_hash);
  EXPECT_EQ(metadata.time_step_s, kTimeStep);
  EXPECT_EQ(metadata.damping_ratio, 0.05);
  EXPECT_EQ(metadata.young_modulus_pa, 3.0e5);
  EXPECT_EQ(metadata.error_estimate, 0.0) << "with static correction the static error is 0";

  ASSERT_EQ(loaded.data.omega_squared.size(), static_cast<std::size_t>(kStoredModes));
  for (int i = 0; i < kStoredModes; ++i) {
    EXPECT_EQ(loaded.data.omega_squared[static_cast<std::size_t>(i)],
              static_cast<float>(result.basis.omega_squared(i)));
    EXPECT_EQ(loaded.data.modal_damping[static_cast<std::size_t>(i)],
              static_cast<float>(result.modal_damping(i)));
  }
  ASSERT_EQ(loaded.data.mode_shapes.size(),
            static_cast<std::size_t>(3 * kRings * kSegments * kStoredModes));
  EXPECT_EQ(
      loaded.data.mode_shapes[static_cast<std::size_t>((3 * kFreeEndNode + 2) * kStoredModes + 3)],
      static_cast<float>(result.basis.node_shapes(3 * kFreeEndNode + 2, 3)));
  ASSERT_EQ(loaded.data.surface_nodes.size(), result.surface_nodes.size());
  for (std::size_t k = 0; k < result.surface_nodes.size(); ++k) {
    EXPECT_EQ(loaded.data.surface_nodes[k], static_cast<std::uint32_t>(result.surface_nodes[k]));
  }
  const std::size_t s3 = 3 * result.surface_nodes.size();
  ASSERT_EQ(loaded.data.residual_compliance.size(), s3 * s3);
  EXPECT_EQ(loaded.data.residual_compliance[s3 + 4],
            static_cast<float>(result.residual->compliance(1, 4)));
  // The clamped ring is recorded as fixed.
  ASSERT_EQ(loaded.image.rows(SectionId::fixed_nodes), static_cast<std::uint32_t>(kClampedNodes));
  EXPECT_EQ(loaded.image.u32s(SectionId::fixed_nodes).back(),
            static_cast<std::uint32_t>(kClampedNodes - 1));

  // Without static correction: no residual section, and the image states the static error.
  const ModalBuildSpec plain_spec = tube_spec(kStoredModes, false);
  const ModalBuildResult plain = build(plain_spec);
  const fs::path plain_path = image_path("_plain");
  ASSERT_TRUE(write_modal_image(plain_spec, plain, plain_path));
  const LoadedImage plain_loaded = load(plain_path);
  fs::remove(plain_path);
  EXPECT_FALSE(plain_loaded.image.has(SectionId::residual_compliance));
  EXPECT_EQ(plain_loaded.image.metadata().static_correction, 0U);
  EXPECT_EQ(plain_loaded.image.metadata().error_estimate, plain.truncation.max_local_relative);
  EXPECT_GT(plain.truncation.max_local_relative, 0.0);
}

// Runtime (from the loaded image) vs K⁻¹ F, for all stored modes active and for 5 of 20: the
// second case needs the static part of the 15 stored-but-inactive modes, which the runtime adds
// to the stored residual (a bug fixed in 66667a0 lost it).
TEST(ModalBuild, RuntimeFromTheImageSettlesOnTheExactStaticSolution) {
  const ModalBuildSpec spec = tube_spec(kStoredModes, true);
  const ModalBuildResult result = build(spec);
  const fs::path path = image_path("");
  ASSERT_TRUE(write_modal_image(spec, result, path));
  const LoadedImage loaded = load(path);
  fs::remove(path);
  ASSERT_FALSE(loaded.image.empty());

  for (const int node : {kFreeEndNode, kMidLengthNode}) {
    const Eigen::Vector3d exact = exact_static(spec, result, node, kForce);
    ASSERT_GT(exact.norm(), 0.0);
    for (const int active : {kStoredModes, 5}) {
      ModalSettings settings;
      settings.time_step_s = static_cast<float>(kTimeStep);
      settings.active_modes = static_cast<std::uint32_t>(active);
      const int steps = settling_steps(result, active);
      ASSERT_LT(steps, 200000) << "the tube should settle within minutes of simulated time";

      settings.static_correction = true;
      const Eigen::Vector3d corrected =
          settled_displacement(loaded.data, settings, node, kForce, steps);
      settings.static_correction = false;
      const Eigen::Vector3d uncorrected =
          settled_displacement(loaded.data, settings, node, kForce, steps);

      const double corrected_error = (corrected - exact).norm() / exact.norm();
      const double uncorrected_error = (uncorrected - exact).norm() / exact.norm();
      std::cout << "[measured] tube node " << node << ", " << active << " of " << kStoredModes
                << " modes, " << steps << " steps: |u - K^-1 F|/|K^-1 F| = " << corrected_error
                << " with static correction, " << uncorrected_error << " without\n";
      EXPECT_LT(corrected_error, 1e-3) << "node " << node << ", " << active << " modes";
      EXPECT_GT(uncorrected_error, 0.01) << "node " << node << ", " << active << " modes";
    }
  }
}

TEST(ModalBuild, AccuracyImprovesWithModesAndStaticCorrectionAndTheModelIsFaster) {
  const ModalBuildSpec spec = tube_spec(kStoredModes, true);
  const ModalBuildResult result = build(spec);
  AccuracyScenario scenario;
  scenario.name = "press the free end";
  scenario.load_point_m = Eigen::Vector3d(kLength, 0.0, kRadius);
  scenario.force_n = Eigen::Vector3d(0.0, 0.0, -1.0e-3);
  scenario.ramp_s = 0.02;
  scenario.duration_s = 0.3;
  const std::vector<int> mode_counts{2, 5, 10, 20};
  auto points = measure_modal_accuracy(spec, result, mode_counts, scenario);
  ASSERT_TRUE(points) << points.error().message;
  ASSERT_EQ(points->size(), 2 * mode_counts.size());

  double previous_without = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < mode_counts.size(); ++k) {
    const AccuracyPoint& without = (*points)[2 * k];
    const AccuracyPoint& with = (*points)[2 * k + 1];
    ASSERT_EQ(without.modes, mode_counts[k]);
    ASSERT_FALSE(without.static_correction);
    ASSERT_TRUE(with.static_correction);
    EXPECT_EQ(without.load_node, kFreeEndNode) << "the node at (L, 0, R)";
    std::cout << "[measured] accuracy r = " << without.modes << ": local error "
              << without.local_error << " without / " << with.local_error
              << " with static correction; final " << without.final_local_error << " / "
              << with.final_local_error << "; field " << without.field_error << " / "
              << with.field_error << "; modal " << with.modal_step_ns << " ns vs full "
              << with.reference_step_ns << " ns per step, speedup " << with.speedup << "\n";
    EXPECT_LT(without.local_error, previous_without) << without.modes << " modes";
    previous_without = without.local_error;
    EXPECT_LT(with.local_error, without.local_error) << with.modes << " modes";
    EXPECT_LT(with.final_local_error, without.final_local_error) << with.modes << " modes";
    EXPECT_GT(with.speedup, 1.0);
    EXPECT_GT(without.speedup, 1.0);
  }
}

// Largest displacement differences (relative to the largest reference displacement) over a
// load history of two pushes that wax and wane, for the float and the double runtime on one
// build, against a double reference (DNIOS or the offline modal integration).
struct PrecisionErrors {
  double float_vs_double = 0.0;
  double double_vs_reference = 0.0;
  double float_vs_reference = 0.0;
};

template <class Reference>
PrecisionErrors run_both_precisions(const ModalBuildSpec& spec, const ModalBuildResult& result,
                                    Reference& reference) {
  const FloatModalData float_data(spec, result);
  const DoubleModalData double_data(spec, result);
  auto arena = core::Arena::create(std::size_t{4} << 20);
  EXPECT_TRUE(arena.has_value());
  auto rounded = ModalModel::create(float_data.view(), *arena,
                                    ModalSettings{static_cast<float>(kTimeStep), 0, false});
  auto precise = ModalModelDouble::create(double_data.view(), *arena,
                                          ModalSettingsDouble{kTimeStep, 0, false});
  EXPECT_TRUE(rounded.has_value() && precise.has_value());
  PrecisionErrors errors;
  if (!rounded || !precise) return errors;
  double largest = 0.0;
  for (int step = 0; step < 400; ++step) {
    const double phase = 2.0 * std::numbers::pi * static_cast<double>(step) / 100.0;
    // Forces rounded to float first, so all three integrate the same load.
    const Eigen::Vector3d force_a = (std::sin(phase) * kForce).cast<float>().cast<double>();
    const Eigen::Vector3d force_b =
        (0.5 * std::cos(0.7 * phase) * kForce.reverse()).cast<float>().cast<double>();
    rounded->clear_forces();
    precise->clear_forces();
    reference.clear_forces();
    const std::pair<int, Eigen::Vector3d> loads[] = {{kFreeEndNode, force_a},
                                                     {kMidLengthNode, force_b}};
    for (const std::pair<int, Eigen::Vector3d>& load : loads) {
      const int node = load.first;
      const Eigen::Vector3d& force = load.second;
      const auto index = static_cast<std::uint32_t>(node);
      EXPECT_TRUE(rounded->add_node_force(index, force.cast<float>()).is_ok());
      EXPECT_TRUE(precise->add_node_force(index, force).is_ok());
      EXPECT_TRUE(reference.add_node_force(node, force).has_value());
    }
    EXPECT_TRUE(rounded->step().is_ok());
    EXPECT_TRUE(precise->step().is_ok());
    reference.step();
    for (int node = 0; node < kRings * kSegments; ++node) {
      const auto index = static_cast<std::uint32_t>(node);
      const Eigen::Vector3d expected = reference.displacement(node);
      const Eigen::Vector3d u_double = precise->displacement(index);
      const Eigen::Vector3d u_float = rounded->displacement(index).cast<double>();
      largest = std::max(largest, expected.cwiseAbs().maxCoeff());
      errors.float_vs_double =
          std::max(errors.float_vs_double, (u_float - u_double).cwiseAbs().maxCoeff());
      errors.double_vs_reference =
          std::max(errors.double_vs_reference, (u_double - expected).cwiseAbs().maxCoeff());
      errors.float_vs_reference =
          std::max(errors.float_vs_reference, (u_float - expected).cwiseAbs().maxCoeff());
    }
  }
  EXPECT_GT(largest, 0.0);
  errors.float_vs_double /= largest;
  errors.double_vs_reference /= largest;
  errors.float_vs_reference /= largest;
  return errors;
}

// DoubleModalData holds the build's values unrounded, FloatModalData the image's float32
// rounding of them; the two runtimes on them agree to float rounding (bound 1e-6 of the
// largest displacement), and the double one follows the double references — the offline modal
// integration of the same modes (bound 1e-12) and, with every mode, DNIOS (bound 1e-10) —
// more than 1000× closer than the float one, whose distance is its data rounding.
TEST(ModalBuild, TheSameBuildRunsInFloatAndInDouble) {
  const ModalBuildSpec spec = tube_spec(kStoredModes, true);
  const ModalBuildResult result = build(spec);
  const DoubleModalData double_data(spec, result);
  const FloatModalData float_data(spec, result);
  const auto precise_view = double_data.view();
  const auto rounded_view = float_data.view();
  ASSERT_EQ(precise_view.mode_shapes.size(), rounded_view.mode_shapes.size());
  for (int i = 0; i < kStoredModes; ++i) {
    const auto mode = static_cast<std::size_t>(i);
    EXPECT_EQ(precise_view.omega_squared[mode], result.basis.omega_squared(i));
    EXPECT_EQ(rounded_view.omega_squared[mode], static_cast<float>(result.basis.omega_squared(i)));
    EXPECT_EQ(precise_view.modal_damping[mode], result.modal_damping(i));
  }
  const auto shape_entry = static_cast<std::size_t>((3 * kFreeEndNode + 2) * kStoredModes + 3);
  EXPECT_EQ(precise_view.mode_shapes[shape_entry],
            result.basis.node_shapes(3 * kFreeEndNode + 2, 3));
  const std::size_t s3 = 3 * result.surface_nodes.size();
  ASSERT_EQ(precise_view.residual_compliance.size(), s3 * s3);
  EXPECT_EQ(precise_view.residual_compliance[s3 + 4], result.residual->compliance(1, 4));
  EXPECT_EQ(precise_view.rest_positions[3 * 7 + 1], spec.mesh.nodes(7, 1));
  EXPECT_EQ(precise_view.surface_nodes.size(), rounded_view.surface_nodes.size());

  // Against the offline modal integration of the same 20 modes (double, same data): what is
  // left is each runtime's arithmetic and data.
  auto modal = ModalNewmark::create(result.basis, result.modal_damping, kTimeStep);
  ASSERT_TRUE(modal.has_value()) << modal.error().message;
  const PrecisionErrors against_modal = run_both_precisions(spec, result, *modal);
  std::printf(
      "[measured] tube, 20 modes vs offline modal Newmark: |float - double| %.2e, |double - "
      "reference| %.2e, |float - reference| %.2e\n",
      against_modal.float_vs_double, against_modal.double_vs_reference,
      against_modal.float_vs_reference);
  // Measured 1.3e-7, 1.6e-14, 1.3e-7.
  EXPECT_LT(against_modal.float_vs_double, 1e-6);
  EXPECT_LT(against_modal.double_vs_reference, 1e-12);
  EXPECT_GT(against_modal.float_vs_reference, 1000.0 * against_modal.double_vs_reference);

  // Every mode (condensation) against DNIOS on the full shell: independent of the modal path.
  const ModalBuildSpec every_spec = tube_spec(kTranslationalDofs, false);
  const ModalBuildResult every = build(every_spec);
  auto full = FullNewmark::create(every.shell, every.rayleigh, kTimeStep);
  ASSERT_TRUE(full.has_value()) << full.error().message;
  const PrecisionErrors against_full = run_both_precisions(every_spec, every, *full);
  std::printf(
      "[measured] tube, every mode (%d) vs DNIOS: |float - double| %.2e, |double - "
      "reference| %.2e, |float - reference| %.2e\n",
      kTranslationalDofs, against_full.float_vs_double, against_full.double_vs_reference,
      against_full.float_vs_reference);
  // Measured 1.1e-7, 3.9e-13 (the eigensolution's and DNIOS's own rounding), 1.1e-7.
  EXPECT_LT(against_full.float_vs_double, 1e-6);
  EXPECT_LT(against_full.double_vs_reference, 1e-10);
  EXPECT_GT(against_full.float_vs_reference, 1000.0 * against_full.double_vs_reference);
}

TEST(ModalBuild, RefusesAnUnknownSurfaceSetAndTooManyModesForShiftInvert) {
  ModalBuildSpec unknown_set = tube_spec(kStoredModes, true);
  unknown_set.surface_set = "mucosa";
  auto refused = build_modal_model(unknown_set);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("model 'test_tube'"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("surface set 'mucosa'"), std::string::npos)
      << refused.error().message;

  // Lanczos cannot return every mode: r = translational dofs is refused with shift-invert,
  // and above that with any method.
  ModalBuildSpec all_modes = tube_spec(kTranslationalDofs, true);
  all_modes.method = ModalMethod::shift_invert;
  refused = build_modal_model(all_modes);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("shift_invert"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find(std::to_string(kTranslationalDofs)), std::string::npos)
      << refused.error().message;

  ModalBuildSpec too_many = tube_spec(kTranslationalDofs + 1, true);
  too_many.method = ModalMethod::shift_invert;
  refused = build_modal_model(too_many);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("translational"), std::string::npos)
      << refused.error().message;
  too_many.method.reset();
  EXPECT_FALSE(build_modal_model(too_many));

  // The same count with condensation (the automatic choice at r = translational dofs) works.
  ModalBuildSpec condensed = tube_spec(kTranslationalDofs, false);
  auto every_mode = build_modal_model(condensed);
  ASSERT_TRUE(every_mode) << every_mode.error().message;
  EXPECT_EQ(every_mode->basis.method, ModalMethod::condensation);
  EXPECT_EQ(every_mode->basis.mode_count(), kTranslationalDofs);
  EXPECT_LT(every_mode->truncation.max_local_relative, 1e-6) << "no mode left out";
}

}  // namespace
}  // namespace trainer::model::offline
