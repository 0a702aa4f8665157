// Speed of the particle catheter (model::Catheter, Basdogan eq. 27–28, METHODS.md §2) with the
// default catheter's parameters (config/models/catheter.toml as the trainer reads it) against
// the particle count N: one haptic period (1 ms, all of its substeps: the count grows with N,
// since the stable substep shrinks as the segments get shorter and lighter) and one substep
// alone. docs/performance.md reports these numbers.
//
// Load: root clamped at the introducer (as the scene holds it), gravity as m·g per particle and
// a tip force of F L²/EI = 1 that turns once a second, so the chain stays bent and moving
// (a straight chain at rest takes the small-angle branch of the bending gradient and would time
// a path a trainee never sees).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

#include <Eigen/Core>

#include "trainer/config/model.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/model/catheter.hpp"

namespace {

using namespace trainer;

constexpr double kPeriodS = 1e-3;               // the scene's 1 kHz loop
constexpr std::uint32_t kBudget = 1000;         // large enough for N = 161 (384 substeps)
constexpr std::size_t kArenaBytes = 128 * 1024;  // 161 particles: ≈ 14 kB state + 28 kB solve
constexpr int kLoadCycleSteps = 1000;           // the tip load turns once per 1000 periods

const core::Expected<config::ModelDefinition>& default_catheter() {
  static const core::Expected<config::ModelDefinition> definition = config::load_model_definition(
      std::string(TRAINER_SOURCE_DIR) + "/config/models/catheter.toml");
  return definition;
}

// Heap allocations made by this thread while the object lives (the RT path must make none).
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

struct Bench {
  core::Arena arena;
  model::Catheter catheter;
  Eigen::Vector3f gravity_force_n;
  float tip_force_n;
};

core::Expected<Bench> make_catheter(std::uint32_t particle_count) {
  const auto& definition = default_catheter();
  if (!definition) return definition.error();
  const config::CatheterConfig& c = definition->catheter;
  model::CatheterParams params;
  params.length_m = static_cast<float>(c.length_m);
  params.outer_radius_m = static_cast<float>(c.outer_radius_m);
  params.bending_stiffness_n_m2 = static_cast<float>(c.bending_stiffness_n_m2);
  params.axial_stiffness_n = static_cast<float>(c.axial_stiffness_n);
  params.linear_density_kg_per_m = static_cast<float>(c.linear_density_kg_per_m);
  params.damping_n_s_per_m = static_cast<float>(c.damping_n_s_per_m);
  params.particle_count = particle_count;
  params.contact_stiffness_n_per_m = model::catheter_contact_stiffness(
      static_cast<float>(c.wall_stiffness_n_per_m), static_cast<float>(c.tool_stiffness_n_per_m));
  model::CatheterSetup setup;
  setup.haptic_period_s = static_cast<float>(kPeriodS);
  setup.max_substeps = kBudget;
  auto arena = core::Arena::create(kArenaBytes);
  if (!arena) return std::move(arena).error();
  auto catheter = model::Catheter::create(params, setup, *arena);
  if (!catheter) return std::move(catheter).error();
  catheter->clamp_start(true);
  const float tip_force_n = static_cast<float>(c.bending_stiffness_n_m2 / (c.length_m * c.length_m));
  const Eigen::Vector3f gravity_force_n = catheter->particle_mass_kg() * Eigen::Vector3f(0.0F, 0.0F, -9.81F);
  return Bench{std::move(*arena), std::move(*catheter), gravity_force_n, tip_force_n};
}

// One cycle's forces: clear, m·g on every particle, the turning tip force.
core::Status load(Bench& bench, int step) noexcept {
  model::Catheter& catheter = bench.catheter;
  catheter.clear_forces();
  core::Status status = core::Status::ok();
  for (std::uint32_t i = 0; i < catheter.particle_count(); ++i) {
    const core::Status added = catheter.add_force(i, bench.gravity_force_n);
    if (!added && status) status = added;
  }
  const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(step) /
                      static_cast<float>(kLoadCycleSteps);
  const Eigen::Vector3f tip(0.0F, bench.tip_force_n * std::cos(angle), bench.tip_force_n * std::sin(angle));
  const core::Status added = catheter.add_force(catheter.particle_count() - 1, tip);
  if (!added && status) status = added;
  return status;
}

// `timed_period_s` = one haptic period (all its substeps), or one stable substep (exactly one)
// when negative.
void run(benchmark::State& state, double timed_period_s) {
  const bool one_substep = timed_period_s < 0.0;
  auto bench = make_catheter(static_cast<std::uint32_t>(state.range(0)));
  if (!bench) {
    state.SkipWithError(bench.error().message.c_str());
    return;
  }
  model::Catheter& catheter = bench->catheter;
  const float period_s = one_substep ? catheter.stable_substep_s() : static_cast<float>(timed_period_s);
  const auto substeps =
      model::Catheter::substeps_for(static_cast<double>(period_s), static_cast<double>(catheter.stable_substep_s()));
  // Bend it first (one load cycle), so the timed state is a moving, bent chain.
  for (int step = 0; step < kLoadCycleSteps; ++step) {
    (void)load(*bench, step);
    (void)catheter.step(static_cast<float>(kPeriodS));
  }
  core::Status first_failure = core::Status::ok();
  int step = 0;
  double allocations = 0.0;
  {
    const AllocationCount counting;
    for (auto _ : state) {
      const core::Status loaded = load(*bench, step);
      const core::Status stepped = catheter.step(period_s);
      benchmark::DoNotOptimize(catheter.positions_m().back());
      if (!loaded && first_failure) first_failure = loaded;
      if (!stepped && first_failure) first_failure = stepped;
      step = step + 1 == kLoadCycleSteps ? 0 : step + 1;
    }
    allocations = counting.counted();
  }
  if (!first_failure) {
    state.SkipWithError(first_failure.detail());
    return;
  }
  const Eigen::Vector3f tip = catheter.positions_m().back();
  if (!tip.allFinite()) {
    state.SkipWithError("catheter state not finite after the run");
    return;
  }
  const auto iterations = static_cast<double>(state.iterations());
  state.counters["particles"] = static_cast<double>(catheter.particle_count());
  state.counters["substeps"] = static_cast<double>(substeps);
  state.counters["stable_substep_us"] = 1e6 * static_cast<double>(catheter.stable_substep_s());
  // CPU time per substep: total CPU time / (iterations × substeps), in seconds.
  state.counters["time_per_substep"] = benchmark::Counter(
      iterations * static_cast<double>(substeps), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["heap_allocations_per_cycle"] =
      benchmark::Counter(allocations, benchmark::Counter::kAvgIterations);
}

// One haptic period of 1 ms: the trainer's per-cycle catheter cost (loads included).
void BM_CatheterPeriod(benchmark::State& state) { run(state, kPeriodS); }
BENCHMARK(BM_CatheterPeriod)->ArgName("particles")->Arg(11)->Arg(21)->Arg(41)->Arg(81)->Arg(161)
    ->Unit(benchmark::kMicrosecond);

// One substep alone (step() over exactly one stable substep; loads included).
void BM_CatheterSubstep(benchmark::State& state) { run(state, -1.0); }
BENCHMARK(BM_CatheterSubstep)->ArgName("particles")->Arg(11)->Arg(21)->Arg(41)->Arg(81)->Arg(161);

// One 100 µs period (a 10 kHz loop; the chain was bent at 1 ms periods first).
void BM_CatheterPeriod100us(benchmark::State& state) { run(state, 1e-4); }
BENCHMARK(BM_CatheterPeriod100us)->ArgName("particles")->Arg(11)->Arg(21)->Arg(41);

}  // namespace

BENCHMARK_MAIN();
