#include "jitter_run.hpp"

#include <sched.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <sstream>
#include <thread>

#include "child_process.hpp"
#include "trainer/app/report.hpp"
#include "trainer/app/trainer_run.hpp"

namespace trainer::tools::jitter {

namespace {

constexpr std::int64_t kDefaultHistogramLimitUs = 20000;
constexpr std::int64_t kSignalPollNs = 50'000'000;
// cyclictest's measurement thread appears within milliseconds; allow for a loaded machine.
constexpr std::chrono::seconds kCyclictestStartTimeout{5};

std::vector<double> load_average() {
  std::ifstream file("/proc/loadavg");
  std::vector<double> values(3, 0.0);
  for (double& value : values) file >> value;
  if (!file) return {};
  return values;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::vector<int> allowed_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  std::vector<int> cpus;
  if (sched_getaffinity(0, sizeof set, &set) != 0) return cpus;
  for (std::size_t cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
    if (CPU_ISSET(cpu, &set)) cpus.push_back(static_cast<int>(cpu));
  }
  return cpus;
}

std::string cpu_list(const std::vector<int>& cpus) {
  std::string text;
  for (const int cpu : cpus) {
    if (!text.empty()) text += ',';
    text += std::to_string(cpu);
  }
  return text;
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The last lines of a child's output, for an error message.
std::string tail_of(const std::filesystem::path& file) {
  constexpr std::size_t kTailChars = 600;
  std::string text = read_text(file);
  if (text.size() > kTailChars) text = "..." + text.substr(text.size() - kTailChars);
  while (!text.empty() && text.back() == '\n') text.pop_back();
  return text;
}

core::Expected<EffectiveSettings> effective_settings(const JitterOptions& options,
                                                     const std::vector<int>& cpus,
                                                     std::vector<std::string>& warnings) {
  auto scene = config::load_scene(options.scene_file);
  if (!scene) return std::move(scene).error();
  if (auto applied = config::apply_loop_overrides(scene->loop, options.loop_overrides); !applied) {
    return std::move(applied).error();
  }
  if (!(options.seconds > 0.0) || !std::isfinite(options.seconds)) {
    return core::make_error("--seconds must be a positive number of seconds");
  }
  EffectiveSettings settings;
  settings.scene_file = options.scene_file;
  settings.scene_name = scene->name;
  settings.period_ns = scene->loop.period_ns;
  settings.priority = scene->loop.priority;
  settings.cpu = scene->loop.cpu;
  settings.lock_memory = scene->loop.lock_memory;
  settings.cpu_dma_latency_us = scene->loop.cpu_dma_latency_us;
  settings.target_cycles = static_cast<std::uint64_t>(
      std::ceil(options.seconds * 1e9 / static_cast<double>(settings.period_ns)));

  const auto available = [&](int cpu) {
    return cpu < 0 || std::find(cpus.begin(), cpus.end(), cpu) != cpus.end();
  };
  if (!available(settings.cpu)) {
    return core::make_error("cpu " + std::to_string(settings.cpu) +
                            " is not available to this process (allowed: " + cpu_list(cpus) +
                            "); give --cpu or change loop.cpu");
  }
  if (options.cyclictest_cpu) {
    settings.cyclictest_cpu = *options.cyclictest_cpu;
    if (!available(settings.cyclictest_cpu)) {
      return core::make_error("--cyclictest-cpu " + std::to_string(settings.cyclictest_cpu) +
                              " is not available to this process (allowed: " + cpu_list(cpus) +
                              ")");
    }
  } else if (options.mode == Mode::sequential) {
    settings.cyclictest_cpu = settings.cpu;
  } else {
    const auto other =
        std::find_if(cpus.begin(), cpus.end(), [&](int cpu) { return cpu != settings.cpu; });
    if (settings.cpu < 0) {
      warnings.push_back(
          "alongside with an unpinned loop: cyclictest is not pinned either, both may share a "
          "CPU; give --cpu and --cyclictest-cpu");
    } else if (other == cpus.end()) {
      return core::make_error(
          "alongside needs a second CPU for cyclictest and this process may only use cpu " +
          cpu_list(cpus) + "; give --cyclictest-cpu to share it, or use --mode sequential");
    } else {
      settings.cyclictest_cpu = *other;
    }
  }
  if (options.mode == Mode::alongside && settings.cpu >= 0 &&
      settings.cyclictest_cpu == settings.cpu && settings.priority > 0) {
    warnings.push_back(
        "alongside on one CPU at one SCHED_FIFO priority: the trainer and cyclictest delay "
        "each other, so both distributions include the other's run time");
  }
  const std::int64_t period_us = settings.period_ns / kNanosecondsPerMicrosecond;
  settings.histogram_limit_us = options.histogram_limit_us > 0
                                    ? options.histogram_limit_us
                                    : std::max(kDefaultHistogramLimitUs, 2 * period_us);
  return settings;
}

CyclictestSettings cyclictest_settings(const JitterOptions& options,
                                       const EffectiveSettings& settings, std::uint64_t loops,
                                       const std::filesystem::path& histogram_file) {
  CyclictestSettings cyclictest;
  cyclictest.executable = options.cyclictest;
  cyclictest.period_us = settings.period_ns / kNanosecondsPerMicrosecond;
  cyclictest.priority = settings.priority;
  cyclictest.cpu = settings.cyclictest_cpu;
  cyclictest.lock_memory = settings.lock_memory;
  cyclictest.cpu_dma_latency_us = settings.cpu_dma_latency_us;
  cyclictest.loops = loops;
  cyclictest.histogram_limit_us = settings.histogram_limit_us;
  cyclictest.histogram_file = histogram_file.string();
  return cyclictest;
}

// The trainer's runs, back to back until target_cycles are covered or a stop signal.
core::Expected<TrainerSide> run_trainer_side(const JitterOptions& options,
                                             const EffectiveSettings& settings,
                                             loop::StopSignals& signals) {
  TrainerSide side;
  std::ofstream log(options.out_dir / "trainer_log.txt");
  const auto start = std::chrono::steady_clock::now();
  while (side.cycles < settings.target_cycles) {
    if (signals.wait_for(0) != 0) {
      side.stopped_by_signal = true;
      break;
    }
    app::RunOptions run;
    run.scene_file = options.scene_file;
    run.max_cycles = settings.target_cycles - side.cycles;
    run.loop_overrides = options.loop_overrides;
    run.on_log = [&log](const std::string& line) { log << line << '\n'; };
    auto result = app::run_trainer(run);
    if (!result) return std::move(result).error();

    TrainerRunRecord record;
    record.cycles = result->loop.cycles;
    record.wall_time_s = result->wall_time_s;
    record.overruns = result->loop.overruns;
    record.longest_overrun_streak = result->loop.longest_overrun_streak;
    record.latched_faults = result->latched_faults;
    record.first_fault = result->first_fault;
    record.report_file =
        options.out_dir / ("trainer_run_" + std::to_string(side.runs.size() + 1) + ".json");
    std::ofstream report(record.report_file);
    report << app::report_json(*result).dump(2) << '\n';
    if (!report) return core::make_error("cannot write " + record.report_file.string());

    if (side.runs.empty()) {
      side.rt = result->rt;
    } else {
      for (const std::string& warning : result->rt.warnings) {
        if (std::find(side.rt.warnings.begin(), side.rt.warnings.end(), warning) ==
            side.rt.warnings.end()) {
          side.rt.warnings.push_back(warning);
        }
      }
    }
    side.runs.push_back(record);
    side.cycles += result->loop.cycles;
    side.overruns += result->loop.overruns;
    side.longest_overrun_streak =
        std::max(side.longest_overrun_streak, result->loop.longest_overrun_streak);
    side.skipped_periods += result->loop.skipped_periods;
    side.cycle_errors += result->loop.cycle_errors;
    side.heap_allocations_after_arming += result->heap_allocations_after_arming;
    if (result->latched_faults != 0) ++side.faulted_runs;
    side.loop_time_s += result->wall_time_s;
    side.wake_latency->merge(result->loop.wake_latency);
    side.step_time->merge(result->loop.step_time);
    if (result->stopped_by_signal) {
      side.stopped_by_signal = true;
      break;
    }
    if (result->loop.cycles == 0) {
      return core::make_error("a trainer run of scene '" + settings.scene_name +
                              "' ran no cycles; cannot cover the duration");
    }
  }
  side.elapsed_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return side;
}

// Waits for cyclictest to end by itself; a stop signal to jitter is passed on as SIGINT.
int wait_for_cyclictest(ChildProcess& child, loop::StopSignals& signals, bool& interrupted) {
  while (true) {
    if (const auto status = child.poll()) return *status;
    if (signals.wait_for(kSignalPollNs) != 0) {
      interrupted = true;
      child.interrupt();
      return child.wait();
    }
  }
}

core::Expected<void> finish_cyclictest(CyclictestSide& side, int exit_status) {
  side.exit_status = exit_status;
  if (exit_status != 0) {
    return core::make_error("cyclictest exited with status " + std::to_string(exit_status) + " (" +
                            side.output_file.string() + "):\n" + tail_of(side.output_file) +
                            "\ncyclictest needs root, or an RLIMIT_RTPRIO above 0 and the "
                            "memlock limit for -m (e.g. the 'realtime' group in limits.conf)");
  }
  auto parsed =
      parse_cyclictest_histogram(read_text(side.histogram_file), side.histogram_file.string());
  if (!parsed) return std::move(parsed).error();
  side.histogram = std::move(*parsed);
  return {};
}

}  // namespace

const char* to_string(Mode mode) noexcept {
  return mode == Mode::alongside ? "alongside" : "sequential";
}

core::Expected<JitterMeasurement> measure(const JitterOptions& options,
                                          loop::StopSignals& signals) {
  JitterMeasurement measurement;
  measurement.mode = options.mode;
  measurement.requested_seconds = options.seconds;
  const std::vector<int> cpus = allowed_cpus();
  measurement.online_cpus = static_cast<int>(sysconf(_SC_NPROCESSORS_ONLN));
  auto settings = effective_settings(options, cpus, measurement.warnings);
  if (!settings) return std::move(settings).error();
  measurement.settings = *settings;

  if (!find_executable(options.cyclictest)) {
    return core::make_error("cyclictest ('" + options.cyclictest +
                            "') not found: install Debian's rt-tests package "
                            "(tools/install-deps.sh) or give --cyclictest PATH");
  }
  std::error_code error;
  std::filesystem::create_directories(options.out_dir, error);
  if (error) {
    return core::make_error("cannot create output directory " + options.out_dir.string() + ": " +
                            error.message());
  }
  // An earlier measurement in the same directory may have had more runs: never mix reports.
  for (std::filesystem::directory_iterator it(options.out_dir, error), end; !error && it != end;
       it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.starts_with("trainer_run_") && name.ends_with(".json")) {
      std::error_code ignored;
      std::filesystem::remove(it->path(), ignored);
    }
  }

