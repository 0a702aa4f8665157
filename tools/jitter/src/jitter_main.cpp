// `jitter`: the timing acceptance test. Runs the trainer's loop with a scene's real workload
// on the simulated bench in real time and cyclictest at the same period, priority and CPU in
// one invocation, then writes both latency histograms (CSV), cyclictest's raw output, a JSON
// summary with the trainer/cyclictest percentile ratios, and a plot (docs/timing.md).
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>

#include <CLI/CLI.hpp>

#include "jitter_plot.hpp"
#include "jitter_run.hpp"
#include "jitter_summary.hpp"
#include "trainer/loop/stop_signals.hpp"

namespace {

using namespace trainer::tools::jitter;

constexpr int kExitSetupError = 1;
constexpr int kExitFaultLatched = 3;
constexpr int kExitAcceptanceFailed = 4;

bool write_file(const std::filesystem::path& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  out.close();
  if (!out) std::cerr << "jitter: cannot write " << file.string() << "\n";
  return static_cast<bool>(out);
}

std::string us_text(double value_us) {
  char text[32];
  std::snprintf(text, sizeof text, value_us < 100.0 ? "%.1f" : "%.0f", value_us);
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  // Before any thread exists: SIGINT/SIGTERM stay pending until jitter collects them, so an
  // interrupted measurement still stops cyclictest and writes what it has.
  trainer::loop::StopSignals signals;

  CLI::App cli{
      "jitter: the trainer's wake-up latency under a scene's real workload, side by "
      "side with cyclictest at the same period, priority and CPU"};
  JitterOptions options;
  AcceptanceCriteria criteria;
  std::string mode = "sequential";
  std::string gnuplot = "gnuplot";
  std::string ratio_at = "p99,p99.9";
  std::int64_t period_us = 0;
  int priority = 0;
  int cpu = -1;
  int cyclictest_cpu = -1;
  double max_ratio = 0.0;
  std::uint64_t max_overruns = 0;

  cli.add_option("--scene", options.scene_file, "Scene file (TOML), e.g. config/scenes/cbd.toml")
      ->required()
      ->check(CLI::ExistingFile);
  cli.add_option("--seconds", options.seconds,
                 "Duration of each side (sequential) or of both together (alongside)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  auto* period_opt = cli.add_option("--period-us", period_us,
                                    "Loop and cyclictest period (default: loop.period_us)");
  auto* priority_opt =
      cli.add_option("--priority", priority,
                     "SCHED_FIFO priority of both, 0 = SCHED_OTHER (default: loop.priority)");
  auto* cpu_opt =
      cli.add_option("--cpu", cpu, "CPU of the loop, -1 = not pinned (default: loop.cpu)");
  cli.add_option("--mode", mode,
                 "sequential: the trainer, then cyclictest on the same CPU; alongside: both at "
                 "once, cyclictest on another CPU")
      ->capture_default_str()
      ->check(CLI::IsMember({"sequential", "alongside"}));
  auto* cyclictest_cpu_opt = cli.add_option(
      "--cyclictest-cpu", cyclictest_cpu,
      "CPU of cyclictest, -1 = not pinned (default: the loop's CPU when sequential, another "
      "CPU when alongside)");
  cli.add_option("--out", options.out_dir, "Output directory")->capture_default_str();
  auto* max_ratio_opt = cli.add_option(
      "--max-ratio", max_ratio,
      "Fail (exit 4) when a trainer/cyclictest wake-up latency ratio at --ratio-at exceeds this");
  max_ratio_opt->check(CLI::PositiveNumber);
  cli.add_option("--ratio-at", ratio_at,
                 "Comma-separated percentiles --max-ratio checks: p50, p90, p99, p99.9, max")
      ->capture_default_str();
  auto* max_overruns_opt = cli.add_option("--max-overruns", max_overruns,
                                          "Fail (exit 4) when the trainer overruns more often");
  cli.add_option("--histogram-us", options.histogram_limit_us,
                 "cyclictest histogram range in us (default: max(20000, 2 periods))")
      ->check(CLI::PositiveNumber);
  cli.add_option("--cyclictest", options.cyclictest, "cyclictest program")->capture_default_str();
  cli.add_option("--gnuplot", gnuplot, "gnuplot program")->capture_default_str();
  cli.footer(
      "A scene whose trainee script ends the run (cbd) is run back to back until the duration "
      "is covered; the last run is cut at it.\nExit status: 0 measured (and within the "
      "acceptance limits given), 1 setup or measurement error (also: stopped by a signal), 2 "
      "usage error, 3 a trainer run latched a fault, 4 an acceptance limit was exceeded.");
  CLI11_PARSE(cli, argc, argv);

  if (*period_opt) options.loop_overrides.period_us = period_us;
  if (*priority_opt) options.loop_overrides.priority = priority;
  if (*cpu_opt) options.loop_overrides.cpu = cpu;
  if (*cyclictest_cpu_opt) options.cyclictest_cpu = cyclictest_cpu;
  options.mode = mode == "alongside" ? Mode::alongside : Mode::sequential;
  if (*max_ratio_opt) criteria.max_ratio = max_ratio;
  if (*max_overruns_opt) criteria.max_overruns = max_overruns;
  criteria.ratio_at.clear();
  std::stringstream names(ratio_at);
  for (std::string name; std::getline(names, name, ',');) {
    if (auto known = percentile_by_name(PercentileSet{}, name); !known) {
      std::cerr << "jitter: --ratio-at: " << known.error().message << "\n";
      return static_cast<int>(CLI::ExitCodes::ValidationError);
    }
    criteria.ratio_at.push_back(name);
  }

  auto measurement = measure(options, signals);
  if (!measurement) {
    std::cerr << "jitter: " << measurement.error().message << "\n";
    return kExitSetupError;
  }
  const Comparison comparison = compare(*measurement);
  auto verdict = evaluate_acceptance(criteria, comparison.ratios, measurement->trainer.overruns);
  if (!verdict) {
    std::cerr << "jitter: " << verdict.error().message << "\n";
    return kExitSetupError;
  }

  const std::filesystem::path& out = options.out_dir;
  bool written = write_file(out / "trainer_wake_latency.csv", comparison.trainer_wake.to_csv()) &&
                 write_file(out / "trainer_step_time.csv", comparison.trainer_step.to_csv()) &&
                 write_file(out / "cyclictest_latency.csv", comparison.cyclictest.to_csv());

  const EffectiveSettings& s = measurement->settings;
  PlotLabels labels;
  labels.title =
      "scene '" + s.scene_name + "', period " + us_text(static_cast<double>(s.period_ns) / 1000.0) +
      " µs, " + (s.priority > 0 ? "SCHED_FIFO " + std::to_string(s.priority) : "SCHED_OTHER") +
      ", cpu " + std::to_string(s.cpu) + " / " + std::to_string(s.cyclictest_cpu) + ", " +
      to_string(measurement->mode) + "\n" + "kernel " + measurement->kernel_release +
      (measurement->preempt_rt ? " (PREEMPT_RT)" : " (not PREEMPT_RT)") + ", " +
      measurement->started_utc;
  labels.trainer_key = "trainer (" + std::to_string(comparison.trainer_wake.count()) +
                       " cycles): p99 " + us_text(comparison.trainer_wake_us.p99_us) +
                       " µs, p99.9 " + us_text(comparison.trainer_wake_us.p99_9_us) + " µs";
  labels.cyclictest_key = "cyclictest (" + std::to_string(comparison.cyclictest.count()) +
                          " loops): p99 " + us_text(comparison.cyclictest_us.p99_us) +
                          " µs, p99.9 " + us_text(comparison.cyclictest_us.p99_9_us) + " µs";
  written = written &&
            write_file(out / "jitter_plot.dat",
                       plot_data(comparison.trainer_wake, comparison.cyclictest)) &&
            write_file(out / "jitter.gp",
                       plot_script(comparison.trainer_wake, comparison.cyclictest, labels));
  std::string plot_status = "jitter.png";
  if (written) {
    if (auto plotted = run_gnuplot(gnuplot, out); !plotted) {
      plot_status = "not drawn: " + plotted.error().message;
      measurement->warnings.push_back("plot " + plot_status);
    }
  }

  const nlohmann::json summary =
      summary_json(*measurement, comparison, criteria, *verdict, plot_status);
  written = written && write_file(out / "summary.json", summary.dump(2) + "\n");
  std::cout << summary_text(*measurement, comparison, *verdict);
  std::cout << "  written: " << out.string()
            << "/{summary.json, trainer_wake_latency.csv, trainer_step_time.csv, "
               "cyclictest_latency.csv, cyclictest_histogram.txt, cyclictest_output.txt, "
               "trainer_run_*.json, jitter_plot.dat, jitter.gp"
            << (plot_status == "jitter.png" ? ", jitter.png}" : "}") << "\n";
  if (!written) return kExitSetupError;
  if (measurement->stopped_by_signal) return kExitSetupError;
  if (!verdict->passed) {
    for (const std::string& violation : verdict->violations) {
      std::cerr << "jitter: acceptance failed: " << violation << "\n";
    }
    return kExitAcceptanceFailed;
  }
  if (measurement->trainer.faulted_runs > 0) return kExitFaultLatched;
  return 0;
}
