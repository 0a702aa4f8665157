// `trainer`: the appliance's main program. Loads a scene, runs the haptic loop on the chosen
// HAL backend, prints a summary and optionally writes the JSON report (docs/report.md).
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>

#include <CLI/CLI.hpp>

#include "trainer/app/report.hpp"
#include "trainer/app/rt_self_check.hpp"
#include "trainer/app/session_recording.hpp"
#include "trainer/metrics/metrics_report.hpp"
#include "trainer/app/trainer_run.hpp"

namespace {

// Creates the report directory before the run, so that a session never runs without a place
// for its record.
trainer::core::Expected<void> make_report_dir(const std::filesystem::path& dir) {
  std::error_code error;
  std::filesystem::create_directories(dir, error);
  if (error) {
    return trainer::core::make_error("--report-dir " + dir.string() +
                                     ": cannot create it: " + error.message());
  }
  return {};
}

// DIR/<scene>-<YYYYmmddTHHMMSSZ>.json for a run started at `started`, with -2, -3, ... when a
// run of the same scene started in the same second already wrote one.
std::filesystem::path trainer_report_path(const std::filesystem::path& dir,
                                          const std::string& scene, std::time_t started) {
  std::error_code error;
  std::tm utc{};
  gmtime_r(&started, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  const std::string stem = scene + "-" + stamp;
  std::filesystem::path path = dir / (stem + ".json");
  for (int n = 2; std::filesystem::exists(path, error) && n < 1000; ++n) {
    path = dir / (stem + "-" + std::to_string(n) + ".json");
  }
  return path;
}

// DIR/latest.json -> the newest report (a relative symlink, replaced atomically).
void point_latest_at(const std::filesystem::path& report) {
  const std::filesystem::path latest = report.parent_path() / "latest.json";
  const std::filesystem::path temporary = report.parent_path() / ".latest.json.tmp";
  std::error_code error;
  std::filesystem::remove(temporary, error);
  std::filesystem::create_symlink(report.filename(), temporary, error);
  if (!error) std::filesystem::rename(temporary, latest, error);
  if (error)
    std::cerr << "trainer: cannot update " << latest.string() << ": " << error.message() << "\n";
}

}  // namespace

namespace {

// --telemetry ADDRESS:PORT ([ADDRESS]:PORT for IPv6); the address itself is checked when the
// sender opens its socket.
trainer::core::Expected<trainer::config::TelemetryConfig> parse_telemetry_destination(
    const std::string& text, std::uint32_t rate_hz) {
  const auto bad = [&] {
    return trainer::core::make_error("--telemetry " + text +
                                     ": expected ADDRESS:PORT, e.g. 127.0.0.1:47800 or "
                                     "[::1]:47800, port 1..65535");
  };
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 >= text.size()) return bad();
  std::string address = text.substr(0, colon);
  if (address.front() == '[') {
    if (address.size() < 3 || address.back() != ']') return bad();
    address = address.substr(1, address.size() - 2);
  }
  const std::string port_text = text.substr(colon + 1);
  if (port_text.find_first_not_of("0123456789") != std::string::npos || port_text.size() > 5)
    return bad();
  const unsigned long port = std::stoul(port_text);
  if (port < 1 || port > 65535) return bad();
  trainer::config::TelemetryConfig config;
  config.enabled = true;
  config.address = address;
  config.port = static_cast<std::uint16_t>(port);
  config.rate_hz = rate_hz;
  return config;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"Laparoscopic haptic trainer controller: runs a scene's haptic loop"};
  trainer::app::RunOptions options;
  std::string report_file;
  std::string time_source = "real";
  std::uint64_t cycles = 0;
  double seconds = 0.0;
  bool no_arm = false;
  bool no_rt = false;

