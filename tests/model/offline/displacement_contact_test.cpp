// Displacement-driven tip contact on the modal duct, end to end with the real pieces: the default
// duct's geometry built offline into an image, loaded, the ModalModel stepped at 1 kHz, its
// deformed surface reconstructed and bucketed every cycle, a tool tip pressing radially into
// the wall at mid-length and withdrawing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <filesystem>
#include <string>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/displacement_contact.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::model {
namespace {

constexpr float kTipRadius = 0.0005F;  // 1 mm forceps tip
constexpr float kDt = 0.001F;

struct Duct {
  core::Arena arena = core::Arena::create(std::size_t{16} << 20).value();
  ModelImage image;
  std::vector<float> deformed;
};

// The default duct (config/models/duct.toml): R 4.3 mm, L 24.4 mm, 21 × 16, E 0.3 MPa, 1 mm,
// DKT, clamped at x = 0, 40 modes with static correction, 1 ms.
std::unique_ptr<Duct> build_duct() {
  auto duct = std::make_unique<Duct>();
  offline::ModalBuildSpec spec;
  spec.name = "duct";
  spec.mesh = offline::make_tube(0.0043, 0.0244, 21, 16).value();
  spec.material = {3e5, 0.45, 0.001, 1000.0};
  spec.fixes = {{"clamped", {0, 1, 2, 3, 4, 5}}};
  spec.mode_count = 40;
  spec.damping_ratio = 0.05;
  spec.time_step_s = 0.001;
  auto built = offline::build_modal_model(spec);
  EXPECT_TRUE(built) << built.error().message;
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("contact_duct_" + std::to_string(::getpid()) + ".img");
  EXPECT_TRUE(offline::write_modal_image(spec, built.value(), path));
  auto image = load_model_image(path, duct->arena, ImageLimits{}, ModelKind::modal_shell);
  std::filesystem::remove(path);
  EXPECT_TRUE(image) << image.error().message;
  duct->image = std::move(image).value();
  duct->deformed.assign(3 * duct->image.metadata().node_count, 0.0F);
  return duct;
}

struct Rig {
  ModalModel modal;
  BucketGrid grid;
  DisplacementContact contact;
  std::span<const float> rest;
  std::span<const std::uint32_t> triangles;
};

Rig make_rig(Duct& duct) {
  ModalSettings settings;
  settings.time_step_s = kDt;
  settings.static_correction = true;
  auto modal = ModalModel::create(modal_model_data(duct.image), duct.arena, settings);
  EXPECT_TRUE(modal) << modal.error().message;
  BucketGridSettings grid_settings;
  grid_settings.max_triangles = duct.image.rows(SectionId::triangles);
  grid_settings.max_vertices = duct.image.metadata().node_count;
  grid_settings.cell_size_m = 0.0015F;  // ~ the mean edge (1.2–1.7 mm)
  grid_settings.table_size = 4096;
  grid_settings.max_entries = 16384;
  auto grid = BucketGrid::create(grid_settings, duct.arena);
  EXPECT_TRUE(grid) << grid.error().message;
  DisplacementContactSettings contact_settings;
  contact_settings.tip_radius_m = kTipRadius;
  auto contact = DisplacementContact::create(contact_settings,
                                             duct.image.u32s(SectionId::fixed_nodes), duct.arena);
  EXPECT_TRUE(contact) << contact.error().message;
  return Rig{std::move(modal).value(), std::move(grid).value(), std::move(contact).value(),
             duct.image.floats(SectionId::rest_positions), duct.image.u32s(SectionId::triangles)};
}

struct CycleResult {
  bool in_contact = false;
  Vec3 tool_force = Vec3::Zero();
  Vec3 imposed = Vec3::Zero();
  std::uint32_t first_target = 0;
};

// One haptic cycle: surface now → contact → imposed forces → step.
CycleResult cycle(Duct& duct, Rig& rig, const Vec3& previous_tip, const Vec3& tip) {
  CycleResult result;
  EXPECT_TRUE(rig.modal.reconstruct(duct.deformed).is_ok());
  for (std::size_t i = 0; i < duct.deformed.size(); ++i) duct.deformed[i] += rig.rest[i];
  const TriangleMeshView view{duct.deformed, rig.triangles};
  EXPECT_TRUE(rig.grid.rebuild(view.positions_m, view.triangles).is_ok());
  EXPECT_TRUE(rig.contact.update(view, rig.grid, previous_tip, tip).is_ok());
  rig.modal.clear_forces();
  std::array<ImposedDisplacement, DisplacementContact::kMaxTargets> targets{};
  const std::size_t count = rig.contact.targets(view, rig.rest, tip, targets);
  if (count > 0) {
    std::array<Vec3, DisplacementContact::kMaxTargets> forces{};
    EXPECT_TRUE(rig.modal.solve_imposed(std::span(targets.data(), count),
                                        std::span(forces.data(), count)).is_ok());
    Vec3 on_tissue = Vec3::Zero();
    for (std::size_t i = 0; i < count; ++i) on_tissue += forces[i];
    rig.contact.observe_force(view, on_tissue);
    if (rig.contact.in_contact()) {
      result.in_contact = true;
      result.tool_force = -on_tissue;
      result.imposed = targets[0].displacement_m;
      result.first_target = targets[0].node;
    } else {
      rig.modal.clear_forces();  // released this cycle: nothing imposed
    }
  }
  EXPECT_TRUE(rig.modal.step().is_ok());
  return result;
}

TEST(DisplacementContact, TipPressIntoTheDuctWallIsResistedAndReleasedOnWithdrawal) {
  auto duct = build_duct();
  Rig rig = make_rig(*duct);
  // Radially down onto the top of the tube (+z side) at mid-length, from 3 mm above the wall
  // to 2 mm into it over 500 cycles, hold 200, withdraw over 500.
  const float x = 0.0122F;
  const auto tip_at = [&](int step) {
    const float top = 0.0043F + kTipRadius;  // the tip sphere touches the undeformed wall
    float height = 0.0F;
    if (step < 500) {
      height = top + 0.003F - 0.005F * static_cast<float>(step) / 500.0F;
    } else if (step < 700) {
      height = top - 0.002F;
    } else {
      height = top - 0.002F + 0.005F * static_cast<float>(step - 700) / 500.0F;
    }
    return Vec3(x, 0.0F, height);
  };
  ASSERT_TRUE(core::alloc::hooks_installed());
  Vec3 previous = tip_at(0);
  std::vector<CycleResult> results;
  results.reserve(1200);
  const std::uint64_t allocations = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (int step = 0; step < 1200; ++step) {
    const Vec3 tip = tip_at(step);
    results.push_back(cycle(*duct, rig, previous, tip));
    previous = tip;
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - allocations, 0U);

  int first_contact = -1;
  int last_contact = -1;
  float peak_force = 0.0F;
  for (int step = 0; step < 1200; ++step) {
    const CycleResult& result = results[static_cast<std::size_t>(step)];
    ASSERT_TRUE(result.tool_force.allFinite()) << "step " << step;
    if (!result.in_contact) continue;
    if (first_contact < 0) first_contact = step;
    last_contact = step;
    peak_force = std::max(peak_force, result.tool_force.norm());
  }
  const auto mean_push = [&](int from, int to) {
    double sum = 0.0;
    for (int step = from; step < to; ++step) {
      sum += static_cast<double>(results[static_cast<std::size_t>(step)].tool_force.z());
    }
    return sum / (to - from);
  };
  // Contact starts when the tip sphere reaches the wall: step 300 of the approach (3 mm at
  // 10 µm per step), within a few steps.
  EXPECT_NEAR(first_contact, 300, 3);
  // Pressing in, the wall pushes the tool back out (+z) harder the deeper it goes (means over
  // 50 ms: the imposed motion also excites the duct's modes, so single cycles jitter).
  const double shallow = mean_push(350, 400);
  const double deep = mean_push(450, 500);
  const double hold = mean_push(600, 700);
  EXPECT_GT(shallow, 0.0);
  EXPECT_GT(deep, 1.5 * shallow);
  EXPECT_NEAR(hold, deep, 0.5 * deep);
  std::printf("push at 0.5 / 1.5 mm: %.4f / %.4f N, hold at 2 mm %.4f N, peak %.4f N\n", shallow,
              deep, hold, static_cast<double>(peak_force));
  // 2 mm into a 0.3 MPa, 1 mm-wall duct: tenths of a newton at most, far below the 8 N limit.
  EXPECT_LT(peak_force, 2.0F);
  // Withdrawal lets go before the tip is back at the touching height (step 1100).
  EXPECT_GT(last_contact, 700);
  EXPECT_LT(last_contact, 1100);
  // After release the duct relaxes back towards rest.
  const Vec3 away(x, 0.0F, 0.02F);
  for (int step = 0; step < 2000; ++step) {
    EXPECT_FALSE(cycle(*duct, rig, away, away).in_contact);
  }
  float largest = 0.0F;
  for (std::uint32_t node = 0; node < rig.modal.node_count(); ++node) {
    largest = std::max(largest, rig.modal.displacement(node).norm());
  }
  EXPECT_LT(largest, 1e-5F);
}

TEST(DisplacementContact, ClampedTrianglesAndNonFiniteTipsAreNoContact) {
  auto duct = build_duct();
  Rig rig = make_rig(*duct);
  // A tip crossing the wall right at the clamp (x = 0): the ring of fixed nodes.
  for (std::size_t i = 0; i < duct->deformed.size(); ++i) duct->deformed[i] = rig.rest[i];
  const TriangleMeshView view{duct->deformed, rig.triangles};
  ASSERT_TRUE(rig.grid.rebuild(view.positions_m, view.triangles).is_ok());
  const float nan = std::nanf("");
  EXPECT_EQ(rig.contact.update(view, rig.grid, Vec3(0.01F, 0.0F, 0.01F), Vec3(nan, 0.0F, 0.0F)).code(),
            core::StatusCode::numeric_error);
  EXPECT_FALSE(rig.contact.in_contact());
  // Crossing near the clamp touches a triangle with free nodes too: targets skip the fixed ones.
  ASSERT_TRUE(
      rig.contact.update(view, rig.grid, Vec3(0.0002F, 0.0F, 0.006F), Vec3(0.0002F, 0.0F, 0.004F))
          .is_ok());
  if (rig.contact.in_contact()) {
    std::array<ImposedDisplacement, DisplacementContact::kMaxTargets> targets{};
    const std::size_t count = rig.contact.targets(view, rig.rest, Vec3(0.0002F, 0.0F, 0.004F), targets);
    const auto fixed = duct->image.u32s(SectionId::fixed_nodes);
    for (std::size_t i = 0; i < count; ++i) {
      EXPECT_FALSE(std::binary_search(fixed.begin(), fixed.end(), targets[i].node));
    }
    EXPECT_LT(count, 3U);
  }
}

}  // namespace
}  // namespace trainer::model
