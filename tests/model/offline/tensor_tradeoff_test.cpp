// Cotin's tensor model's trade study (tensor_tradeoff.hpp) on a small block clamped on its base
// (80 × 60 × 30 mm, 10 mm spacing, 252 nodes: the liver block's material, a mesh that builds in
// milliseconds): the default probes, the contact sets (pulling nodes released), the force error
// falling to float rounding once the cap holds the contact set, the quasi-non-linear force rule
// in the reference, costs growing with the cap, and the setup errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "trainer/model_offline/tensor_tradeoff.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model::offline {
namespace {

TensorStudySpec block_spec() {
  TensorStudySpec spec;
  auto mesh = make_tet_box(0.08, 0.06, 0.03, 8, 6, 3);
  EXPECT_TRUE(mesh) << mesh.error().message;
  spec.mesh = std::move(mesh).value();
  spec.material = {1.5e4, 0.45, 1060.0};  // config/models/liver.toml
  spec.fixes = {{spec.mesh.node_sets.at("z0"), {true, true, true}}};
  spec.contacts_per_block = 64;
  return spec;
}

// The block's contact nodes: its boundary minus the clamped base.
std::vector<int> free_boundary(const TetMesh& mesh) {
  std::vector<int> nodes;
  for (Eigen::Index n = 0; n < mesh.nodes.rows(); ++n) {
    const Eigen::Vector3d x = mesh.nodes.row(n).transpose();
    const bool boundary = x.x() < 1e-9 || x.x() > 0.08 - 1e-9 || x.y() < 1e-9 ||
                          x.y() > 0.06 - 1e-9 || x.z() > 0.03 - 1e-9;
    if (boundary && x.z() > 1e-9) nodes.push_back(static_cast<int>(n));
  }
  return nodes;
}

std::vector<TensorProbeScenario> block_scenarios(const TetMesh& mesh) {
  auto scenarios = default_tensor_scenarios(mesh, free_boundary(mesh));
  EXPECT_TRUE(scenarios) << scenarios.error().message;
  return std::move(scenarios).value();
}

CycleCostOptions tensor_quick_cost() {
#if defined(TRAINER_SANITIZER_BUILD)
  return {20, 2, 50};
#else
  return {200, 3, 500};
#endif
}

class TensorTradeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    TensorStudySpec spec = block_spec();
    auto scenarios = block_scenarios(spec.mesh);
    auto created = TensorTradeStudy::create(std::move(spec), std::move(scenarios));
    ASSERT_TRUE(created) << created.error().message;
    study_ = std::move(created).value().release();
  }
  static void TearDownTestSuite() {
    delete study_;
    study_ = nullptr;
  }
  static TensorTradeStudy* study_;
};
TensorTradeStudy* TensorTradeTest::study_ = nullptr;

TEST_F(TensorTradeTest, DefaultProbesScaleWithTheNodeSpacing) {
  const std::vector<TensorProbeScenario>& scenarios = study_->scenarios();
  ASSERT_EQ(scenarios.size(), 5U);
  EXPECT_NEAR(scenarios[0].radius_m, 0.55 * 0.01, 1e-9);  // spacing 10 mm on the top face
  EXPECT_NEAR(scenarios[1].radius_m, 1.6 * 0.01, 1e-9);
  EXPECT_NEAR(scenarios[3].radius_m, 2.7 * 0.01, 1e-9);
  EXPECT_EQ(std::count_if(scenarios.begin(), scenarios.end(),
                          [](const TensorProbeScenario& s) { return s.tuning; }),
            2);
  // The small probe over a node covers that node only; the others cover several.
  for (const TensorTradeStudy::Press& press : study_->presses()[0]) {
    EXPECT_EQ(press.nodes.size(), 1U);
  }
  EXPECT_GE(study_->largest_contact_set(), 5U);
  EXPECT_EQ(study_->contact_nodes().size(), free_boundary(study_->spec().mesh).size());
}

TEST_F(TensorTradeTest, ContactSetsPushAndDeeperPressesTakeMoreForce) {
  for (std::size_t s = 0; s < study_->scenarios().size(); ++s) {
    const TensorProbeScenario& scenario = study_->scenarios()[s];
    double previous_push_n = 0.0;
    for (const TensorTradeStudy::Press& press : study_->presses()[s]) {
      ASSERT_FALSE(press.contact_set.empty());
      EXPECT_LE(press.contact_set.size(), press.nodes.size());
      EXPECT_TRUE(std::is_sorted(press.contact_set.begin(), press.contact_set.end()))
          << "deepest first";
      // The force on the tissue points into it, along the push.
      const double push_n = press.reference_force_n.dot(scenario.inward);
      EXPECT_GT(push_n, 0.8 * press.reference_force_n.norm()) << scenario.name;
      EXPECT_GT(push_n, previous_push_n) << scenario.name << " at " << press.depth_m;
      previous_push_n = push_n;
      // Each covered node sits on the sphere after its displacement.
      for (std::size_t i = 0; i < press.nodes.size(); ++i) {
        const Eigen::Vector3d moved =
            study_->spec().mesh.nodes.row(press.nodes[i]).transpose() + press.displacements_m[i];
        EXPECT_NEAR((moved - press.centre_m).norm(), scenario.radius_m, 1e-12);
      }
    }
  }
}