  auto* scene_opt =
      cli.add_option("--scene", options.scene_file,
                     "Scene file (TOML), e.g. config/scenes/wall.toml (required unless --replay)")
          ->check(CLI::ExistingFile);
  std::string record_file;
  std::string replay_file;
  auto* record_opt = cli.add_option(
      "--record", record_file,
      "Record the session into this MCAP file: every cycle's HAL inputs, outputs and model "
      "state hash (docs/recording.md)");
  auto* replay_opt =
      cli.add_option("--replay", replay_file,
                     "Rerun a recording's cycles in simulated time on its recorded inputs and "
                     "compare every output and state hash (exit 0 identical, 3 a difference, "
                     "4 identical up to damage or a gap in the file); --report FILE writes the "
                     "result as JSON")
          ->check(CLI::ExistingFile)
          ->excludes(scene_opt)
          ->excludes(record_opt);
  bool no_record = false;
  auto* no_record_opt = cli.add_flag(
      "--no-record", no_record,
      "With --report-dir: do not record the session (by default it is recorded next to its "
      "report, DIR/<scene>-<UTC start time>.mcap)");
  no_record_opt->excludes(record_opt);
  std::string device_file;
  auto* device_opt =
      cli.add_option("--device", device_file,
                     "Device file (TOML) replacing the one the scene names, e.g. "
                     "config/devices/canopen_vcan.toml; its [device] backend is the HAL")
          ->check(CLI::ExistingFile);
  cli.add_option("--hal", options.hal,
                 "device: the backend the device file names (sim, canopen or usb, with its GPIO "
                 "lines when it has digital_io = \"gpio\"); sim: the simulated bench with the "
                 "device file's mechanism, whatever it names (and its GPIO lines)")
      ->check(CLI::IsMember({"device", "sim"}))
      ->capture_default_str();
  auto* cycles_opt =
      cli.add_option("--cycles", cycles, "Number of cycles to run")->check(CLI::PositiveNumber);
  auto* seconds_opt =
      cli.add_option("--seconds", seconds, "Run length in seconds")->check(CLI::PositiveNumber);
  cycles_opt->excludes(seconds_opt);
  auto* report_opt = cli.add_option("--report", report_file, "Write the JSON report to this file");
  std::string report_dir;
  cli.add_option("--report-dir", report_dir,
                 "Write the JSON report to DIR/<scene>-<UTC start time>.json and point "
                 "DIR/latest.json at it (the appliance: /var/lib/trainer/reports); DIR is "
                 "created if absent; the session is recorded beside it unless --no-record")
      ->excludes(report_opt)
      ->excludes(replay_opt);
  cli.add_option("--time", time_source,
                 "real: CLOCK_MONOTONIC (the appliance); simulated: as fast as possible, "
                 "deterministic (simulated bench only)")
      ->check(CLI::IsMember({"real", "simulated"}));
  std::int64_t period_us = 0;
  int priority = 0;
  int cpu = -1;
  auto* period_opt = cli.add_option("--period-us", period_us,
                                    "Loop period in microseconds, replacing loop.period_us");
  auto* priority_opt = cli.add_option(
      "--priority", priority, "SCHED_FIFO priority (0 = SCHED_OTHER), replacing loop.priority");
  auto* cpu_opt = cli.add_option("--cpu", cpu,
                                 "CPU to pin the haptic thread to (-1 = none), replacing loop.cpu");
  cli.add_option("--slow-motion", options.slow_motion,
                 "Run real time N times slower (an emulator such as the bench VM, debugging); "
                 "1 = the appliance")
      ->check(CLI::Range(1, 1000));
  std::int64_t overrun_limit = 0;
  auto* overrun_opt = cli.add_option(
      "--overrun-streak-limit", overrun_limit,
      "Consecutive overruns that latch a fault, replacing loop.overrun_streak_limit (an "
      "emulator's stalls in the bench VM)");
  std::uint32_t repeat = 0;
  auto* repeat_opt = cli.add_option(
      "--repeat", repeat,
      "With --time simulated: run the same session N times (1-100) and report the compute time "
      "of every cycle, step, stage and sub-stage on the real clock, as the per-cycle minimum "
      "over the runs (the report's 'compute' section, docs/performance.md); with N > 1 the "
      "session is not recorded (--no-record with --report-dir)");
  repeat_opt->excludes(replay_opt);
  std::string compute_csv;
  cli.add_option("--compute-csv", compute_csv,
                 "With --repeat: write the per-cycle minimum (ns: step, each stage and "
                 "sub-stage) of every cycle to this CSV file")
      ->needs(repeat_opt);
  cli.add_flag("--no-arm", no_arm, "Do not issue the reset that arms the safety chain");
  cli.add_flag("--no-rt", no_rt, "Do not request SCHED_FIFO, CPU affinity or mlockall");
  bool check_rt = false;
  bool json = false;
  std::string rt_check_root = "/";
  std::string telemetry_to;
  std::uint32_t telemetry_rate_hz = 60;
  auto* telemetry_opt = cli.add_option(
      "--telemetry", telemetry_to,
      "Stream telemetry to ADDRESS:PORT (numeric IPv4, or [IPv6]:PORT), replacing the device "
      "file's [telemetry] (docs/telemetry.md)");
  cli.add_option("--telemetry-rate", telemetry_rate_hz, "With --telemetry: frames per second")
      ->check(CLI::Range(30, 120))
      ->capture_default_str();
  std::uint16_t telemetry_source_port = 0;
  cli.add_option("--telemetry-source-port", telemetry_source_port,
                 "With --telemetry: local UDP port the frames leave from (0 = any)")
      ->capture_default_str();
  cli.add_flag("--check-rt", check_rt,
               "Run the RT self-check of this machine for the scene (and device file) and exit: "
               "0 no fatal failure, 1 a check listed in loop.rt_check_fatal failed");
  cli.add_flag("--json", json, "With --check-rt: print the results as JSON");
  cli.add_option("--rt-check-root", rt_check_root,
                 "Directory holding the /proc and /sys trees the RT self-check reads (tests)")
      ->check(CLI::ExistingDirectory)
      ->capture_default_str();
  cli.footer(
      "Run length defaults to the trainee script's length; a scene whose script never ends "
      "runs until SIGINT/SIGTERM.\nExit status: 0 run completed, 1 setup error (or a fatal RT "
      "self-check failure, or --repeat runs that were not identical), 2 usage error, 3 run "
      "completed with a fault latched.");
  CLI11_PARSE(cli, argc, argv);

