// Speed of the reduced-modal duct (NIRMS, METHODS.md §1) on the default duct of
// config/models/duct.toml: the runtime ModalModel's haptic cycle against r, with and without
// static correction, the displacement-driven contact path against the contact count, the
// graphics-rate full reconstruction, the full-system reference (DNIOS, dnios.hpp) on the same
// mesh, and the offline precompute. docs/performance.md reports these numbers. The haptic
// cycle and the contact path also run on ModalModelDouble (…Double benchmarks): the same
// build held in double, for the float-vs-double trade.
//
// Images: every model is built once per process (build_modal_model, static correction on, so
// the image holds the residual compliance) and converted to the float32 arrays an image holds,
// as modal_accuracy.cpp does. "stored" is the mode count of the image, "modes" the active
// modes the runtime integrates: an image built with exactly r modes is what the appliance
// would load; running r of 160 stored modes shows what a larger image costs (with static
// correction the inactive stored modes enter every residual entry, modal_model.hpp).
//
// Loads vary through a 1 s cycle (1000 steps at the 1 ms the image is built for) so the state
// never settles to denormals or exact zeros, which would time a different machine path than a
// trainee pushing on the duct.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <numbers>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "model_spec.hpp"
#include "trainer/config/model.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/dnios.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace {

using namespace trainer;
namespace offline = model::offline;

constexpr std::int64_t kModeCounts[] = {10, 20, 40, 80, 160};
constexpr std::int64_t kLargestImageModes = 160;
constexpr std::int64_t kDefaultModes = 40;  // config/models/duct.toml [modal] mode_count
constexpr std::size_t kLoadCycleSteps = 1000;  // one load period: 1 s at Δt = 1 ms
constexpr std::size_t kArenaBytes = std::size_t{1} << 20;  // ModalModel state: < 20 kB used

// The default duct's spec, read from the real definition file (what `modelc build` builds).
core::Expected<offline::ModalBuildSpec> load_default_spec() {
  auto definition =
      config::load_model_definition(std::string(TRAINER_SOURCE_DIR) + "/config/models/duct.toml");
  if (!definition) return std::move(definition).error();
  return tools::modelc::modal_spec_from(*definition);
}

const core::Expected<offline::ModalBuildSpec>& default_spec() {
  static const core::Expected<offline::ModalBuildSpec> spec = load_default_spec();
  return spec;
}

struct DuctImage {
  offline::ModalBuildSpec spec;
  offline::ModalBuildResult build;
  offline::FloatModalData data;  // as the image holds it
};

// The default duct built with `mode_count` modes (static correction on), built on first use.
core::Expected<const DuctImage*> duct_image(std::int64_t mode_count) {
  static std::map<std::int64_t, std::unique_ptr<const DuctImage>> cache;
  if (const auto found = cache.find(mode_count); found != cache.end()) return found->second.get();
  const auto& base = default_spec();
  if (!base) return base.error();
  offline::ModalBuildSpec spec = *base;
  spec.mode_count = static_cast<int>(mode_count);
  spec.static_correction = true;
  auto build = offline::build_modal_model(spec);
  if (!build) return std::move(build).error();
  offline::FloatModalData data(spec, *build);
  auto image = std::make_unique<const DuctImage>(
      DuctImage{std::move(spec), std::move(*build), std::move(data)});
  const DuctImage* pointer = image.get();
  cache.emplace(mode_count, std::move(image));
  return pointer;
}

// Surface nodes ordered by distance from the middle of the tube's wall on its +y side (a tool
// pressing there): the first is the loaded node, the first c the contact patch.
std::vector<std::uint32_t> surface_nodes_near_middle(const DuctImage& image) {
  const auto& nodes = image.spec.mesh.nodes;
  const double length_m = nodes.col(0).maxCoeff();
  const double radius_m = nodes.row(0).tail<2>().norm();
  const Eigen::Vector3d point(0.5 * length_m, radius_m, 0.0);
  std::vector<std::pair<double, std::uint32_t>> by_distance;
  for (int node : image.build.surface_nodes) {
    by_distance.emplace_back((nodes.row(node).transpose() - point).norm(),
                             static_cast<std::uint32_t>(node));
  }
  std::sort(by_distance.begin(), by_distance.end());
  std::vector<std::uint32_t> ordered;
  for (const auto& entry : by_distance) ordered.push_back(entry.second);
  return ordered;
}

