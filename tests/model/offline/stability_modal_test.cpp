// Stability of the reduced-modal duct at the extremes (docs/stability.md): Young's modulus over
// ten decades, Poisson's ratio up to 0.4999, time steps from 10 µs to 100 ms, imposed
// penetrations up to twice the duct's diameter — through the real offline build (shell FEM,
// modes, Rayleigh damping, residual compliance), its float32 data and the runtime ModalModel,
// with the tool force passed through the safety chain.
//
// For every extreme: no NaN or Inf in the modal state, the displacements or the forces; the
// energy of the undriven damped system, E = Σ ½ (v_i² + ω_i² x_i²) in modal coordinates
// (kg·m²/s² = J with M-orthonormal modes), never grows from one step to the next once the load
// is released (average-acceleration Newmark: E_{n+1} − E_n = −α_i Δt ((v_n + v_{n+1})/2)² per
// mode exactly, so only rounding can raise it: the tolerance is a relative 1e-12 per step,
// measured worst 1e-15); the undamped system keeps its energy at any ω Δt (unconditional
// stability); and the force on the tool, after SafetySupervisor::limit_force, stays within
// max_force_n and its slew limit.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <span>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/displacement_contact.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/mesh_generators.hpp"
#include "trainer/model_offline/modal_build.hpp"
#include "safety_chain_probe.hpp"  // tests/support