  utsname names{};
  if (uname(&names) == 0) {
    measurement.kernel_release = names.release;
    measurement.kernel_version = names.version;
  }
  measurement.preempt_rt = loop::kernel_is_preempt_rt();
  measurement.started_utc = utc_now();
  measurement.load_average_start = load_average();

  CyclictestSide& cyclictest = measurement.cyclictest;
  cyclictest.histogram_file =
      std::filesystem::absolute(options.out_dir / "cyclictest_histogram.txt");
  cyclictest.output_file = std::filesystem::absolute(options.out_dir / "cyclictest_output.txt");
  std::filesystem::remove(cyclictest.histogram_file, error);

  if (options.mode == Mode::alongside) {
    cyclictest.arguments =
        cyclictest_arguments(cyclictest_settings(options, *settings, 0, cyclictest.histogram_file));
    auto child = ChildProcess::start(cyclictest.arguments, cyclictest.output_file);
    if (!child) return std::move(child).error();
    // Measuring once its timer thread exists (main thread + one measurement thread).
    const auto deadline = std::chrono::steady_clock::now() + kCyclictestStartTimeout;
    while (child->thread_count() < 2 && std::chrono::steady_clock::now() < deadline) {
      if (const auto status = child->poll()) {
        if (auto finished = finish_cyclictest(cyclictest, *status); !finished) {
          return std::move(finished).error();
        }
        return core::make_error("cyclictest ended before the trainer started:\n" +
                                tail_of(cyclictest.output_file));
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (child->thread_count() < 2) {
      measurement.warnings.push_back(
          "cyclictest's measurement thread was not seen within 5 s of its start; the trainer "
          "started anyway");
    }
    auto trainer = run_trainer_side(options, *settings, signals);
    cyclictest.interrupted = true;
    child->interrupt();
    const int status = child->wait();
    if (!trainer) return std::move(trainer).error();
    measurement.trainer = std::move(*trainer);
    if (auto finished = finish_cyclictest(cyclictest, status); !finished) {
      return std::move(finished).error();
    }
  } else {
    auto trainer = run_trainer_side(options, *settings, signals);
    if (!trainer) return std::move(trainer).error();
    measurement.trainer = std::move(*trainer);
    if (measurement.trainer.stopped_by_signal || measurement.trainer.cycles == 0) {
      return core::make_error(
          "stopped by a signal during the trainer's runs, before cyclictest ran: nothing to "
          "compare (each finished run's report is in " +
          options.out_dir.string() + ")");
    }
    cyclictest.arguments = cyclictest_arguments(cyclictest_settings(
        options, *settings, measurement.trainer.cycles, cyclictest.histogram_file));
    auto child = ChildProcess::start(cyclictest.arguments, cyclictest.output_file);
    if (!child) return std::move(child).error();
    const int status = wait_for_cyclictest(*child, signals, cyclictest.interrupted);
    if (auto finished = finish_cyclictest(cyclictest, status); !finished) {
      return std::move(finished).error();
    }
  }
  measurement.stopped_by_signal = measurement.trainer.stopped_by_signal ||
                                  (options.mode == Mode::sequential && cyclictest.interrupted);
  measurement.load_average_end = load_average();

  if (measurement.stopped_by_signal) {
    measurement.warnings.push_back("stopped by a signal: the measurement is shorter than asked");
  }
  if (measurement.trainer.faulted_runs > 0) {
    measurement.warnings.push_back(
        std::to_string(measurement.trainer.faulted_runs) +
        " trainer run(s) latched a fault; after a fault the loop keeps running with zero "
        "outputs, so the rest of that run is not the scene's full workload");
  }
  if (cyclictest.histogram.overflows > 0) {
    measurement.warnings.push_back("cyclictest: " + std::to_string(cyclictest.histogram.overflows) +
                                   " samples above its histogram limit of " +
                                   std::to_string(settings->histogram_limit_us) +
                                   " us; a percentile falling among them is reported as its max");
  }
  if (!measurement.preempt_rt) {
    measurement.warnings.push_back(
        "kernel " + measurement.kernel_release +
        " is not PREEMPT_RT: latencies are not representative of the appliance");
  }
  for (const std::string& warning : measurement.trainer.rt.warnings) {
    measurement.warnings.push_back("trainer: " + warning);
  }
  return measurement;
}

}  // namespace trainer::tools::jitter