  if (*replay_opt) {
    auto replayed = trainer::app::replay_recording(replay_file);
    if (!replayed) {
      std::cerr << "trainer: " << replayed.error().message << "\n";
      return 1;
    }
    std::cout << "replay of " << replay_file << " (scene " << replayed->scene_name
              << "): " << trainer::app::replay_summary(*replayed) << "\n";
    if (replayed->metrics) {
      std::cout << trainer::metrics::metrics_summary(*replayed->metrics,
                                                    replayed->instrument_names);
    }
    if (!report_file.empty()) {
      nlohmann::json report{
          {"replay", replay_file},
          {"scene", replayed->scene_name},
          {"cycles_replayed", replayed->cycles_replayed},
          {"identical", replayed->identical},
          {"first_difference_cycle", replayed->first_difference_cycle
                                         ? nlohmann::json(*replayed->first_difference_cycle)
                                         : nlohmann::json(nullptr)},
          {"difference", replayed->difference},
          {"damage", replayed->damage},
          {"complete", replayed->complete},
          {"dropped_cycles", replayed->dropped_cycles},
          {"summary", trainer::app::replay_summary(*replayed)},
          {"metrics", replayed->metrics
                          ? trainer::metrics::metrics_json(*replayed->metrics,
                                                           replayed->metrics_thresholds,
                                                           replayed->instrument_names,
                                                           replayed->model_names)
                          : nlohmann::json(nullptr)}};
      std::ofstream out(report_file);
      out << report.dump(2) << "\n";
      if (!out) {
        std::cerr << "trainer: cannot write report '" << report_file << "'\n";
        return 1;
      }
    }
    if (replayed->first_difference_cycle) return 3;
    return replayed->identical ? 0 : 4;
  }
  if (!*scene_opt) {
    std::cerr << "trainer: --scene is required (unless --replay)\n";
    return 2;
  }
  if (*record_opt) options.record_file = record_file;

  if (*device_opt) options.device_file = device_file;
  if (*cycles_opt) options.cycles = cycles;
  if (*seconds_opt) options.seconds = seconds;
  options.time_source = time_source == "simulated" ? trainer::app::TimeSource::simulated
                                                   : trainer::app::TimeSource::real;
  if (*period_opt) options.loop_overrides.period_us = period_us;
  if (*priority_opt) options.loop_overrides.priority = priority;
  if (*cpu_opt) options.loop_overrides.cpu = cpu;
  if (*overrun_opt) options.loop_overrides.overrun_streak_limit = overrun_limit;
  options.arm = !no_arm;
  options.apply_rt_settings = !no_rt;
  options.rt_check_root = rt_check_root;
  if (*telemetry_opt) {
    auto stream = parse_telemetry_destination(telemetry_to, telemetry_rate_hz);
    if (!stream) {
      std::cerr << "trainer: " << stream.error().message << "\n";
      return 2;
    }
    options.telemetry = *stream;
    options.telemetry->source_port = telemetry_source_port;
  }

