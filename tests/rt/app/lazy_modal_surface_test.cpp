// LazyModalSurface (rt/app, docs/collision.md "Lazy reconstruction"): on a small synthetic modal
// shell with static correction (random mode shapes, r = 10 so the packet sums have a tail, a
// random symmetric positive residual compliance), driven by a scripted press/release sequence
// and by random loads:
//  - every vertex a query makes current equals the full reconstruction bit for bit, both the
//    lazy kernel's full path and ModalModel::reconstruct (+ rest), the field the cycle used
//    before;
//  - the per-cluster bound is conservative (every vertex of a cluster is within its cluster's
//    bound of the hierarchy's reference), and the lazy path is taken exactly when the full
//    path's refit would skip the work: a lazy step's full reconstruction is within the slack
//    of the hierarchy's reference, a full step's is beyond it (the refit did the work);
//  - lazy (also with clusters checked) and full steps all happen; no heap after setup.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <optional>
#include <string>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "trainer/app/contact_surface.hpp"
#include "trainer/app/lazy_modal_surface.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/model/modal_model.hpp"

namespace trainer::app {
namespace {

using Vec3 = Eigen::Vector3f;

struct Shell {
  std::uint32_t side = 6;  // side × side nodes, 10 mm apart
  std::uint32_t modes = 10;
  std::vector<float> rest, shapes, omega2, damping, residual;
  std::vector<std::uint32_t> surface, triangles;

  Shell() {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> unit(-1.0F, 1.0F);
    const std::uint32_t n = side * side;
    for (std::uint32_t y = 0; y < side; ++y) {
      for (std::uint32_t x = 0; x < side; ++x) {
        rest.push_back(0.01F * static_cast<float>(x));
        rest.push_back(0.01F * static_cast<float>(y));
        rest.push_back(0.0F);
      }
    }
    for (std::uint32_t y = 0; y + 1 < side; ++y) {
      for (std::uint32_t x = 0; x + 1 < side; ++x) {
        const std::uint32_t a = y * side + x;
        triangles.insert(triangles.end(), {a, a + 1, a + side + 1, a, a + side + 1, a + side});
      }
    }
    for (std::size_t i = 0; i < 3 * n * modes; ++i) shapes.push_back(unit(rng));
    for (std::uint32_t i = 0; i < modes; ++i) {
      omega2.push_back(400.0F * static_cast<float>(i + 1));
      damping.push_back(20.0F);
    }
    for (std::uint32_t i = 0; i < n; ++i) surface.push_back(i);
    // R = B Bᵀ / 3n · 1e-3 m/N: symmetric, positive semi-definite.
    const std::size_t d = 3 * n;
    std::vector<float> b(d * d);
    for (float& value : b) value = unit(rng);
    residual.assign(d * d, 0.0F);
    for (std::size_t i = 0; i < d; ++i) {
      for (std::size_t j = 0; j <= i; ++j) {
        double sum = 0.0;
        for (std::size_t k = 0; k < d; ++k) sum += static_cast<double>(b[i * d + k]) * static_cast<double>(b[j * d + k]);
        residual[i * d + j] = residual[j * d + i] = static_cast<float>(sum / static_cast<double>(d) * 1e-3);
      }
    }
  }

  model::ModalModelData data() const {
    model::ModalModelData result;
    result.node_count = side * side;
    result.mode_count = modes;
    result.rest_positions = rest;
    result.mode_shapes = shapes;
    result.omega_squared = omega2;
    result.modal_damping = damping;
    result.surface_nodes = surface;
    result.residual_compliance = residual;
    return result;
  }
};

struct Rig {
  Shell shell;
  core::Arena arena = std::move(core::Arena::create(std::size_t{1} << 22).value());
  std::optional<model::ModalModel> modal;
  ContactSurface surface;
  std::optional<LazyModalSurface> lazy;
  std::vector<float> full, reference;
  std::uint64_t lazy_steps = 0, full_steps = 0, needless_full_steps = 0;

  Rig() {
    model::ModalSettings settings;
    settings.time_step_s = 1e-3F;
    settings.static_correction = true;
    modal.emplace(std::move(model::ModalModel::create(shell.data(), arena, settings).value()));
    config::SceneModelConfig entry;
    surface = std::move(make_contact_surface(entry, shell.rest, shell.triangles, true, arena).value());
    lazy.emplace(std::move(LazyModalSurface::create(shell.data(), *modal, arena).value()));
    full.resize(shell.rest.size());
    reference.resize(shell.rest.size());
  }

