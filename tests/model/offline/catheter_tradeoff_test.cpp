// The particle catheter's trade study (catheter_tradeoff.hpp) on the cbd scene's catheter
// (config/models/catheter_cbd.toml's physical parameters) with shortened scenarios and a coarse
// reference (N_ref = 21 extrapolated with 11 and 6) so it runs in about a second: the double
// reference chain against the float runtime at the same N, the physics of the insertion (the
// grasp feels the frictionless wall's normal), errors that fall with N, costs, refusals by the
// substep budget, and the setup errors.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "trainer/model_offline/catheter_tradeoff.hpp"

namespace trainer::model::offline {
namespace {

// config/models/catheter_cbd.toml [catheter] (N = 11 needs 1 substep of its budget of 64).
CatheterStudySpec cbd_spec() {
  CatheterStudySpec spec;
  spec.params.length_m = 0.15F;
  spec.params.outer_radius_m = 0.00125F;
  spec.params.bending_stiffness_n_m2 = 3.9e-5F;
  spec.params.axial_stiffness_n = 157.0F;
  spec.params.linear_density_kg_per_m = 1.65e-3F;
  spec.params.damping_n_s_per_m = 5.0e-4F;
  spec.params.particle_count = 11;
  spec.max_substeps = 64;
  spec.reference_particle_count = 21;  // 11 on every other particle: extrapolation allowed
  return spec;
}

// The default scenarios, shortened: the push in 0.3 s, the cantilever's load in 0.2 s, 0.45 s
// each (the tip meets the wall at about 0.08 s). The sanitizer build, ~15x slower here, runs
// them in 0.2, 0.15 and 0.3 s.
std::vector<CatheterScenario> short_scenarios(double length_m) {
  std::vector<CatheterScenario> scenarios = default_catheter_scenarios(length_m);
  for (CatheterScenario& scenario : scenarios) {
#if defined(TRAINER_SANITIZER_BUILD)
    scenario.duration_s = 0.3;
    scenario.push_time_s = 0.2;
    scenario.load_time_s = 0.15;
#else
    scenario.duration_s = 0.45;
    scenario.push_time_s = 0.3;
    scenario.load_time_s = 0.2;
#endif
  }
  return scenarios;
}

CycleCostOptions catheter_quick_cost() {
#if defined(TRAINER_SANITIZER_BUILD)
  return {10, 2, 20};
#else
  return {50, 3, 100};
#endif
}

// A study whose only use is run(): the cheapest reference (N = 6, plain).
std::unique_ptr<CatheterTradeStudy> runner() {
  CatheterStudySpec spec = cbd_spec();
  spec.reference_particle_count = 6;
  spec.extrapolate_reference = false;
  auto created = CatheterTradeStudy::create(spec, short_scenarios(0.15));
  EXPECT_TRUE(created) << created.error().message;
  return created ? std::move(created).value() : nullptr;
}

TEST(CatheterTrade, ChainPointInterpolatesAlongTheChainAndClamps) {
  const std::vector<Eigen::Vector3f> chain{{0.0F, 0.0F, 0.0F}, {0.1F, 0.0F, 0.0F},
                                           {0.1F, 0.1F, 0.0F}};
  const std::span<const Eigen::Vector3f> view(chain);
  EXPECT_NEAR((chain_point_at(view, 0.1, 0.05) - Eigen::Vector3d(0.05, 0, 0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((chain_point_at(view, 0.1, 0.175) - Eigen::Vector3d(0.1, 0.075, 0)).norm(), 0.0,
              1e-8);
  EXPECT_NEAR((chain_point_at(view, 0.1, 0.2) - Eigen::Vector3d(0.1, 0.1, 0)).norm(), 0.0, 1e-8);
  EXPECT_NEAR((chain_point_at(view, 0.1, 0.5) - Eigen::Vector3d(0.1, 0.1, 0)).norm(), 0.0, 1e-8);
  EXPECT_NEAR(chain_point_at(view, 0.1, -1.0).norm(), 0.0, 1e-12);
}

// The double reference chain reimplements Catheter::step; at the same N it must follow the float
// runtime to float rounding (positions) and to the runtime's rounding chatter (forces).
TEST(CatheterTrade, ReferenceChainFollowsTheRuntimeCatheterAtTheSameN) {
  const std::unique_ptr<CatheterTradeStudy> study = runner();
  ASSERT_TRUE(study);
  const CatheterScenario& insertion = study->scenarios().front();
  ASSERT_EQ(insertion.kind, CatheterScenarioKind::insertion);
  auto runtime = study->run(insertion, 11, RuntimePrecision::float32);
  auto reference = study->run(insertion, 11, RuntimePrecision::float64);
  ASSERT_TRUE(runtime) << runtime.error().message;
  ASSERT_TRUE(reference) << reference.error().message;
  ASSERT_EQ(runtime->stations_m.size(), reference->stations_m.size());
  double position_difference_m = 0.0;
  double force_peak_n = 0.0;
  double force_difference_n = 0.0;
  for (std::size_t k = 0; k < runtime->stations_m.size(); ++k) {
    for (std::size_t j = 0; j < 4; ++j) {
      position_difference_m = std::max(
          position_difference_m, (runtime->stations_m[k][j] - reference->stations_m[k][j]).norm());
    }
    force_peak_n = std::max(force_peak_n, reference->grasp_force_n[k].norm());
    force_difference_n = std::max(
        force_difference_n, (runtime->grasp_force_n[k] - reference->grasp_force_n[k]).norm());
  }
  EXPECT_LT(position_difference_m, 1e-5 * 0.15);  // float rounding of 0.15 m positions, grown
  ASSERT_GT(force_peak_n, 1e-3);                  // the tip did meet the wall
  EXPECT_LT(force_difference_n, 0.05 * force_peak_n);
  // And a different N is visibly different (the comparison above is not vacuous).
  auto coarse = study->run(insertion, 6, RuntimePrecision::float64);
  ASSERT_TRUE(coarse) << coarse.error().message;
  EXPECT_GT((coarse->grasp_force_n.back() - reference->grasp_force_n.back()).norm(),
            0.2 * force_peak_n);
}

// Pressed against a frictionless wall and come to rest, the catheter is pushed by the wall along
// its normal only: what the grasp feels is along the wall normal n = (−sin α, cos α, 0).
TEST(CatheterTrade, GraspFeelsTheWallNormalOnceSettled) {
  const std::unique_ptr<CatheterTradeStudy> study = runner();
  ASSERT_TRUE(study);
  for (const CatheterScenario& scenario : study->scenarios()) {
    if (scenario.kind != CatheterScenarioKind::insertion) continue;
    auto history = study->run(scenario, 11, RuntimePrecision::float64);
    ASSERT_TRUE(history) << history.error().message;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t k = history->grasp_force_n.size() - 50; k < history->grasp_force_n.size(); ++k) {
      mean += history->grasp_force_n[k] / 50.0;
    }
    const double angle = scenario.wall_angle_deg * M_PI / 180.0;
    const Eigen::Vector3d normal(-std::sin(angle), std::cos(angle), 0.0);
    ASSERT_GT(mean.norm(), 1e-3) << scenario.name;
    EXPECT_GT(mean.normalized().dot(normal), std::cos(5.0 * M_PI / 180.0)) << scenario.name;
    EXPECT_NEAR(history->grasp_arc_length_m, 0.8 * 0.15, 1e-7);  // L = 0.15F
  }
}

// One study (N_ref = 21 extrapolated with 11) and four measurements: N = 6 and 11 within the
// budget, 21 refused, and 21 measured beyond it. One test, because ctest runs every test case
// in a process of its own and the study is the expensive part.
TEST(CatheterTrade, ErrorsFallWithTheParticleCountCostsGrowAndTheBudgetRefuses) {
  // A budget of 3 substeps: N = 11 needs 1 (the largest substep of the linearly implicit chain,
  // set by the bending's remainder: 1248 µs), N = 21 needs 4 (312 µs) and is refused.
  CatheterStudySpec spec = cbd_spec();
  spec.max_substeps = 3;
  auto created = CatheterTradeStudy::create(spec, short_scenarios(0.15));
  ASSERT_TRUE(created) << created.error().message;
  const CatheterTradeStudy& study = **created;
  const auto measure = [&](std::uint32_t n, bool beyond) {
    auto point = study.measure({n}, catheter_quick_cost(), beyond);
    EXPECT_TRUE(point) << point.error().message;
    return point ? std::move(point).value() : CatheterTradePoint{};
  };
  const CatheterTradePoint coarse_point = measure(6, false);
  const CatheterTradePoint fine_point = measure(11, false);
  const CatheterTradePoint refused_point = measure(21, false);
  const CatheterTradePoint beyond_point = measure(21, true);
  const CatheterTradePoint* coarse = &coarse_point;
  const CatheterTradePoint* fine = &fine_point;
  ASSERT_TRUE(coarse->measured && fine->measured);
  EXPECT_FALSE(coarse->refused || fine->refused);
  ASSERT_EQ(coarse->errors.size(), study.scenarios().size());
  for (std::size_t s = 0; s < coarse->errors.size(); ++s) {
    const CatheterScenarioError& a = coarse->errors[s];
    const CatheterScenarioError& b = fine->errors[s];
    EXPECT_GT(a.shape_error, b.shape_error) << a.scenario;
    if (a.kind == CatheterScenarioKind::insertion) {
      EXPECT_GT(a.force_error, 1.2 * b.force_error) << a.scenario;
      EXPECT_GT(a.reference_peak_force_n, 1e-3) << a.scenario;
    } else {
      EXPECT_EQ(a.force_error, 0.0);
      EXPECT_GT(a.reference_peak_tip_travel_m, 0.2 * 0.15);  // a large deflection
    }
    EXPECT_EQ(a.error, std::max(a.force_error, a.shape_error));
  }
  EXPECT_GT(coarse->worst_error, fine->worst_error);
  EXPECT_GT(fine->tuning_error, 0.0);
  EXPECT_GT(fine->validation_error, 0.0);
  // N = 11 runs 1 substep of 11 particles, N = 6 one of 6.
  EXPECT_EQ(fine->substeps_per_period, 1U);
  EXPECT_EQ(coarse->substeps_per_period, 1U);
  for (const CatheterTradePoint* point : {coarse, fine}) {
    EXPECT_GT(point->cost.median_ns, 0.0);
    EXPECT_GE(point->cost.p99_ns, point->cost.median_ns);
    EXPECT_GT(point->cost.haptic_median_ns, 0.0);
    EXPECT_LE(point->cost.haptic_median_ns, point->cost.median_ns);
    EXPECT_LE(point->cost.repetition_median_min_ns, point->cost.repetition_median_max_ns);
    EXPECT_EQ(point->cost.repetitions, catheter_quick_cost().repetitions);
    EXPECT_GT(point->state_bytes, 0U);
  }
  EXPECT_GT(fine->cost.haptic_median_ns, coarse->cost.haptic_median_ns);
  // b scaled to keep b/m: the definition's N = 11 keeps the definition's b.
  EXPECT_NEAR(fine->damping_n_s_per_m, 5.0e-4, 1e-9);
  EXPECT_NEAR(coarse->damping_n_s_per_m, 5.0e-4 * 11.0 / 6.0, 1e-9);

  // Over the budget: refused with Catheter::create's message, not measured, not an error.
  const CatheterTradePoint* refused = &refused_point;
  EXPECT_TRUE(refused->refused);
  EXPECT_FALSE(refused->measured);
  EXPECT_GT(refused->substeps_per_period, 3U);
  EXPECT_NE(refused->refusal.find("max_substeps = 3"), std::string::npos) << refused->refusal;
  EXPECT_TRUE(refused->errors.empty());
  EXPECT_EQ(refused->cost.median_ns, 0.0);

  // Beyond the budget on request: measured, and nearer the reference than N = 11.
  const CatheterTradePoint* beyond = &beyond_point;
  const CatheterTradePoint* within = fine;
  EXPECT_TRUE(beyond->refused);
  EXPECT_TRUE(beyond->measured);
  EXPECT_LT(beyond->worst_error, within->worst_error);
  EXPECT_GT(beyond->cost.haptic_median_ns, within->cost.haptic_median_ns);

  // The observed orders: the grasp hinges make the grasp force converge at second order (1.6–1.7
  // from these coarse N = 6, 11, 21 and short runs, 1.96 from 21, 41, 81 with the full ones;
  // without the hinges the differences halved at most, an order of 1 or less).
  ASSERT_EQ(study.reference_orders().size(), study.scenarios().size());
  for (std::size_t s = 0; s < study.scenarios().size(); ++s) {
    const auto& order = study.reference_orders()[s];
    std::printf("%s: observed order shape %.3f, grasp force %.3f\n",
                study.scenarios()[s].name.c_str(), order.shape, order.force);
    EXPECT_GE(order.shape, 1.0);
    EXPECT_LE(order.shape, 2.0);
    if (study.scenarios()[s].kind == CatheterScenarioKind::insertion) {
      EXPECT_GT(order.force, 1.4) << study.scenarios()[s].name;
    } else {
      EXPECT_EQ(order.force, 0.0);
    }
  }

  // The plain N_ref run against the extrapolated reference is its first-order error, the same
  // as N_ref against N_ref/2, so it is non-zero and below the error of N_ref/2 = 11 itself.
  ASSERT_EQ(study.reference_check().size(), study.scenarios().size());
  const CatheterTradePoint* half = fine;
  for (std::size_t s = 0; s < half->errors.size(); ++s) {
    EXPECT_GT(study.reference_check()[s].error, 0.0);
    EXPECT_LT(study.reference_check()[s].error, half->errors[s].error);
  }
}

TEST(CatheterTrade, SetupErrorsNameTheProblem) {
  const auto expect_error = [](CatheterStudySpec spec, std::vector<CatheterScenario> scenarios,
                               const std::string& fragment) {
    auto study = CatheterTradeStudy::create(spec, std::move(scenarios));
    ASSERT_FALSE(study) << fragment;
    EXPECT_NE(study.error().message.find(fragment), std::string::npos) << study.error().message;
  };
  std::vector<CatheterScenario> one{short_scenarios(0.15).front()};
  one.front().duration_s = 0.0105;  // 10.5 periods: a 2-period scenario is too short to matter
  expect_error(cbd_spec(), one, "whole number");
  one.front().duration_s = 0.01;
  one.front().grasp_arc_length_m = 0.2;
  expect_error(cbd_spec(), one, "grasp arc length");
  one.front().grasp_arc_length_m = 0.149;  // inside, but the tip particle would be held
  expect_error(cbd_spec(), one, "a held segment and a free tip");
  one.front().grasp_arc_length_m = 0.12;
  one.front().wall_angle_deg = 0.0;
  expect_error(cbd_spec(), one, "wall angle");
  one.front().wall_angle_deg = 45.0;
  CatheterStudySpec even = cbd_spec();
  even.reference_particle_count = 20;
  expect_error(even, one, "N_ref = 4k + 1");
  CatheterStudySpec broken = cbd_spec();
  broken.params.axial_stiffness_n = 0.0F;
  expect_error(broken, one, "axial_stiffness_n");
  expect_error(cbd_spec(), {}, "no scenarios");
  // A grasp at 0.75 L is particle 15 of N_ref = 21 but lies between particles 7 and 8 of
  // N = 11: the two runs of the extrapolation would hold different points.
  one.front().grasp_arc_length_m = 0.75 * 0.15;
  expect_error(cbd_spec(), one, "extrapolation needs a grasp");

  CatheterStudySpec plain = cbd_spec();
  plain.extrapolate_reference = false;
  auto study = CatheterTradeStudy::create(plain, one);
  ASSERT_TRUE(study) << study.error().message;
  EXPECT_TRUE((*study)->reference_check().empty());
  auto too_few = (*study)->measure({2}, catheter_quick_cost());
  ASSERT_FALSE(too_few);
  EXPECT_NE(too_few.error().message.find("particle_count"), std::string::npos);
  auto bad_cost = (*study)->measure({6}, CycleCostOptions{0, 0, 10});
  ASSERT_FALSE(bad_cost);
  EXPECT_NE(bad_cost.error().message.find("repetitions"), std::string::npos);
}

}  // namespace
}  // namespace trainer::model::offline