TEST_F(TensorTradeTest, ErrorFallsToFloatRoundingOnceTheCapHoldsTheContactSet) {
  const auto largest = static_cast<std::uint32_t>(study_->largest_contact_set());
  auto one = study_->measure({1}, tensor_quick_cost());
  auto three = study_->measure({3}, tensor_quick_cost());
  auto all = study_->measure({largest}, tensor_quick_cost());
  ASSERT_TRUE(one) << one.error().message;
  ASSERT_TRUE(three) << three.error().message;
  ASSERT_TRUE(all) << all.error().message;
  for (std::size_t s = 0; s < all->errors.size(); ++s) {
    // Float32 tensors against the double direct solve (docs/tensor-model.md: < 2e-5).
    EXPECT_LT(all->errors[s].force_error, 1e-5) << all->errors[s].scenario;
    EXPECT_EQ(all->errors[s].imposed_nodes, all->errors[s].contact_nodes);
    if (all->errors[s].contact_nodes > 1) {
      EXPECT_GT(one->errors[s].force_error, 0.05) << one->errors[s].scenario;
      EXPECT_GT(one->errors[s].force_error, three->errors[s].force_error)
          << one->errors[s].scenario;
      EXPECT_LE(one->errors[s].imposed_nodes, 1);
    } else {
      EXPECT_LT(one->errors[s].force_error, 1e-5) << one->errors[s].scenario;
    }
  }
  EXPECT_GT(one->worst_error, three->worst_error);
  EXPECT_GT(three->worst_error, all->worst_error);
  EXPECT_LT(all->worst_error, 1e-5);
  EXPECT_GT(one->tuning_error, 0.05);
  EXPECT_GT(one->validation_error, 0.05);
  // Costs: the solve is O(m³), the field O(m·q); the state holds (3m)² doubles.
  for (const TensorTradePoint* point : {&*one, &*three, &*all}) {
    EXPECT_GT(point->cost.haptic_median_ns, 0.0);
    EXPECT_LE(point->cost.haptic_median_ns, point->cost.median_ns);
    EXPECT_GE(point->cost.p99_ns, point->cost.median_ns);
    EXPECT_LE(point->cost.repetition_median_min_ns, point->cost.repetition_median_max_ns);
  }
  EXPECT_LT(one->state_bytes, all->state_bytes);
  auto sixteen = study_->measure({16}, tensor_quick_cost());
  ASSERT_TRUE(sixteen) << sixteen.error().message;
  EXPECT_GT(sixteen->cost.haptic_median_ns, 4.0 * one->cost.haptic_median_ns);
  EXPECT_GT(sixteen->cost.median_ns, one->cost.median_ns);
  EXPECT_LT(sixteen->worst_error, 1e-5);  // the cap above every contact set changes nothing
}

// Holding every covered node glues the tissue to the probe: the nodes the release drops pull,
// so the glued press pushes less.
TEST_F(TensorTradeTest, GluingEveryCoveredNodeTakesLessForceThanReleasingThePullingOnes) {
  TensorStudySpec spec = block_spec();
  spec.release_pulling_nodes = false;
  auto glued = TensorTradeStudy::create(std::move(spec), study_->scenarios());
  ASSERT_TRUE(glued) << glued.error().message;
  int released_presses = 0;
  for (std::size_t s = 0; s < study_->scenarios().size(); ++s) {
    const Eigen::Vector3d inward = study_->scenarios()[s].inward;
    for (std::size_t d = 0; d < study_->presses()[s].size(); ++d) {
      const TensorTradeStudy::Press& free = study_->presses()[s][d];
      const TensorTradeStudy::Press& stuck = (*glued)->presses()[s][d];
      EXPECT_EQ(stuck.contact_set.size(), stuck.nodes.size());
      if (free.contact_set.size() == free.nodes.size()) {
        EXPECT_NEAR((free.reference_force_n - stuck.reference_force_n).norm(), 0.0,
                    1e-9 * free.reference_force_n.norm());
        continue;
      }
      ++released_presses;
      EXPECT_GT(free.reference_force_n.dot(inward), stuck.reference_force_n.dot(inward))
          << study_->scenarios()[s].name << " at " << free.depth_m;
    }
  }
  EXPECT_GT(released_presses, 0);
}