  // One cycle: the loads, a step, the surface as the modal stage refreshes it. Checks that the
  // lazy path is taken exactly when the full path's refit would skip the work.
  void step(const std::vector<std::pair<std::uint32_t, Eigen::Vector3f>>& loads) {
    modal->clear_forces();
    for (const auto& [node, force] : loads) ASSERT_TRUE(modal->add_node_force(node, force).is_ok());
    ASSERT_TRUE(modal->step().is_ok());
    ASSERT_TRUE(modal->reconstruct(full).is_ok());
    for (std::size_t i = 0; i < full.size(); ++i) full[i] += shell.rest[i];
    // The hierarchy's reference before this step (what refit() compares against).
    const std::span<const float> held = surface.grid->reference_positions();
    std::copy(held.begin(), held.end(), reference.begin());
    float deviation = 0.0F;
    for (std::size_t i = 0; i < full.size(); ++i) deviation = std::max(deviation, std::abs(full[i] - reference[i]));
    const std::uint64_t refits = surface.grid->refit_count();
    if (lazy->begin(surface, *modal)) {
      ++lazy_steps;
      ASSERT_LE(deviation, surface.grid_slack_m) << "lazy although the full path would refit";
      ASSERT_EQ(refits, surface.grid->refit_count());
    } else {
      ASSERT_TRUE(lazy->finish_full(surface));
      // The full path: all vertices equal the model's reconstruction.
      ASSERT_EQ(0, std::memcmp(surface.deformed.data(), full.data(), full.size() * sizeof(float)));
      // Every full step after the first is one the refit needs.
      if (full_steps > 0 && deviation <= surface.grid_slack_m) ++needless_full_steps;
      EXPECT_EQ(needless_full_steps, 0U) << "a full step the refit did not need";
      if (deviation > surface.grid_slack_m) {
        EXPECT_EQ(refits + 1, surface.grid->refit_count());
      }
      ++full_steps;
    }
  }

