// One jitter measurement: the trainer's loop with a scene's real workload on the simulated
// bench, in real time, and cyclictest at the same period, priority, CPU (or another CPU when
// both run at once), memory locking and PM QoS request, in one invocation. Everything the
// summary, the CSV files and the plot need is returned; nothing here prints.
//
// The trainer side runs the scene back to back: each run_trainer() call is one whole run as
// the trainer program would make it (scene loaded, models built or loaded, armed, stopped,
// outputs zeroed), capped at the cycles still missing, until the requested duration is
// covered. A scene whose trainee script ends the run (cbd: about 11.5 s) is thus repeated,
// so the workload stays the scripted procedure instead of a hand holding its last pose (what
// `trainer --seconds` beyond the script gives); the last run is cut at the duration. The
// loop's histograms are merged over the runs (histogram counts add).
//
// Modes: sequential = the trainer's runs, then cyclictest on the same CPU for as many loops as
// the trainer ran cycles; alongside = cyclictest started first (another CPU by default: two
// SCHED_FIFO threads of one priority on one CPU would delay each other), the trainer's runs,
// then cyclictest stopped with SIGINT, so it also measures the seconds between runs.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cyclictest.hpp"
#include "latency_distribution.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/histogram.hpp"
#include "trainer/loop/rt_settings.hpp"
#include "trainer/loop/stop_signals.hpp"

namespace trainer::tools::jitter {

enum class Mode : std::uint8_t { sequential, alongside };
const char* to_string(Mode mode) noexcept;

struct JitterOptions {
  std::filesystem::path scene_file;
  double seconds = 60.0;                 // per side (sequential) or together (alongside)
  config::LoopOverrides loop_overrides;  // period, priority, CPU over the scene's [loop]
  Mode mode = Mode::sequential;
  std::optional<int> cyclictest_cpu;      // unset: see mode; -1 = not pinned
  std::string cyclictest = "cyclictest";  // program name or path
  std::int64_t histogram_limit_us = 0;    // cyclictest -h; 0 = max(20000, 20 periods)
  std::filesystem::path out_dir = "out/jitter";
};

// What the loop and cyclictest ran with, after the overrides and the CPU choice.
struct EffectiveSettings {
  std::filesystem::path scene_file;  // as given
  std::string scene_name;
  std::int64_t period_ns = 0;
  int priority = 0;
  int cpu = -1;
  int cyclictest_cpu = -1;
  bool lock_memory = false;
  int cpu_dma_latency_us = -1;
  std::int64_t histogram_limit_us = 0;
  std::uint64_t target_cycles = 0;  // the duration in periods
};

struct TrainerRunRecord {  // one run_trainer() call
  std::uint64_t cycles = 0;
  double wall_time_s = 0.0;
  std::uint64_t overruns = 0;
  std::uint32_t longest_overrun_streak = 0;
  std::uint32_t latched_faults = 0;
  std::string first_fault;
  std::filesystem::path report_file;  // that run's trainer report (docs/report.md)
};

struct TrainerSide {
  std::vector<TrainerRunRecord> runs;
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;
  std::uint32_t longest_overrun_streak = 0;  // longest in any one run
  std::uint64_t skipped_periods = 0;
  std::uint64_t cycle_errors = 0;
  std::uint64_t heap_allocations_after_arming = 0;
  std::uint32_t faulted_runs = 0;
  double loop_time_s = 0.0;     // sum of the runs' wall times
  double elapsed_time_s = 0.0;  // first run's start to last run's end, setup between included
  bool stopped_by_signal = false;
  loop::RtReport rt;  // as the first run obtained it; warnings of every run, once each
  // Merged over the runs; heap-held (each is about 10 KiB of bins).
  std::unique_ptr<core::LatencyHistogram> wake_latency = std::make_unique<core::LatencyHistogram>();
  std::unique_ptr<core::LatencyHistogram> step_time = std::make_unique<core::LatencyHistogram>();
};

struct CyclictestSide {
  std::vector<std::string> arguments;
  int exit_status = 0;
  bool interrupted = false;  // stopped with SIGINT (alongside, or jitter was interrupted)
  CyclictestHistogram histogram;
  std::filesystem::path histogram_file;
  std::filesystem::path output_file;
};

struct JitterMeasurement {
  EffectiveSettings settings;
  Mode mode = Mode::sequential;
  double requested_seconds = 0.0;
  TrainerSide trainer;
  CyclictestSide cyclictest;
  std::string started_utc;                 // ISO 8601
  std::vector<double> load_average_start;  // 1, 5, 15 min (/proc/loadavg)
  std::vector<double> load_average_end;
  std::string kernel_release;
  std::string kernel_version;
  bool preempt_rt = false;
  int online_cpus = 0;
  std::vector<std::string> warnings;
  bool stopped_by_signal = false;
};

// Runs both sides. Errors: scene or override refused, CPU not available, cyclictest missing,
// failing or writing an unreadable histogram, output directory not writable.
core::Expected<JitterMeasurement> measure(const JitterOptions& options, loop::StopSignals& signals);

}  // namespace trainer::tools::jitter
