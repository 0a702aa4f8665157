// trainer --repeat N: the same simulated-time session N times, folded into the per-cycle
// minimum compute (compute_trace.hpp says why).
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "trainer/app/compute_trace.hpp"
#include "trainer/app/trainer_run.hpp"

namespace trainer::app {
namespace {

std::string hash_text(std::uint64_t hash) {
  char text[24];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

// What makes two runs of a session the same run; "" when they are.
std::string repeat_mismatch(const RunResult& first, const RunResult& run) {
  if (run.loop.cycles != first.loop.cycles) {
    return "cycles " + std::to_string(run.loop.cycles) + " vs " + std::to_string(first.loop.cycles);
  }
  if (run.final_state_hash != first.final_state_hash) {
    return "final state hash " + hash_text(run.final_state_hash) + " vs " +
           hash_text(first.final_state_hash);
  }
  if (run.latched_faults != first.latched_faults || run.first_fault != first.first_fault) {
    return "latched faults " + std::to_string(run.latched_faults) + " (" + run.first_fault +
           ") vs " + std::to_string(first.latched_faults) + " (" + first.first_fault + ")";
  }
  if (run.app.armed_cycles != first.app.armed_cycles) {
    return "armed cycles " + std::to_string(run.app.armed_cycles) + " vs " +
           std::to_string(first.app.armed_cycles);
  }
  return {};
}

}  // namespace

core::Expected<RunResult> run_trainer_repeated(const RunOptions& options, std::uint32_t runs) {
  if (runs < 1 || runs > kMaxRepeatRuns) {
    return core::make_error("--repeat " + std::to_string(runs) + ": expected 1 to " +
                            std::to_string(kMaxRepeatRuns) + " runs");
  }
  if (options.time_source != TimeSource::simulated) {
    return core::make_error(
        "--repeat needs --time simulated: only a simulated-time session is the same session "
        "in every run (a real-time run depends on the machine's timing)");
  }
  if (runs > 1 && options.record_file) {
    return core::make_error("--repeat " + std::to_string(runs) +
                            " cannot record the session (each run would overwrite the "
                            "recording): use --no-record, or --repeat 1");
  }
  CycleTimeTrace trace;
  auto minimum_trace = std::make_shared<CycleTimeTrace>();
  CycleTimeTrace& minimum = *minimum_trace;
  std::vector<ComputeRun> per_run;
  std::optional<RunResult> first;
  std::optional<RunResult> last;
  std::string mismatch;
  RunOptions run_options = options;
  run_options.compute_trace = &trace;
  for (std::uint32_t run = 0; run < runs; ++run) {
    auto result = run_trainer(run_options);
    if (!result) {
      return core::make_error("run " + std::to_string(run + 1) + " of " + std::to_string(runs) +
                              ": " + result.error().message);
    }
    if (result->stopped_by_signal) {  // incomplete: not folded, and the series ends
      if (!last) last = std::move(*result);
      break;
    }
    const auto cycles = static_cast<std::size_t>(result->loop.cycles);
    ComputeRun summary;
    summary.cycles = result->loop.cycles;
    summary.final_state_hash = result->final_state_hash;
    summary.wall_time_s = result->wall_time_s;
    summary.step =
        compute_statistics("step", trace.step_ns().first(std::min(cycles, trace.cycles())));
    per_run.push_back(std::move(summary));
    if (!first) {
      first = *result;
    } else if (mismatch.empty()) {
      const std::string differs = repeat_mismatch(*first, *result);
      if (!differs.empty())
        mismatch = "run " + std::to_string(run + 1) + " differs from run 1: " + differs;
    }
    minimum.fold_minimum(trace, cycles);
    last = std::move(*result);
  }
  if (minimum.folds() > 0) {
    ComputeSummary compute =
        summarize_compute(minimum, static_cast<std::size_t>(first->loop.cycles), last->app);
    compute.period_ns = last->period_ns;
    compute.identical = mismatch.empty();
    compute.mismatch = mismatch;
    compute.per_run = std::move(per_run);
    compute.per_cycle_minimum = std::move(minimum_trace);
    last->compute = std::move(compute);
  }
  return std::move(*last);
}

}  // namespace trainer::app