// Inward unit normal of the tube wall at `node` (the tube's axis is +x).
Eigen::Vector3d inward_normal(const DuctImage& image, std::uint32_t node) {
  const Eigen::Vector3d position = image.spec.mesh.nodes.row(static_cast<Eigen::Index>(node));
  return -Eigen::Vector3d(0.0, position.y(), position.z()).normalized();
}

// 0.5 (1 − cos) over one load cycle: 0 → 1 → 0, smooth, never negative.
double load_profile(std::size_t step) {
  const double phase =
      2.0 * std::numbers::pi * static_cast<double>(step) / static_cast<double>(kLoadCycleSteps);
  return 0.5 * (1.0 - std::cos(phase));
}

// One press of up to 0.1 N into the wall per load cycle, at `node`, in the model's precision.
template <typename Scalar>
std::vector<Eigen::Matrix<Scalar, 3, 1>> force_history(const DuctImage& image, std::uint32_t node) {
  constexpr double kPeakForceN = 0.1;
  std::vector<Eigen::Matrix<Scalar, 3, 1>> forces;
  for (std::size_t step = 0; step < kLoadCycleSteps; ++step) {
    forces.push_back(
        (kPeakForceN * load_profile(step) * inward_normal(image, node)).template cast<Scalar>());
  }
  return forces;
}

// The same build held in double, for ModalModelDouble. Copied on first use: a run of the float
// benchmarks alone neither makes nor holds the copies (the 160-mode image's are 8.7 MB, most of
// it the 960 × 960 residual compliance).
const offline::DoubleModalData& double_data(const DuctImage& image) {
  static std::map<const DuctImage*, std::unique_ptr<const offline::DoubleModalData>> cache;
  std::unique_ptr<const offline::DoubleModalData>& copy = cache[&image];
  if (!copy) copy = std::make_unique<const offline::DoubleModalData>(image.spec, image.build);
  return *copy;
}

template <typename Scalar>
model::BasicModalModelData<Scalar> runtime_data(const DuctImage& image) {
  if constexpr (std::is_same_v<Scalar, float>) {
    return image.data.view();
  } else {
    return double_data(image).view();
  }
}

// ModalModel (float, the image's data) or ModalModelDouble (the same build in double).
template <typename Scalar>
core::Expected<model::BasicModalModel<Scalar>> make_runtime(const DuctImage& image,
                                                            core::Arena& arena,
                                                            std::int64_t active_modes,
                                                            bool static_correction) {
  model::BasicModalSettings<Scalar> settings;
  settings.time_step_s = static_cast<Scalar>(image.spec.time_step_s);
  settings.active_modes = static_cast<std::uint32_t>(active_modes);
  settings.static_correction = static_correction;
  return model::BasicModalModel<Scalar>::create(runtime_data<Scalar>(image), arena, settings);
}

void set_size_counters(benchmark::State& state, const DuctImage& image) {
  state.counters["nodes"] = static_cast<double>(image.spec.mesh.nodes.rows());
  state.counters["free_dofs"] = static_cast<double>(image.build.shell.dofs.free_count());
  state.counters["stored_modes"] = static_cast<double>(image.build.basis.mode_count());
  state.counters["surface_nodes"] = static_cast<double>(image.build.surface_nodes.size());
  state.counters["triangles"] = static_cast<double>(image.spec.mesh.triangles.rows());
}

// Heap allocations made by this thread while the object lives (the RT path must make none;
// reported per cycle, so DNIOS's Eigen temporaries show too).
class AllocationCount {
 public:
  AllocationCount() : start_(core::alloc::counted_allocations()) {
    core::alloc::begin_counting_this_thread();
  }
  AllocationCount(const AllocationCount&) = delete;
  AllocationCount& operator=(const AllocationCount&) = delete;
  ~AllocationCount() { core::alloc::end_counting_this_thread(); }
  double counted() const {
    return static_cast<double>(core::alloc::counted_allocations() - start_);
  }

 private:
  std::uint64_t start_;
};