  // Queries over boxes around random points: every vertex of every returned triangle is the
  // full reconstruction's, bit for bit. Returns how many triangles were checked.
  std::size_t query_and_compare(std::mt19937& rng) {
    std::uniform_real_distribution<float> where(-0.005F, 0.055F);
    std::array<std::uint32_t, 64> ids{};
    std::size_t checked = 0;
    for (int q = 0; q < 3; ++q) {
      const Vec3 centre(where(rng), where(rng), 0.0F);
      std::size_t count = 0;
      EXPECT_TRUE(lazy->query(model::Aabb::around_point(centre, 0.008F), ids, count).is_ok());
      for (std::size_t k = 0; k < count; ++k) {
        for (std::size_t c = 0; c < 3; ++c) {
          const std::size_t base = 3 * static_cast<std::size_t>(shell.triangles[3 * ids[k] + c]);
          EXPECT_EQ(0, std::memcmp(&surface.deformed[base], &full[base], 3 * sizeof(float)))
              << "vertex " << base / 3 << ": lazy " << surface.deformed[base] << " full " << full[base];
        }
        ++checked;
      }
    }
    return checked;
  }
};

TEST(LazyModalSurface, QueriedVerticesEqualTheFullReconstructionOverAPressAndRelease) {
  Rig rig;
  std::mt19937 rng(11);
  std::size_t checked = 0;
  // Press two nodes with a ramp, hold, release; a third node tapped.
  for (int cycle = 0; cycle < 600; ++cycle) {
    std::vector<std::pair<std::uint32_t, Eigen::Vector3f>> loads;
    const float ramp = cycle < 200 ? static_cast<float>(cycle) / 200.0F : (cycle < 400 ? 1.0F : 0.0F);
    if (ramp > 0.0F) {
      // Large enough to move the surface beyond the hierarchy's slack (refits happen).
      loads.emplace_back(14U, Eigen::Vector3f(0.0F, 0.0F, -30.0F * ramp));
      loads.emplace_back(21U, Eigen::Vector3f(6.0F, 0.0F, -20.0F * ramp));
    }
    if (cycle % 50 < 5) loads.emplace_back(8U, Eigen::Vector3f(0.0F, 0.0F, -12.0F));
    rig.step(loads);
    checked += rig.query_and_compare(rng);
    // The lazy path's every vertex (its per-node static correction) against the model's
    // reconstruction too.
    for (std::uint32_t node = 0; node < rig.shell.side * rig.shell.side; ++node) {
      float out[3];
      rig.lazy->reconstruct_node(node, out);
      ASSERT_EQ(0, std::memcmp(out, &rig.full[3 * node], sizeof(out))) << "node " << node;
    }
  }
  EXPECT_GT(checked, 1000U);
  EXPECT_GT(rig.lazy_steps, 0U);
  EXPECT_GT(rig.full_steps, 1U);
}

TEST(LazyModalSurface, ClusterBoundsAreConservativeUnderRandomLoads) {
  Rig rig;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> force(-30.0F, 30.0F);
  std::uniform_int_distribution<std::uint32_t> node(0, rig.shell.side * rig.shell.side - 1);
  std::vector<std::pair<std::uint32_t, Eigen::Vector3f>> loads;
  double tightest = 0.0;
  std::size_t bounds_checked = 0;
  for (int cycle = 0; cycle < 2000; ++cycle) {
    if (cycle % 7 == 0) {  // new loads now and then; held in between
      loads.clear();
      const int count = static_cast<int>(node(rng) % 4);
      for (int k = 0; k < count; ++k) loads.emplace_back(node(rng), Eigen::Vector3f(force(rng), force(rng), force(rng)));
    }
    const std::uint64_t full_before = rig.full_steps;
    rig.step(loads);
    if (full_before == 0) continue;
    // Every cluster's bound of this step against its vertices' distance from the hierarchy's
    // reference before the step (rig.reference).
    for (std::size_t c = 0; c < rig.lazy->cluster_count(); ++c) {
      const double bound = rig.lazy->last_cluster_bound_m(c);
      ASSERT_TRUE(std::isfinite(bound));
      double moved = 0.0;
      for (std::uint32_t k = rig.lazy->cluster_start(c); k < rig.lazy->cluster_start(c + 1); ++k) {
        const std::size_t v = rig.lazy->cluster_nodes()[k];
        for (std::size_t a = 0; a < 3; ++a) {
          moved = std::max(moved, std::abs(static_cast<double>(rig.full[3 * v + a]) -
                                           static_cast<double>(rig.reference[3 * v + a])));
        }
      }
      ASSERT_LE(moved, bound) << "cycle " << cycle << " cluster " << c;
      if (bound > 0.0) tightest = std::max(tightest, moved / bound);
      ++bounds_checked;
    }
  }
  EXPECT_GT(bounds_checked, 1000U);
  EXPECT_GT(rig.lazy_steps, 100U);
  EXPECT_GT(rig.lazy->checked_steps(), 10U);
  EXPECT_GT(rig.full_steps, 10U);
  // Round 4's paths ran under the bound check too: clusters kept by the mean-row bound, and
  // whole-surface steps rebased without a refit.
  EXPECT_GT(rig.lazy->refined_clusters(), 10U);
  EXPECT_GT(rig.lazy->rebased_steps(), 0U);
  RecordProperty("bound_tightness", std::to_string(tightest));
  std::printf("lazy %llu (checked %llu, refined clusters %llu, rebased %llu) full %llu (refit not needed %llu), largest motion / bound %.3f\n",
              static_cast<unsigned long long>(rig.lazy_steps),
              static_cast<unsigned long long>(rig.lazy->checked_steps()),
              static_cast<unsigned long long>(rig.lazy->refined_clusters()),
              static_cast<unsigned long long>(rig.lazy->rebased_steps()),
              static_cast<unsigned long long>(rig.full_steps),
              static_cast<unsigned long long>(rig.needless_full_steps), tightest);
}

TEST(LazyModalSurface, NoHeapAfterSetup) {
  Rig rig;
  std::mt19937 rng(3);
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int cycle = 0; cycle < 200; ++cycle) {
    rig.modal->clear_forces();
    (void)rig.modal->add_node_force(14U, Eigen::Vector3f(0.0F, 0.0F, cycle < 100 ? -0.05F : 0.0F));
    (void)rig.modal->step();
    if (!rig.lazy->begin(rig.surface, *rig.modal)) (void)rig.lazy->finish_full(rig.surface);
    std::array<std::uint32_t, 64> ids{};
    std::size_t count = 0;
    (void)rig.lazy->query_segment(Vec3(0.0F, 0.0F, 0.0F), Vec3(0.05F, 0.05F, 0.0F), 0.004F, ids, count);
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_GT(rig.lazy->lazy_steps(), 0U);
  (void)rng;
}

}  // namespace
}  // namespace trainer::app