// The reference applies the runtime's quasi-non-linear force rule to its total: along the push
// P(a) = a + 0.5 a² + 0.1 a³ (liver.toml), so the cap that holds the contact set still agrees to
// float rounding, and the mapped push is P of the linear one.
TEST_F(TensorTradeTest, QuasiNonLinearForceMapFollowsTheRuntimeRule) {
  TensorStudySpec spec = block_spec();
  const std::vector<double> coefficients{0.0, 1.0, 0.5, 0.1};
  auto map = AmplitudeMap::create(coefficients, 5.0, "force_colinear");
  ASSERT_TRUE(map) << map.error().message;
  spec.nonlinear.force_colinear = *map;
  auto mapped = TensorTradeStudy::create(std::move(spec), study_->scenarios());
  ASSERT_TRUE(mapped) << mapped.error().message;
  int compared = 0;
  for (std::size_t s = 0; s < study_->scenarios().size(); ++s) {
    for (std::size_t d = 0; d < study_->presses()[s].size(); ++d) {
      const TensorTradeStudy::Press& linear = study_->presses()[s][d];
      const TensorTradeStudy::Press& nonlinear = (*mapped)->presses()[s][d];
      Eigen::Vector3d push = Eigen::Vector3d::Zero();
      for (const std::size_t i : nonlinear.contact_set) push += nonlinear.displacements_m[i];
      const Eigen::Vector3d direction = push.normalized();
      const double a = linear.reference_force_n.dot(direction);
      // The mapped forces decide which nodes pull, so the sets can differ; beyond 5 N the map
      // goes on linearly.
      if (linear.contact_set != nonlinear.contact_set || a > 5.0) continue;
      ++compared;
      const double expected = a + 0.5 * a * a + 0.1 * a * a * a;
      EXPECT_NEAR(nonlinear.reference_force_n.dot(direction), expected, 1e-6 * expected)
          << study_->scenarios()[s].name << " at " << linear.depth_m;
    }
  }
  EXPECT_GE(compared, 7);  // of 11 presses
  auto all = (*mapped)->measure({static_cast<std::uint32_t>((*mapped)->largest_contact_set())},
                                tensor_quick_cost());
  ASSERT_TRUE(all) << all.error().message;
  EXPECT_LT(all->worst_error, 1e-5);
  auto one = (*mapped)->measure({1}, tensor_quick_cost());
  ASSERT_TRUE(one) << one.error().message;
  EXPECT_GT(one->worst_error, 0.05);
}

TEST(TensorTrade, SetupErrorsNameTheProblem) {
  const TensorStudySpec spec = block_spec();
  const std::vector<TensorProbeScenario> good = block_scenarios(spec.mesh);
  const auto expect_error = [&](std::vector<TensorProbeScenario> scenarios, TensorStudySpec s,
                                const std::string& fragment) {
    auto study = TensorTradeStudy::create(std::move(s), std::move(scenarios));
    ASSERT_FALSE(study) << fragment;
    EXPECT_NE(study.error().message.find(fragment), std::string::npos) << study.error().message;
  };
  std::vector<TensorProbeScenario> one{good[1]};
  one[0].depths_m = {one[0].radius_m};
  expect_error(one, spec, "expected in (0, radius");
  one[0].depths_m = {0.3 * one[0].radius_m};
  one[0].inward = Eigen::Vector3d(0.0, 0.0, -2.0);
  expect_error(one, spec, "unit vector");
  one[0].inward = -Eigen::Vector3d::UnitZ();
  TensorStudySpec unknown_set = spec;
  unknown_set.contact_set = "lid";
  expect_error(one, unknown_set, "contact set 'lid'");
  // A small probe between four nodes, barely pressed: nothing under it.
  std::vector<TensorProbeScenario> between{good[0]};
  between[0].surface_point_m += Eigen::Vector3d(0.005, 0.005, 0.0);
  between[0].depths_m = {0.1 * between[0].radius_m};
  expect_error(between, spec, "covers no contact node");
  expect_error({}, spec, "no scenarios");

  auto study = TensorTradeStudy::create(spec, one);
  ASSERT_TRUE(study) << study.error().message;
  auto zero = (*study)->measure({0}, tensor_quick_cost());
  ASSERT_FALSE(zero);
  EXPECT_NE(zero.error().message.find("max_contacts"), std::string::npos) << zero.error().message;
  auto too_many = (*study)->measure({65}, tensor_quick_cost());
  ASSERT_FALSE(too_many);
  auto bad_cost = (*study)->measure({2}, CycleCostOptions{-1, 1, 1});
  ASSERT_FALSE(bad_cost);
  EXPECT_NE(bad_cost.error().message.find("warm-up"), std::string::npos);

  TensorStudySpec flat = spec;
  auto no_top = default_tensor_scenarios(flat.mesh, std::vector<int>{0});
  ASSERT_FALSE(no_top);
  EXPECT_NE(no_top.error().message.find("top face"), std::string::npos);
}

}  // namespace
}  // namespace trainer::model::offline