// One haptic cycle of the duct: clear, one nodal force, step, read that node's displacement.
template <typename Scalar>
void modal_step_cycle(benchmark::State& state, std::int64_t active_modes, std::int64_t stored_modes,
                      bool static_correction) {
  auto image = duct_image(stored_modes);
  if (!image) {
    state.SkipWithError(image.error().message.c_str());
    return;
  }
  auto arena = core::Arena::create(kArenaBytes);
  if (!arena) {
    state.SkipWithError(arena.error().message.c_str());
    return;
  }
  auto duct = make_runtime<Scalar>(**image, *arena, active_modes, static_correction);
  if (!duct) {
    state.SkipWithError(duct.error().message.c_str());
    return;
  }
  const std::uint32_t node = surface_nodes_near_middle(**image).front();
  const auto forces = force_history<Scalar>(**image, node);
  core::Status first_failure = core::Status::ok();
  std::size_t step = 0;
  double allocations = 0.0;
  {
    const AllocationCount counting;
    for (auto _ : state) {
      duct->clear_forces();
      const core::Status added = duct->add_node_force(node, forces[step]);
      const core::Status stepped = duct->step();
      auto displacement_m = duct->displacement(node);
      benchmark::DoNotOptimize(displacement_m);
      if (!added && first_failure) first_failure = added;
      if (!stepped && first_failure) first_failure = stepped;
      step = step + 1 == kLoadCycleSteps ? 0 : step + 1;
    }
    allocations = counting.counted();
  }
  if (!first_failure) {
    state.SkipWithError(first_failure.detail());
    return;
  }
  set_size_counters(state, **image);
  state.counters["active_modes"] = static_cast<double>(duct->active_mode_count());
  state.counters["static_correction"] = static_correction ? 1.0 : 0.0;
  state.counters["scalar_bytes"] = static_cast<double>(sizeof(Scalar));
  state.counters["heap_allocations_per_cycle"] =
      benchmark::Counter(allocations, benchmark::Counter::kAvgIterations);
}

// The image an appliance would load (stored = r) and r of a 160-mode image; static correction
// on, as the default duct definition builds it.
void modal_step_arguments(benchmark::internal::Benchmark* b) {
  b->ArgNames({"modes", "stored"});
  for (const std::int64_t modes : kModeCounts) {
    b->Args({modes, modes});
    if (modes != kLargestImageModes) b->Args({modes, kLargestImageModes});
  }
}
void BM_ModalStep(benchmark::State& state) {
  modal_step_cycle<float>(state, state.range(0), state.range(1), true);
}
BENCHMARK(BM_ModalStep)->Apply(modal_step_arguments);
// The same cycles on the same builds held in double (ModalModelDouble).
void BM_ModalStepDouble(benchmark::State& state) {
  modal_step_cycle<double>(state, state.range(0), state.range(1), true);
}
BENCHMARK(BM_ModalStepDouble)->Apply(modal_step_arguments);

void BM_ModalStepStaticCorrection(benchmark::State& state) {
  modal_step_cycle<float>(state, state.range(0), state.range(1), state.range(2) != 0);
}
BENCHMARK(BM_ModalStepStaticCorrection)
    ->ArgNames({"modes", "stored", "correction"})
    ->Apply([](benchmark::internal::Benchmark* b) {
      for (const std::int64_t modes : kModeCounts) {
        for (const std::int64_t correction : {0, 1}) {
          b->Args({modes, modes, correction});
          if (modes != kLargestImageModes) b->Args({modes, kLargestImageModes, correction});
        }
      }
    });

