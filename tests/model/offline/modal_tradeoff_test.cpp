// The duct's speed/accuracy trade study (modal_tradeoff.hpp) on a small clamped tube: the DNIOS
// reference step with an imposed displacement, the error measure against it, the budget
// choice, and the budget recorded in the image.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model_offline/dnios.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/modal_build.hpp"
#include "trainer/model_offline/modal_tradeoff.hpp"

namespace trainer::model::offline {
namespace {

namespace fs = std::filesystem;

ModalBuildSpec small_tube() {
  auto mesh = make_tube(0.0043, 0.0244, 7, 8);
  EXPECT_TRUE(mesh.has_value());
  ModalBuildSpec spec;
  spec.name = "tradeoff_tube";
  spec.mesh = std::move(mesh).value();
  spec.material = ShellMaterial{3.0e5, 0.45, 1.0e-3, 1000.0};
  spec.bending = BendingElement::dkt;
  spec.fixes = {{"clamped", {0, 1, 2, 3, 4, 5}}};
  spec.mode_count = 20;
  spec.damping_ratio = 0.05;
  spec.time_step_s = 1e-3;
  spec.static_correction = true;
  spec.surface_set = "all";
  return spec;
}

CycleCostOptions modal_quick_cost() {
  CycleCostOptions options;
  options.warmup_cycles = 50;
  options.repetitions = 2;
  options.cycles_per_repetition = 100;
  return options;
}

TEST(DniosImposed, ReachesTheTargetAndHoldsItWithTheStaticForce) {
  const ModalBuildSpec spec = small_tube();
  auto built = build_modal_model(spec);
  ASSERT_TRUE(built.has_value()) << built.error().message;
  auto dnios = FullNewmark::create(built->shell, built->rayleigh, 2.5e-4);
  ASSERT_TRUE(dnios.has_value());
  const int node = built->surface_nodes.back();  // on the free end ring
  const Eigen::Vector3d target(0.0, 0.0, -2e-4);
  Eigen::Vector3d before_previous = Eigen::Vector3d::Zero();
  Eigen::Vector3d previous = Eigen::Vector3d::Zero();
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  for (int step = 0; step < 4000; ++step) {  // 1 s: the damped transient dies out
    before_previous = previous;
    previous = force;
    auto imposed = dnios->step_imposed(node, target);
    ASSERT_TRUE(imposed.has_value()) << imposed.error().message;
    force = *imposed;
    ASSERT_LT((dnios->displacement(node) - target).norm(), 1e-12);
  }
  // The imposed jump leaves Newmark's undamped alternation on the held node, growing linearly
  // ((−1)^n (A + B n), see smooth_nyquist in modal_tradeoff.cpp); the centred [1 2 1]/4 average
  // removes it exactly and leaves the static force: K u = E f, positive work.
  const Eigen::Vector3d alternating = force - previous;
  const Eigen::Vector3d mean = 0.25 * (before_previous + 2.0 * previous + force);
  EXPECT_GT(alternating.norm(), 1e3 * mean.norm()) << "the raw force rings";
  const Eigen::VectorXd internal = built->shell.stiffness * dnios->free_displacement();
  const auto& free_index = built->shell.dofs.free_index;
  Eigen::Vector3d stiffness_force;
  for (int axis = 0; axis < 3; ++axis) {
    stiffness_force[axis] = internal[free_index[static_cast<std::size_t>(node * 6 + axis)]];
  }
  EXPECT_LT((mean - stiffness_force).norm(), 1e-3 * stiffness_force.norm());
  EXPECT_GT(mean.dot(target), 0.0);

  EXPECT_FALSE(dnios->step_imposed(0, target).has_value()) << "node 0 is clamped";
  EXPECT_FALSE(dnios->step_imposed(node, Eigen::Vector3d(NAN, 0, 0)).has_value());
}

TEST(DuctTradeStudy, ErrorsFollowTheKnobs) {
  auto study = DuctTradeStudy::create(small_tube(), default_duct_scenarios(small_tube().mesh), 2.5e-4);
  ASSERT_TRUE(study.has_value()) << study.error().message;
  ASSERT_EQ((*study)->scenarios().size(), 5U);
  const auto measure = [&](int modes, bool correction, double step_s) {
    ModalTradeConfig config;
    config.modes = modes;
    config.static_correction = correction;
    config.time_step_s = step_s;
    auto point = (*study)->measure(config, modal_quick_cost());
    if (!point) {
      ADD_FAILURE() << point.error().message;
      return ModalTradePoint{};
    }
    return std::move(point).value();
  };
  const ModalTradePoint uncorrected = measure(10, false, 1e-3);
  const ModalTradePoint corrected = measure(10, true, 1e-3);
  const ModalTradePoint fine_step = measure(10, true, 2.5e-4);
  const ModalTradePoint coarse_step = measure(10, true, 2e-3);
  ModalTradeConfig double_config;
  double_config.modes = 10;
  double_config.precision = RuntimePrecision::float64;
  auto in_double = (*study)->measure(double_config, modal_quick_cost());
  ASSERT_TRUE(in_double.has_value()) << in_double.error().message;
  // Same build, same algorithm: float32 storage changes the force by rounding only.
  EXPECT_NEAR(in_double->worst_error, corrected.worst_error, 1e-3 * corrected.worst_error);
  EXPECT_EQ(in_double->data_bytes, 2 * corrected.data_bytes);
  for (const ModalTradePoint* point : {&uncorrected, &corrected, &fine_step, &coarse_step}) {
    ASSERT_EQ(point->errors.size(), 5U);
    EXPECT_GT(point->cost.median_ns, 0.0);
    EXPECT_GE(point->cost.p99_ns, point->cost.median_ns);
    EXPECT_GE(point->cost.median_ns, point->cost.haptic_median_ns);
    for (const ScenarioError& error : point->errors) {
      EXPECT_TRUE(std::isfinite(error.rms_error) && std::isfinite(error.peak_error));
      EXPECT_GT(error.reference_peak_force_n, 0.0);
    }
  }
  // Displacement-driven contact through 10 modes alone is far too stiff; the residual
  // compliance restores the static response.
  EXPECT_GT(uncorrected.worst_error, 10.0 * corrected.worst_error);
  // A finer step follows the reference's transients better; the coarse one worse.
  EXPECT_LT(fine_step.worst_error, corrected.worst_error);
  EXPECT_GT(coarse_step.worst_error, corrected.worst_error);
  EXPECT_LT(fine_step.worst_error, 0.05);

  // A step that is not a multiple of the reference's is refused.
  ModalTradeConfig odd;
  odd.time_step_s = 3.3e-4;
  EXPECT_FALSE((*study)->measure(odd, modal_quick_cost()).has_value());
}

TEST(DuctTradeStudy, BudgetPicksTheCheapestThatMeetsItAndRecordsIt) {
  auto study = DuctTradeStudy::create(small_tube(), default_duct_scenarios(small_tube().mesh), 2.5e-4);
  ASSERT_TRUE(study.has_value()) << study.error().message;
  std::vector<ModalTradeConfig> candidates;
  for (int modes : {5, 10, 20}) {
    for (bool correction : {false, true}) {
      ModalTradeConfig config;
      config.modes = modes;
      config.static_correction = correction;
      candidates.push_back(config);
    }
  }
  const double budget = 0.15;
  auto choice = choose_for_budget(**study, budget, candidates, modal_quick_cost());
  ASSERT_TRUE(choice.has_value()) << choice.error().message;
  EXPECT_LE(choice->chosen.tuning_error, budget);
  EXPECT_LE(choice->chosen.validation_error, budget);
  ASSERT_EQ(choice->candidates.size(), candidates.size());
  // Nothing clearly cheaper met the budget on both sets.
  for (const ModalTradePoint& point : choice->candidates) {
    if (selection_cost_ns(point) < selection_cost_ns(choice->chosen) / 1.05) {
      EXPECT_TRUE(point.tuning_error > budget || point.validation_error > budget)
          << point.config.label() << " is cheaper and meets the budget";
    }
  }
  // An unreachable budget is refused, naming the most accurate configuration.
  auto impossible = select_for_budget(choice->candidates, 1e-9, nullptr);
  ASSERT_FALSE(impossible.has_value());
  EXPECT_NE(impossible.error().message.find("no configuration meets the error budget"),
            std::string::npos);

  // The image records the budget and the measured error.
  ModalBuildSpec spec = (*study)->spec_for(choice->chosen.config);
  auto built = build_modal_model(spec);
  ASSERT_TRUE(built.has_value());
  const fs::path path =
      fs::temp_directory_path() / ("trainer_tradeoff_" + std::to_string(getpid()) + ".img");
  ASSERT_TRUE(write_modal_image(spec, *built, path,
                                ErrorBudgetRecord{budget, choice->chosen.worst_error})
                  .has_value());
  auto arena = core::Arena::create(std::size_t{4} << 20);
  ASSERT_TRUE(arena.has_value());
  auto image = load_model_image(path, *arena, ImageLimits{}, ModelKind::modal_shell);
  fs::remove(path);
  ASSERT_TRUE(image.has_value()) << image.error().message;
  EXPECT_DOUBLE_EQ(image->metadata().error_budget, budget);
  EXPECT_DOUBLE_EQ(image->metadata().error_estimate, choice->chosen.worst_error);
  EXPECT_EQ(image->metadata().mode_count, static_cast<std::uint32_t>(choice->chosen.config.modes));
}

}  // namespace
}  // namespace trainer::model::offline