namespace trainer::model {
namespace {

// The default duct's section and length (config/models/duct.toml) on a coarse mesh: 7 rings of
// 8 nodes (56 nodes, 48 free), so a build takes milliseconds.
constexpr double kRadiusM = 0.0043;
constexpr double kLengthM = 0.0244;
constexpr int kRings = 7;
constexpr int kSegments = 8;
constexpr int kModes = 12;
constexpr double kDefaultYoungPa = 3e5;
constexpr double kDefaultPoisson = 0.45;
// Relative rise of the released system's energy allowed per step: rounding only (see above).
constexpr double kEnergyRiseTolerance = 1e-12;

#if defined(TRAINER_SANITIZER_BUILD)
constexpr int kFreeSteps = 100;  // the sanitizer build checks the same extremes, shorter
#else
constexpr int kFreeSteps = 500;
#endif

// A built model and the float32 arrays the runtime views (as an image would hold them).
struct Duct {
  offline::ModalBuildSpec spec;
  offline::ModalBuildResult build;
  std::unique_ptr<offline::FloatModalData> data;
  core::Arena arena = core::Arena::create(std::size_t{4} << 20).value();
};

std::unique_ptr<Duct> build_duct(double young_pa, double poisson, double damping_ratio = 0.05) {
  auto duct = std::make_unique<Duct>();
  duct->spec.name = "duct";
  duct->spec.mesh = offline::make_tube(kRadiusM, kLengthM, kRings, kSegments).value();
  duct->spec.material = {young_pa, poisson, 0.001, 1000.0};
  duct->spec.fixes = {{"clamped", {0, 1, 2, 3, 4, 5}}};
  duct->spec.mode_count = kModes;
  duct->spec.damping_ratio = damping_ratio;
  duct->spec.time_step_s = 0.001;
  duct->spec.static_correction = true;
  auto built = offline::build_modal_model(duct->spec);
  EXPECT_TRUE(built) << built.error().message;
  if (!built) return nullptr;
  duct->build = std::move(built).value();
  duct->data = std::make_unique<offline::FloatModalData>(duct->spec, duct->build);
  return duct;
}

ModalModel make_model(Duct& duct, float time_step_s, ModalModelData data) {
  ModalSettings settings;
  settings.time_step_s = time_step_s;
  settings.static_correction = true;
  auto model = ModalModel::create(data, duct.arena, settings);
  EXPECT_TRUE(model) << model.error().message;
  return std::move(model).value();
}

// Σ ½ (v_i² + ω_i² x_i²) over the active modes, in double from the model's own state and ω².
double modal_energy(const ModalModel& model, std::span<const float> omega_squared) {
  double energy = 0.0;
  const auto x = model.modal_displacement();
  const auto v = model.modal_velocity();
  for (std::size_t i = 0; i < x.size(); ++i) {
    energy += 0.5 * (v[i] * v[i] + static_cast<double>(omega_squared[i]) * x[i] * x[i]);
  }
  return energy;
}

bool state_finite(const ModalModel& model) {
  for (const auto values : {model.modal_displacement(), model.modal_velocity(),
                            model.modal_acceleration()}) {
    for (const double value : values) {
      if (!std::isfinite(value)) return false;
    }
  }
  return true;
}

// The node on top (+z) of the ring nearest mid-length: where a tool presses the duct.
std::uint32_t top_node_at_mid_length() {
  const int ring = kRings / 2;
  return static_cast<std::uint32_t>(ring * kSegments + kSegments / 4);  // φ = π/2: +z
}

struct ReleaseRun {
  bool finite = true;
  double released_energy_j = 0.0;   // after the step that removes the load
  double final_energy_j = 0.0;
  double worst_rise = 0.0;          // max over steps of (E_{n+1} − E_n)/E_n
  double peak_displacement_m = 0.0; // at the observed node, whole run
};

// From the model's current state: removes every force, takes one transition step (in which
// the last force's work still enters), then steps `free_steps` undriven, checking every state.
void free_run(ModalModel& model, std::span<const float> omega_squared, std::uint32_t node,
              int free_steps, ReleaseRun& run) {
  const auto observe = [&] {
    run.finite = run.finite && state_finite(model);
    const Vec3 u = model.displacement(node);
    run.finite = run.finite && u.allFinite();
    run.peak_displacement_m = std::max(run.peak_displacement_m, static_cast<double>(u.norm()));
  };
  model.clear_forces();
  EXPECT_TRUE(model.step().is_ok());
  observe();
  double energy = modal_energy(model, omega_squared);
  run.released_energy_j = energy;
  for (int step = 0; step < free_steps; ++step) {
    EXPECT_TRUE(model.step().is_ok());
    observe();
    const double next = modal_energy(model, omega_squared);
    if (energy > 0.0) run.worst_rise = std::max(run.worst_rise, (next - energy) / energy);
    energy = next;
  }
  run.final_energy_j = energy;
}

ReleaseRun free_run(ModalModel& model, std::span<const float> omega_squared, std::uint32_t node,
                    int free_steps) {
  ReleaseRun run;
  free_run(model, omega_squared, node, free_steps, run);
  return run;
}

// From rest: loads `node` with `force_n` for `load_steps`, then free_run().
ReleaseRun release_run(ModalModel& model, std::span<const float> omega_squared,
                       std::uint32_t node, const Vec3& force_n, int load_steps, int free_steps) {
  ReleaseRun run;
  model.reset();
  EXPECT_TRUE(model.add_node_force(node, force_n).is_ok());
  for (int step = 0; step < load_steps; ++step) {
    EXPECT_TRUE(model.step().is_ok());
    run.finite = run.finite && state_finite(model) && model.displacement(node).allFinite();
    run.peak_displacement_m =
        std::max(run.peak_displacement_m, static_cast<double>(model.displacement(node).norm()));
  }
  free_run(model, omega_squared, node, free_steps, run);
  return run;
}

TEST(ModalStability, YoungsModulusOverTenDecades) {
  // 100 Pa (softer than any tissue) to 1 TPa (the configuration's upper bound, stiffer than
  // steel). The force is scaled with E so the static deflection is the same at every E.
  const std::uint32_t node = top_node_at_mid_length();
  double reference_ratio = 0.0;
  for (double young_pa = 1e2; young_pa <= 1e12 * 1.0001; young_pa *= 10.0) {
    SCOPED_TRACE(young_pa);
    auto duct = build_duct(young_pa, kDefaultPoisson);
    ASSERT_TRUE(duct);
    // ω² ∝ E exactly (K ∝ E, M independent of E): the eigensolver keeps that over ten decades.
    const double ratio = duct->build.basis.omega_squared(0) / young_pa;
    if (reference_ratio == 0.0) reference_ratio = ratio;
    EXPECT_NEAR(ratio / reference_ratio, 1.0, 1e-9);
    const ModalModelData data = duct->data->view();
    ModalModel model = make_model(*duct, 1e-3F, data);
    const float force_scale = static_cast<float>(young_pa / kDefaultYoungPa);
    const ReleaseRun run = release_run(model, data.omega_squared, node,
                                       Vec3(0.0F, 0.0F, -0.05F * force_scale), 200, kFreeSteps);
    const double omega_first = std::sqrt(duct->build.basis.omega_squared(0));
    const double omega_last = std::sqrt(duct->build.basis.omega_squared(kModes - 1));
    std::printf("E %8.1e Pa: f1 %10.4g Hz, f%d %10.4g Hz, w_r dt %9.3g, peak |u| %.4e m, energy "
                "%.3e -> %.3e J, worst rise %.1e\n",
                young_pa, omega_first / (2 * std::numbers::pi), kModes,
                omega_last / (2 * std::numbers::pi), omega_last * 1e-3, run.peak_displacement_m,
                run.released_energy_j, run.final_energy_j, run.worst_rise);
    EXPECT_TRUE(run.finite);
    EXPECT_GT(run.released_energy_j, 0.0);
    EXPECT_LE(run.worst_rise, kEnergyRiseTolerance);
    EXPECT_LT(run.final_energy_j, run.released_energy_j);
  }
}

// A copy of a model's data with every modal damping set to zero (the undamped system).
struct UndampedData {
  std::vector<float> damping;
  ModalModelData data;
};

UndampedData undamped(const ModalModelData& data) {
  UndampedData copy;
  copy.damping.assign(data.modal_damping.size(), 0.0F);
  copy.data = data;
  copy.data.modal_damping = copy.damping;
  return copy;
}

TEST(ModalStability, TimeStepsFromTenMicrosecondsToATenthOfASecond) {
  // 10 µs (a 100 kHz loop) to 100 ms (the configuration's upper bound): ω Δt from 1e-3 to
  // 3e4 on a soft (1 kPa) and a stiff (1 GPa) duct. Damped: the released energy never rises.
  // Undamped: average-acceleration Newmark is unconditionally stable with no numerical
  // damping, so the energy after release stays what it was to rounding at every ω Δt.
  const std::uint32_t node = top_node_at_mid_length();
  for (const double young_pa : {1e3, 1e9}) {
    auto duct = build_duct(young_pa, kDefaultPoisson);
    ASSERT_TRUE(duct);
    const ModalModelData data = duct->data->view();
    const UndampedData free_data = undamped(data);
    const float force = static_cast<float>(-0.05 * young_pa / kDefaultYoungPa);
    for (const float dt : {1e-5F, 1e-4F, 1e-3F, 1e-2F, 1e-1F}) {
      SCOPED_TRACE(testing::Message() << "E " << young_pa << " Pa, dt " << dt << " s");
      ModalModel damped = make_model(*duct, dt, data);
      const ReleaseRun run =
          release_run(damped, data.omega_squared, node, Vec3(0.0F, 0.0F, force), 50, kFreeSteps);
      EXPECT_TRUE(run.finite);
      EXPECT_LE(run.worst_rise, kEnergyRiseTolerance);
      EXPECT_LE(run.final_energy_j, run.released_energy_j);

      ModalModel conservative = make_model(*duct, dt, free_data.data);
      const ReleaseRun free_run = release_run(conservative, data.omega_squared, node,
                                              Vec3(0.0F, 0.0F, force), 50, kFreeSteps);
      const double drift =
          std::abs(free_run.final_energy_j - free_run.released_energy_j) / free_run.released_energy_j;
      const double omega_dt_first =
          std::sqrt(static_cast<double>(data.omega_squared[0])) * static_cast<double>(dt);
      const double omega_dt_last =
          std::sqrt(static_cast<double>(data.omega_squared[kModes - 1])) * static_cast<double>(dt);
      std::printf("E %6.0e Pa dt %6.0e s: w dt %8.2g..%8.2g, damped energy %.3e -> %.3e J (worst "
                  "rise %.1e), undamped drift %.1e over %d steps\n",
                  young_pa, static_cast<double>(dt), omega_dt_first, omega_dt_last,
                  run.released_energy_j, run.final_energy_j, run.worst_rise, drift, kFreeSteps);
      EXPECT_TRUE(free_run.finite);
      EXPECT_LT(drift, 1e-9);
    }
  }
}

TEST(ModalStability, PoissonRatioUpTo0_4999) {
  // Plane stress (the shell's membrane and plate bending): D = E/(1 − ν²) stays finite as
  // ν → 0.5, so there is no volumetric locking: the frequencies and the deflection converge to
  // a finite limit (measured: ω₁² at ν = 0.45 is 0.920 of ν = 0, at 0.499 and 0.4999 both
  // 0.9197, 1e-5 apart) and nothing is refused below 0.5.
  const std::uint32_t node = top_node_at_mid_length();
  auto reference = build_duct(kDefaultYoungPa, 0.0);
  ASSERT_TRUE(reference);
  const double omega_squared_at_zero = reference->build.basis.omega_squared(0);
  double previous_ratio = 0.0;
  double previous_peak_m = 0.0;
  for (const double poisson : {0.3, 0.45, 0.49, 0.499, 0.4999}) {
    SCOPED_TRACE(poisson);
    auto duct = build_duct(kDefaultYoungPa, poisson);
    ASSERT_TRUE(duct);
    const double ratio = duct->build.basis.omega_squared(0) / omega_squared_at_zero;
    EXPECT_GT(ratio, 0.9);
    EXPECT_LT(ratio, 1.0);
    const ModalModelData data = duct->data->view();
    ModalModel model = make_model(*duct, 1e-3F, data);
    const ReleaseRun run =
        release_run(model, data.omega_squared, node, Vec3(0.0F, 0.0F, -0.05F), 200, kFreeSteps);
    std::printf("nu %.4f: f1 %.4f Hz (w1^2 x%.5f of nu = 0), peak |u| %.5e m, worst rise %.1e\n",
                poisson, std::sqrt(duct->build.basis.omega_squared(0)) / (2 * std::numbers::pi),
                ratio, run.peak_displacement_m, run.worst_rise);
    EXPECT_TRUE(run.finite);
    EXPECT_LE(run.worst_rise, kEnergyRiseTolerance);
    if (poisson == 0.4999) {
      EXPECT_NEAR(ratio / previous_ratio, 1.0, 1e-4);
      EXPECT_NEAR(run.peak_displacement_m / previous_peak_m, 1.0, 1e-3);
    }
    previous_ratio = ratio;
    previous_peak_m = run.peak_displacement_m;
  }
  offline::ModalBuildSpec refused = reference->spec;
  refused.material.poisson_ratio = 0.5;
  auto at_half = offline::build_modal_model(refused);
  ASSERT_FALSE(at_half);
  EXPECT_NE(at_half.error().message.find("poisson_ratio = 0.5"), std::string::npos)
      << at_half.error().message;
}


TEST(ModalStability, ImposedPenetrationUpToTwiceTheDiameter) {
  // The top node at mid-length is driven down by solve_imposed (the displacement-driven
  // contact) to 0.1 mm .. 17.2 mm, twice the duct's diameter (the linear model lets the wall
  // pass through the axis and the far wall: no self-contact), ramped over 100 steps and held
  // 100, on the default tissue and a 1 GPa duct. The model is linear and starts at rest, so
  // every force history is the 1 mm one scaled by the depth: nothing clips, refuses or
  // degrades with depth. After the safety chain the tool force stays within 8 N and its slew.
  const std::uint32_t node = top_node_at_mid_length();
  constexpr float kDt = 1e-3F;
  for (const double young_pa : {kDefaultYoungPa, 1e9}) {
    auto duct = build_duct(young_pa, kDefaultPoisson);
    ASSERT_TRUE(duct);
    const ModalModelData data = duct->data->view();
    ModalModel model = make_model(*duct, kDt, data);
    std::vector<float> reference_per_m;  // force z per metre of depth, the 1 mm run
    for (const float depth_m : {1e-3F, 1e-4F, 4.3e-3F, 8.6e-3F, 17.2e-3F}) {
      SCOPED_TRACE(testing::Message() << "E " << young_pa << " Pa, depth " << depth_m << " m");
      model.reset();
      test::SafetyChainProbe safety;
      float peak_requested_n = 0.0F;
      double worst_scaling_error = 0.0;
      for (int step = 0; step < 200; ++step) {
        const float reached = depth_m * std::min(1.0F, static_cast<float>(step + 1) / 100.0F);
        const std::array<ImposedDisplacement, 1> target{{{node, Vec3(0.0F, 0.0F, -reached)}}};
        std::array<Vec3, 1> force{};
        model.clear_forces();
        ASSERT_TRUE(model.solve_imposed(target, force).is_ok());
        ASSERT_TRUE(model.step().is_ok());
        ASSERT_TRUE(force[0].allFinite());
        ASSERT_TRUE(state_finite(model));
        EXPECT_NEAR(model.displacement(node).z(), -reached, 1e-4F * depth_m);
        const float per_m = force[0].z() / depth_m;
        if (depth_m == 1e-3F) {
          reference_per_m.push_back(per_m);
        } else {
          const float reference = reference_per_m[static_cast<std::size_t>(step)];
          worst_scaling_error = std::max(
              worst_scaling_error, static_cast<double>(std::abs(per_m - reference)) /
                                       static_cast<double>(std::abs(reference) + 1e-30F));
        }
        peak_requested_n = std::max(peak_requested_n, force[0].norm());
        safety.pass(-force[0], kDt);
      }
      std::printf("E %6.0e Pa, depth %5.1f mm: peak requested %10.4g N, after safety %.3f N, "
                  "worst deviation from the scaled 1 mm history %.1e\n",
                  young_pa, 1e3 * static_cast<double>(depth_m),
                  static_cast<double>(peak_requested_n), static_cast<double>(safety.peak_n),
                  worst_scaling_error);
      EXPECT_LT(worst_scaling_error, 1e-4);
      safety.expect_within_limits(kDt);
      // Released from the press: the energy only decays.
      const ReleaseRun after = free_run(model, data.omega_squared, node, 100);
      EXPECT_TRUE(after.finite);
      EXPECT_GT(after.released_energy_j, 0.0);
      EXPECT_LE(after.worst_rise, kEnergyRiseTolerance);
    }
  }
}

TEST(ModalStability, ToolTipPressedThroughTheWholeDiameter) {
  // The haptic cycle's chain on the deformed surface (as tests/model/offline's contact test and
  // rt/app do it): reconstruct → bucket grid → DisplacementContact → solve_imposed → step. The
  // tip comes down on the top of the duct at mid-length and drives the wall 8.6 mm, the whole
  // diameter, to where the bottom wall rests (26 µm per 1 ms cycle), holds, and withdraws.
  constexpr float kDt = 1e-3F;
  constexpr float kTipRadiusM = 5e-4F;
  const float radius = static_cast<float>(kRadiusM);
  const float x = static_cast<float>(kLengthM / 2.0);
  const float touching = radius + kTipRadiusM;  // tip height where the sphere meets the wall
  const float deepest = touching - 2.0F * radius;
  const auto tip_at = [&](int cycle) {
    const float start = touching + 0.002F;
    float z = deepest;
    if (cycle < 400) z = start + (deepest - start) * static_cast<float>(cycle) / 400.0F;
    if (cycle >= 500) z = deepest + (start - deepest) * static_cast<float>(cycle - 500) / 400.0F;
    return Vec3(x, 0.0F, z);
  };
  for (const double young_pa : {kDefaultYoungPa, 1e9}) {
    SCOPED_TRACE(young_pa);
    auto duct = build_duct(young_pa, kDefaultPoisson);
    ASSERT_TRUE(duct);
    const ModalModelData data = duct->data->view();
    ModalModel model = make_model(*duct, kDt, data);
    std::vector<std::uint32_t> triangles;
    for (Eigen::Index t = 0; t < duct->spec.mesh.triangles.rows(); ++t) {
      for (int c = 0; c < 3; ++c) {
        triangles.push_back(static_cast<std::uint32_t>(duct->spec.mesh.triangles(t, c)));
      }
    }
    std::vector<std::uint32_t> fixed;
    for (const int node : duct->spec.mesh.node_sets.at("clamped")) {
      fixed.push_back(static_cast<std::uint32_t>(node));
    }
    std::sort(fixed.begin(), fixed.end());
    BucketGridSettings grid_settings;
    grid_settings.max_triangles = static_cast<std::uint32_t>(triangles.size() / 3);
    grid_settings.max_vertices = data.node_count;
    grid_settings.cell_size_m = 0.004F;  // ~ the coarse mesh's edge
    grid_settings.table_size = 1024;
    grid_settings.max_entries = 1 << 16;
    auto grid = BucketGrid::create(grid_settings, duct->arena);
    ASSERT_TRUE(grid) << grid.error().message;
    DisplacementContactSettings contact_settings;
    contact_settings.tip_radius_m = kTipRadiusM;
    auto contact = DisplacementContact::create(contact_settings, fixed, duct->arena);
    ASSERT_TRUE(contact) << contact.error().message;
    std::vector<float> deformed(3 * data.node_count);
    test::SafetyChainProbe safety;
    Vec3 previous = tip_at(0);
    int contact_cycles = 0;
    float deepest_imposed_m = 0.0F;
    float peak_requested_n = 0.0F;
    for (int cycle = 0; cycle < 900; ++cycle) {
      const Vec3 tip = tip_at(cycle);
      ASSERT_TRUE(model.reconstruct(deformed).is_ok());
      for (std::size_t i = 0; i < deformed.size(); ++i) deformed[i] += data.rest_positions[i];
      ASSERT_TRUE(std::all_of(deformed.begin(), deformed.end(), [](float v) { return std::isfinite(v); }))
          << "cycle " << cycle;
      const TriangleMeshView view{deformed, triangles};
      ASSERT_TRUE(grid->rebuild(view.positions_m, view.triangles).is_ok()) << "cycle " << cycle;
      ASSERT_TRUE(contact->update(view, *grid, previous, tip).is_ok());
      model.clear_forces();
      std::array<ImposedDisplacement, DisplacementContact::kMaxTargets> targets{};
      const std::size_t count = contact->targets(view, data.rest_positions, tip, targets);
      Vec3 on_tool = Vec3::Zero();
      if (count > 0) {
        std::array<Vec3, DisplacementContact::kMaxTargets> forces{};
        ASSERT_TRUE(model.solve_imposed(std::span(targets.data(), count),
                                        std::span(forces.data(), count)).is_ok())
            << "cycle " << cycle;
        Vec3 on_tissue = Vec3::Zero();
        for (std::size_t i = 0; i < count; ++i) {
          on_tissue += forces[i];
          deepest_imposed_m = std::max(deepest_imposed_m, -targets[i].displacement_m.z());
        }
        ASSERT_TRUE(on_tissue.allFinite()) << "cycle " << cycle;
        contact->observe_force(view, on_tissue);
        if (contact->in_contact()) {
          ++contact_cycles;
          on_tool = -on_tissue;
        } else {
          model.clear_forces();
        }
      }
      peak_requested_n = std::max(peak_requested_n, on_tool.norm());
      safety.pass(on_tool, kDt);
      ASSERT_TRUE(model.step().is_ok()) << "cycle " << cycle;
      ASSERT_TRUE(state_finite(model)) << "cycle " << cycle;
      previous = tip;
    }
    std::printf("E %6.0e Pa: tip through the diameter: %d contact cycles, deepest imposed %.2f mm, "
                "peak requested %.4g N, after safety %.3f N\n",
                young_pa, contact_cycles, 1e3 * static_cast<double>(deepest_imposed_m),
                static_cast<double>(peak_requested_n), static_cast<double>(safety.peak_n));
    EXPECT_GT(contact_cycles, 300);
    EXPECT_GT(deepest_imposed_m, 0.95F * 2.0F * radius);  // the wall was driven a diameter deep
    EXPECT_FALSE(contact->in_contact());                  // and let go on the way out
    safety.expect_within_limits(kDt);
    const ReleaseRun after = free_run(model, data.omega_squared, top_node_at_mid_length(), 100);
    EXPECT_TRUE(after.finite);
    EXPECT_GT(after.released_energy_j, 0.0);
    EXPECT_LE(after.worst_rise, kEnergyRiseTolerance);
  }
}

}  // namespace
}  // namespace trainer::model