// Displacement-driven contact at c surface nodes (the patch under a tool): solve the forces
// that put them at their imposed positions, step, read each node back. r = 40 of the default
// 40-mode image with static correction (the contact compliance is then the exact static one
// plus the modal dynamics). Indentation 0.1..0.5 mm along the inward normal over a load cycle.
template <typename Scalar>
void contact_cycle(benchmark::State& state) {
  using Vector3 = Eigen::Matrix<Scalar, 3, 1>;
  const auto contact_count = static_cast<std::size_t>(state.range(0));
  auto image = duct_image(kDefaultModes);
  if (!image) {
    state.SkipWithError(image.error().message.c_str());
    return;
  }
  auto arena = core::Arena::create(kArenaBytes);
  if (!arena) {
    state.SkipWithError(arena.error().message.c_str());
    return;
  }
  auto duct = make_runtime<Scalar>(**image, *arena, kDefaultModes, true);
  if (!duct) {
    state.SkipWithError(duct.error().message.c_str());
    return;
  }
  const std::vector<std::uint32_t> near = surface_nodes_near_middle(**image);
  std::vector<std::vector<model::BasicImposedDisplacement<Scalar>>> targets(kLoadCycleSteps);
  for (std::size_t step = 0; step < kLoadCycleSteps; ++step) {
    const double depth_m = 1e-4 + 4e-4 * load_profile(step);
    for (std::size_t k = 0; k < contact_count; ++k) {
      targets[step].push_back(
          {near[k], (depth_m * inward_normal(**image, near[k])).template cast<Scalar>()});
    }
  }
  std::vector<Vector3> forces_n(contact_count, Vector3::Zero());
  core::Status first_failure = core::Status::ok();
  std::size_t step = 0;
  double allocations = 0.0;
  {
    const AllocationCount counting;
    for (auto _ : state) {
      duct->clear_forces();
      const core::Status solved = duct->solve_imposed(targets[step], forces_n);
      const core::Status stepped = duct->step();
      for (const auto& target : targets[step]) {
        Vector3 displacement_m = duct->displacement(target.node);
        benchmark::DoNotOptimize(displacement_m);
      }
      benchmark::DoNotOptimize(forces_n.data());
      benchmark::ClobberMemory();
      if (!solved && first_failure) first_failure = solved;
      if (!stepped && first_failure) first_failure = stepped;
      step = step + 1 == kLoadCycleSteps ? 0 : step + 1;
    }
    allocations = counting.counted();
  }
  if (!first_failure) {
    state.SkipWithError(first_failure.detail());
    return;
  }
  // The solved displacement must be reached: a wrong solve timed fast would mean nothing.
  const auto& last = targets[step == 0 ? kLoadCycleSteps - 1 : step - 1][0];
  const double reached_error_m =
      (duct->displacement(last.node) - last.displacement_m).template cast<double>().norm();
  if (!(reached_error_m < 1e-7)) {
    state.SkipWithError("contact node missed its imposed displacement by more than 0.1 µm");
    return;
  }
  set_size_counters(state, **image);
  state.counters["active_modes"] = static_cast<double>(duct->active_mode_count());
  state.counters["contacts"] = static_cast<double>(contact_count);
  state.counters["scalar_bytes"] = static_cast<double>(sizeof(Scalar));
  state.counters["heap_allocations_per_cycle"] =
      benchmark::Counter(allocations, benchmark::Counter::kAvgIterations);
}
void BM_ContactRowProjection(benchmark::State& state) {
  contact_cycle<float>(state);
}
BENCHMARK(BM_ContactRowProjection)->ArgName("contacts")->Arg(1)->Arg(2)->Arg(4)->Arg(8);
void BM_ContactRowProjectionDouble(benchmark::State& state) {
  contact_cycle<double>(state);
}
BENCHMARK(BM_ContactRowProjectionDouble)->ArgName("contacts")->Arg(1)->Arg(2)->Arg(4)->Arg(8);