  if (check_rt) {
    trainer::config::LoadOptions load_options;
    load_options.device_file = options.device_file;
    auto scene = trainer::config::load_scene(options.scene_file, load_options);
    if (!scene) {
      std::cerr << "trainer: " << scene.error().message << "\n";
      return 1;
    }
    if (auto overridden =
            trainer::config::apply_loop_overrides(scene->loop, options.loop_overrides);
        !overridden) {
      std::cerr << "trainer: " << overridden.error().message << "\n";
      return 1;
    }
    const auto results = trainer::app::run_scene_rt_check(*scene, options.rt_check_root);
    if (json) {
      std::cout << trainer::app::rt_check_json(results).dump(2) << "\n";
    } else {
      std::cout << "scene " << options.scene_file.string() << ", device "
                << scene->device.source_path.string() << ", loop.cpu " << scene->loop.cpu
                << ", loop.priority " << scene->loop.priority << "\n"
                << trainer::appliance::format_rt_check(results);
    }
    return trainer::appliance::rt_check_failed(results) ? 1 : 0;
  }

  if (*repeat_opt) {
    if (options.time_source != trainer::app::TimeSource::simulated) {
      std::cerr << "trainer: --repeat needs --time simulated: only a simulated-time session is "
                   "the same session in every run\n";
      return 2;
    }
    if (repeat < 1 || repeat > trainer::app::kMaxRepeatRuns) {
      std::cerr << "trainer: --repeat " << repeat << ": expected 1 to "
                << trainer::app::kMaxRepeatRuns << " runs\n";
      return 2;
    }
    if (repeat > 1 && (*record_opt || (!report_dir.empty() && !no_record))) {
      std::cerr << "trainer: --repeat " << repeat
                << " cannot record the session (each run would overwrite the recording): drop "
                   "--record, add --no-record with --report-dir, or use --repeat 1\n";
      return 2;
    }
  }
  if (!report_dir.empty()) {
    if (auto made = make_report_dir(report_dir); !made) {
      std::cerr << "trainer: " << made.error().message << "\n";
      return 1;
    }
  }
  // The appliance (--report-dir) records every session next to its report: recorded under a
  // temporary name, renamed to the report's name once the scene's name is known.
  std::filesystem::path pending_recording;
  if (!report_dir.empty() && !*record_opt && !no_record) {
    pending_recording =
        std::filesystem::path(report_dir) / (".recording-" + std::to_string(::getpid()) + ".mcap");
    options.record_file = pending_recording;
  }
  const std::time_t started = std::time(nullptr);
  auto result = *repeat_opt ? trainer::app::run_trainer_repeated(options, repeat)
                            : trainer::app::run_trainer(options);
  if (!result) {
    if (!pending_recording.empty()) {
      std::error_code ignored;
      std::filesystem::remove(pending_recording, ignored);
    }
    std::cerr << "trainer: " << result.error().message << "\n";
    return 1;
  }
  if (!report_dir.empty()) {
    report_file = trainer_report_path(report_dir, result->scene_name, started).string();
  }
  if (!pending_recording.empty()) {
    std::filesystem::path named = report_file;
    named.replace_extension(".mcap");
    std::error_code error;
    std::filesystem::rename(pending_recording, named, error);
    if (error) {
      std::cerr << "trainer: cannot rename " << pending_recording.string() << " to "
                << named.string() << ": " << error.message() << "\n";
    } else {
      result->recording_file = named.string();
    }
  }
  std::cout << trainer::app::report_summary(*result);
  if (!result->recording_file.empty()) {
    std::cout << "  recording: " << result->recording_file << ", " << result->recorded_cycles
              << " cycles, " << result->recording_bytes << " bytes, "
              << result->recording_dropped_cycles << " dropped (ring full)";
    if (!result->recording_error.empty()) std::cout << ", stopped: " << result->recording_error;
    std::cout << "\n";
  }
  if (!report_file.empty()) {
    std::ofstream out(report_file);
    out << trainer::app::report_json(*result).dump(2) << "\n";
    if (!out) {
      std::cerr << "trainer: cannot write report '" << report_file << "'\n";
      return 1;
    }
    std::cout << "  report: " << report_file << "\n";
    if (!report_dir.empty()) point_latest_at(report_file);
  }
  if (!compute_csv.empty() && result->compute) {
    std::ofstream csv(compute_csv);
    trainer::app::write_compute_csv(*result->compute, csv);
    csv.close();
    if (!csv) {
      std::cerr << "trainer: cannot write '" << compute_csv << "'\n";
      return 1;
    }
    std::cout << "  per-cycle minima: " << compute_csv << "\n";
  }
  if (result->compute && !result->compute->identical) {
    std::cerr << "trainer: --repeat: the runs were not identical (" << result->compute->mismatch
              << "): the per-cycle minima mean nothing\n";
    return 1;
  }
  // The shutdown fault is expected at the end of every run; anything else means the run
  // ended faulted.
  const std::uint32_t unexpected = result->latched_faults;
  return unexpected == 0 ? 0 : 3;
}