// Graphics-rate field: every node's displacement into a 3n float buffer, with the static
// correction of the last step's load (the duct after a few steps of one nodal force).
void BM_FullReconstruction(benchmark::State& state) {
  const std::int64_t active_modes = state.range(0);
  auto image = duct_image(state.range(1));
  if (!image) {
    state.SkipWithError(image.error().message.c_str());
    return;
  }
  auto arena = core::Arena::create(kArenaBytes);
  if (!arena) {
    state.SkipWithError(arena.error().message.c_str());
    return;
  }
  auto duct = make_runtime<float>(**image, *arena, active_modes, true);
  if (!duct) {
    state.SkipWithError(duct.error().message.c_str());
    return;
  }
  const std::uint32_t node = surface_nodes_near_middle(**image).front();
  const std::vector<Eigen::Vector3f> forces = force_history<float>(**image, node);
  for (std::size_t step = 0; step < kLoadCycleSteps / 4; ++step) {
    duct->clear_forces();
    if (!duct->add_node_force(node, forces[step]) || !duct->step()) {
      state.SkipWithError("could not load the duct before reconstructing");
      return;
    }
  }
  std::vector<float> field_m(3 * static_cast<std::size_t>(duct->node_count()));
  core::Status first_failure = core::Status::ok();
  double allocations = 0.0;
  {
    const AllocationCount counting;
    for (auto _ : state) {
      const core::Status status = duct->reconstruct(field_m);
      benchmark::DoNotOptimize(field_m.data());
      benchmark::ClobberMemory();
      if (!status && first_failure) first_failure = status;
    }
    allocations = counting.counted();
  }
  if (!first_failure) {
    state.SkipWithError(first_failure.detail());
    return;
  }
  const std::size_t base = 3 * static_cast<std::size_t>(node);
  const model::Vec3 from_field(field_m[base], field_m[base + 1], field_m[base + 2]);
  const model::Vec3 exact = duct->displacement(node);
  if (!((from_field - exact).norm() <= 1e-5F * exact.norm()) || !(from_field.norm() > 0.0F)) {
    state.SkipWithError("reconstructed field disagrees with displacement() at the loaded node");
    return;
  }
  set_size_counters(state, **image);
  state.counters["active_modes"] = static_cast<double>(duct->active_mode_count());
  state.counters["heap_allocations_per_cycle"] =
      benchmark::Counter(allocations, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_FullReconstruction)
    ->ArgNames({"modes", "stored"})
    ->Apply([](benchmark::internal::Benchmark* b) {
      for (const std::int64_t modes : kModeCounts) {
        b->Args({modes, modes});
        if (modes != kLargestImageModes) b->Args({modes, kLargestImageModes});
      }
    });

// DNIOS: one full-system Newmark step (every free dof, double, one sparse back-substitution)
// + the loaded node's displacement, same load as BM_ModalStep, Rayleigh damping of the
// default 40-mode image.
void BM_DniosStep(benchmark::State& state) {
  auto image = duct_image(kDefaultModes);
  if (!image) {
    state.SkipWithError(image.error().message.c_str());
    return;
  }
  auto reference = offline::FullNewmark::create((*image)->build.shell, (*image)->build.rayleigh,
                                                (*image)->spec.time_step_s);
  if (!reference) {
    state.SkipWithError(reference.error().message.c_str());
    return;
  }
  const std::uint32_t node = surface_nodes_near_middle(**image).front();
  const std::vector<Eigen::Vector3f> forces = force_history<float>(**image, node);
  std::size_t step = 0;
  bool refused = false;
  double allocations = 0.0;
  {
    const AllocationCount counting;
    for (auto _ : state) {
      reference->clear_forces();
      const auto added =
          reference->add_node_force(static_cast<int>(node), forces[step].cast<double>());
      reference->step();
      Eigen::Vector3d displacement_m = reference->displacement(static_cast<int>(node));
      benchmark::DoNotOptimize(displacement_m);
      refused = refused || !added;
      step = step + 1 == kLoadCycleSteps ? 0 : step + 1;
    }
    allocations = counting.counted();
  }
  if (refused) {
    state.SkipWithError("DNIOS refused the nodal force");
    return;
  }
  set_size_counters(state, **image);
  state.counters["heap_allocations_per_cycle"] =
      benchmark::Counter(allocations, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_DniosStep);

// The whole offline build of the default duct definition: assembly, modes (shift-invert),
// damping, residual compliance of every surface node, truncation-error estimate. Counters:
// the build's own phase timings (ms) of the last iteration.
void BM_PrecomputeDefaultDuct(benchmark::State& state) {
  const auto& base = default_spec();
  if (!base) {
    state.SkipWithError(base.error().message.c_str());
    return;
  }
  offline::ModalBuildSpec spec = *base;
  spec.mode_count = static_cast<int>(state.range(0));
  offline::ModalBuildTimings timings;
  for (auto _ : state) {
    auto build = offline::build_modal_model(spec);
    if (!build) {
      state.SkipWithError(build.error().message.c_str());
      return;
    }
    benchmark::DoNotOptimize(build->basis.omega_squared.data());
    if (build->residual) benchmark::DoNotOptimize(build->residual->compliance.data());
    timings = build->timings;
  }
  state.counters["modes"] = static_cast<double>(spec.mode_count);
  state.counters["assembly_ms"] = 1e3 * timings.assembly_s;
  state.counters["modes_ms"] = 1e3 * timings.modes_s;
  state.counters["residual_ms"] = 1e3 * timings.residual_s;
  state.counters["error_estimate_ms"] = 1e3 * timings.error_estimate_s;
}
BENCHMARK(BM_PrecomputeDefaultDuct)
    ->ArgName("modes")
    ->Arg(kDefaultModes)
    ->Arg(kLargestImageModes)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
