// hil check, GPIO (docs/hil-io.md): the e-stop and enable lines pressed/released by the
// operator, timed from the kernel's edge to the read of the trainer's own backend
// (hal/gpiod's GpioDevice, read in a periodic loop as the RT loop reads it) that reported the
// latched level; the drive-enable and fault-lamp outputs set and read back.
#include <pthread.h>
#include <sched.h>
#include <time.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "trainer/app/device_wiring.hpp"
#include "trainer/hal_gpiod/gpio_device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;
constexpr int kDefaultTrials = 10;

std::int64_t gpio_check_now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void gpio_check_sleep_until(std::int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
  }
}

void gpio_check_sleep_ms(std::int64_t ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

// "gpiochip0:0 (estop)": the line as the kernel knows it, for messages.
struct ResolvedLine {
  std::string text;
  std::string chip_name;
  int offset = -1;
  bool active_low = false;
};

ResolvedLine gpio_check_resolve(const std::vector<GpioChipInfo>& chips,
                                const config::GpioLineConfig& line, const std::string& role) {
  ResolvedLine r;
  r.active_low = line.active_low;
  const GpioChipInfo* chip = find_gpio_chip(chips, line.chip);
  if (chip != nullptr) {
    r.chip_name = chip->name;
    if (line.line_name.empty()) {
      r.offset = line.offset;
    } else {
      for (const GpioLineInfo& l : chip->lines) {
        if (l.name == line.line_name) r.offset = static_cast<int>(l.offset);
      }
    }
  }
  r.text = (r.chip_name.empty() ? line.chip : r.chip_name) + ":" +
           (r.offset >= 0 ? std::to_string(r.offset) : line.line_name) + " (" + role + ")";
  return r;
}

// What the periodic reader shares with the steps. The reader is the only writer of everything
// but `stop` and the arm request.
struct ReaderShared {
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> arm_seq{0};
  std::atomic<std::int64_t> arm_ns{0};
  std::atomic<std::uint64_t> done_seq{0};
  std::atomic<bool> quiet{false};
  std::atomic<bool> interest{false};
  std::atomic<std::uint64_t> reads{0};
  std::atomic<std::uint64_t> read_errors{0};
  std::atomic<std::uint64_t> overruns{0};
  std::atomic<std::size_t> input_index{0};
  std::atomic<int> bit{0};
  std::atomic<bool> interest_when_set{true};  // e-stop: set = pressed; enable: clear = released
  LatchTrial result;  // written before done_seq is published
};

// The read loop, as the trainer's RT loop runs it: absolute periodic sleeps, one
// read_digital_inputs() per period, nothing else but the bookkeeping.
void gpio_check_reader(hal::gpiod::GpioDevice& device, ReaderShared& shared,
                       std::int64_t period_ns) {
  EdgeLatchMeter meter;
  std::uint64_t seen_arm = 0;
  std::int64_t next = gpio_check_now_ns();
  while (!shared.stop.load(std::memory_order_acquire)) {
    next += period_ns;
    gpio_check_sleep_until(next);
    const std::size_t index = shared.input_index.load(std::memory_order_relaxed);
    const std::uint64_t changed_before = device.stats().changed_reads[index];
    std::uint32_t levels = 0;
    const std::int64_t start = gpio_check_now_ns();
    const hal::ReturnCode rc = device.read_digital_inputs(levels);
    const std::int64_t done = gpio_check_now_ns();
    shared.reads.fetch_add(1, std::memory_order_relaxed);
    if (rc != hal::ReturnCode::ok) shared.read_errors.fetch_add(1, std::memory_order_relaxed);
    const std::uint64_t arm = shared.arm_seq.load(std::memory_order_acquire);
    if (arm != seen_arm) {
      seen_arm = arm;
      meter.arm(shared.arm_ns.load(std::memory_order_relaxed));
    }
    const bool set = (levels >> static_cast<unsigned>(shared.bit.load(std::memory_order_relaxed))) & 1U;
    LatchRead read;
    read.start_ns = start;
    read.done_ns = done;
    read.reported_active = set == shared.interest_when_set.load(std::memory_order_relaxed);
    if (device.stats().changed_reads[index] != changed_before) {
      read.event_ns = device.stats().last_change_event_ns[index];
    }
    if (meter.on_read(read)) {
      shared.result = meter.trial();
      shared.done_seq.store(seen_arm, std::memory_order_release);
    }
    shared.quiet.store(meter.quiet(), std::memory_order_release);
    shared.interest.store(meter.active(), std::memory_order_release);
    if (done > next + period_ns) {  // late: start again from now instead of catching up
      shared.overruns.fetch_add(1, std::memory_order_relaxed);
      next = done;
    }
  }
}

// Waits up to `timeout_ns` for `done()`, polling every millisecond.
template <typename Done>
bool gpio_check_wait(std::int64_t timeout_ns, Done done) {
  const std::int64_t deadline = gpio_check_now_ns() + timeout_ns;
  while (!done()) {
    if (gpio_check_now_ns() > deadline) return false;
    gpio_check_sleep_ms(1);
  }
  return true;
}

std::string gpio_check_seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", s);
  return text;
}

struct InputPlan {
  std::string role;       // "estop" / "enable"
  std::string what;       // "e-stop" / "enable switch"
  std::size_t index = 0;  // in the GpioDevice's lines
  int bit = 0;
  bool interest_when_set = true;
  ResolvedLine line;
};

StepResult gpio_check_input(const BenchContext& bench, ReaderShared& shared, const InputPlan& plan,
                            std::int64_t period_ns, std::int64_t limit_ns, int trials) {
  const std::string id = "gpio." + plan.role + ".edge_to_latch";
  const std::string title = plan.what + " " + plan.line.text + ": edge to latch";
  const auto timeout_ns = static_cast<std::int64_t>(bench.action_timeout_s * 1e9);
  const std::string timeout_text = gpio_check_seconds(bench.action_timeout_s);
  shared.input_index.store(plan.index);
  shared.bit.store(plan.bit);
  shared.interest_when_set.store(plan.interest_when_set);
  shared.quiet.store(false);
  const std::string press_action = plan.role == "estop" ? "gpio.estop.press" : "gpio.enable.release";
  const std::string instruction = plan.role == "estop"
                                      ? "press the e-stop and release it"
                                      : "release the enable switch and hold it again";
  auto failed = [&](std::string reason) {
    StepResult step;
    step.id = id;
    step.title = title;
    step.outcome = Outcome::fail;
    step.reason = std::move(reason);
    return step;
  };
  // The resting state first: e-stop released, enable switch held.
  const std::uint64_t reads0 = shared.reads.load();
  gpio_check_wait(timeout_ns, [&] { return shared.reads.load() >= reads0 + 3; });
  if (!shared.quiet.load() && plan.role == "enable") {
    if (bench.op == nullptr || !bench.op->request("gpio.enable.hold", "hold the enable switch")) {
      StepResult step;
      step.id = id;
      step.title = title;
      step.reason = "the enable switch is not held and holding it was declined";
      return step;
    }
  }
  if (!gpio_check_wait(timeout_ns, [&] { return shared.quiet.load(); })) {
    return failed(plan.role == "estop"
                      ? "the e-stop " + plan.line.text + " reads pressed for " + timeout_text +
                            " s: release it (or the line is stuck active, or active_low is wrong)"
                      : "the enable switch " + plan.line.text + " never read held within " +
                            timeout_text + " s — check wiring (or active_low)");
  }
  std::vector<LatchTrial> done;
  std::uint64_t seq = shared.arm_seq.load();
  for (int k = 0; k < trials; ++k) {
    if (k > 0 && !gpio_check_wait(timeout_ns, [&] { return shared.quiet.load(); })) {
      StepResult step = judge_edge_to_latch(id, title, done, static_cast<std::size_t>(trials),
                                            period_ns, limit_ns);
      step.outcome = Outcome::fail;
      step.reason = "trial " + std::to_string(k + 1) + ": " + plan.line.text +
                    " did not return to rest within " + timeout_text + " s; " + step.reason;
      return step;
    }
    shared.arm_ns.store(gpio_check_now_ns());
    shared.arm_seq.store(++seq, std::memory_order_release);
    if (bench.op == nullptr || !bench.op->request(press_action, instruction)) {
      StepResult step;
      step.id = id;
      step.title = title;
      step.outcome = Outcome::skip;
      step.reason = "declined by the operator after " + std::to_string(k) + " trial(s)";
      return step;
    }
    if (!gpio_check_wait(timeout_ns, [&] {
          return shared.done_seq.load(std::memory_order_acquire) == seq;
        })) {
      StepResult step = judge_edge_to_latch(id, title, done, static_cast<std::size_t>(trials),
                                            period_ns, limit_ns);
      step.outcome = Outcome::fail;
      step.reason = "no edge on " + plan.line.text + " within " + timeout_text +
                    " s — check wiring (trial " + std::to_string(k + 1) + " of " +
                    std::to_string(trials) + ")";
      return step;
    }
    done.push_back(shared.result);
  }
  return judge_edge_to_latch(id, title, done, static_cast<std::size_t>(trials), period_ns,
                             limit_ns);
}

// gpio-sim's sysfs value of a line (the physical level), when the chip is gpio-sim.
std::optional<int> gpio_check_sim_value(const ResolvedLine& line) {
  if (line.chip_name.empty() || line.offset < 0) return std::nullopt;
  std::error_code ec;
  for (const auto& dev : std::filesystem::directory_iterator("/sys/devices/platform", ec)) {
    const auto file = dev.path() / line.chip_name / ("sim_gpio" + std::to_string(line.offset)) / "value";
    std::ifstream in(file);
    int value = -1;
    if (in >> value) return value;
  }
  return std::nullopt;
}

StepResult gpio_check_output(const BenchContext& bench, hal::gpiod::GpioDevice& device,
                             const std::string& role, const std::string& what, int bit,
                             const ResolvedLine& line, std::uint32_t& word) {
  StepResult step;
  step.id = "gpio." + role + ".output";
  step.title = what + " " + line.text + ": set and read back";
  if (role == "drive_enable" &&
      (bench.op == nullptr ||
       !bench.op->confirm("set the drive-enable line " + line.text +
                          " high for a moment (drives get power if the enable chain is wired)?"))) {
    step.reason = "not confirmed: the drive-enable line stays low";
    return step;
  }
  nlohmann::json readings = nlohmann::json::array();
  bool ok = true;
  bool read_back = true;
  std::string reason;
  for (const int level : {1, 0}) {
    word = level != 0 ? word | (1U << static_cast<unsigned>(bit)) : word & ~(1U << static_cast<unsigned>(bit));
    if (device.write_digital_outputs(word) != hal::ReturnCode::ok) {
      ok = false;
      reason = "writing " + std::to_string(level) + " failed";
      break;
    }
    gpio_check_sleep_ms(50);
    const std::optional<int> physical = gpio_check_sim_value(line);
    if (!physical) {
      read_back = false;
      continue;
    }
    const int logical = line.active_low ? 1 - *physical : *physical;
    readings.push_back({{"set", level}, {"read", logical}, {"physical", *physical}});
    if (logical != level) {
      ok = false;
      reason += (reason.empty() ? "" : "; ") + std::string("set ") + std::to_string(level) +
                ", read back " + std::to_string(logical) + " (physical " +
                std::to_string(*physical) + ")";
    }
  }
  step.details = {{"readings", readings}};
  if (!ok) {
    step.outcome = Outcome::fail;
    step.reason = reason;
  } else if (!read_back) {
    step.outcome = Outcome::skip;
    step.reason = "set 1 and 0 without error; not read back (the chip offers no read-back of an "
                  "output line: gpio-sim only) — watch the " + what;
  } else {
    step.outcome = Outcome::pass;
    step.reason = "set 1 and 0, read back 1 and 0 (gpio-sim sysfs)";
  }
  return step;
}

}  // namespace

CheckSection check_gpio(const BenchContext& bench) { return check_gpio(bench, GpioCheckOptions{}); }

CheckSection check_gpio(const BenchContext& bench, const GpioCheckOptions& options) {
  CheckSection section;
  section.part = "gpio";
  auto skip_all = [](const std::string& reason) {
    return skipped_checks("gpio", "GPIO checks", reason);
  };
  if (!bench.device) return skip_all("no device file: which lines to check is the [gpio] table's");
  const config::DeviceConfig& device = *bench.device;
  if (device.digital_io != config::DigitalIo::gpio) {
    return skip_all(device.source_path.string() + " has no [gpio] table (digital_io is not \"gpio\")");
  }
  const std::int64_t slow = std::max<std::int64_t>(1, bench.slow_motion);
  const std::int64_t period_ns = options.period_ns > 0 ? options.period_ns : kNsPerMs * slow;
  const std::int64_t margin_ns = options.margin_ns >= 0 ? options.margin_ns : period_ns / 2;
  const int trials = bench.trials > 0 ? bench.trials : kDefaultTrials;

  const std::vector<GpioChipInfo> chips = list_gpio_chips();
  hal::gpiod::GpioDeviceParams params = app::gpio_params_from(device);
  params.name = "hil";
  hal::gpiod::GpioDevice gpio(params);
  if (auto configured = gpio.configure(); !configured) {
    StepResult step;
    step.id = "gpio.claim";
    step.title = "claim the [gpio] lines";
    step.outcome = Outcome::fail;
    step.reason = configured.error().message;
    section.steps.push_back(std::move(step));
    return section;
  }
  if (auto active = gpio.activate(); !active) {
    StepResult step;
    step.id = "gpio.claim";
    step.title = "claim the [gpio] lines";
    step.outcome = Outcome::fail;
    step.reason = active.error().message;
    section.steps.push_back(std::move(step));
    gpio.deactivate();
    return section;
  }

  // The inputs the safety chain uses, by their [digital] bit.
  std::vector<InputPlan> inputs;
  std::size_t index = 0;
  for (const config::GpioLineConfig& line : device.gpio.inputs) {
    const std::string role = gpio_line_role(device, line, false);
    if (role == "estop" || role == "enable") {
      InputPlan plan;
      plan.role = role;
      plan.what = role == "estop" ? "e-stop" : "enable switch";
      plan.index = index;
      plan.bit = line.bit;
      plan.interest_when_set = role == "estop";
      plan.line = gpio_check_resolve(chips, line, role);
      inputs.push_back(plan);
    }
    ++index;
  }
  for (const char* role : {"estop", "enable"}) {
    const bool wired = std::string(role) == "estop" ? device.digital.estop_input_bit >= 0
                                                    : device.digital.enable_input_bit >= 0;
    bool planned = false;
    for (const InputPlan& p : inputs) planned = planned || p.role == role;
    if (!planned) {
      StepResult step;
      step.id = std::string("gpio.") + role + ".edge_to_latch";
      step.title = std::string(role) + ": edge to latch";
      step.reason = wired ? "its [digital] bit is on no [[gpio.input]] line"
                          : "not wired ([digital] bit -1)";
      section.steps.push_back(std::move(step));
    }
  }

  ReaderShared shared;
  if (!inputs.empty()) {
    shared.input_index.store(inputs.front().index);
    shared.bit.store(inputs.front().bit);
  }
  std::thread reader([&] { gpio_check_reader(gpio, shared, period_ns); });
  bool realtime = false;
  if (options.realtime) {
    sched_param sp{};
    sp.sched_priority = 40;
    realtime = pthread_setschedparam(reader.native_handle(), SCHED_FIFO, &sp) == 0;
  }
  for (const InputPlan& plan : inputs) {
    StepResult step = gpio_check_input(bench, shared, plan, period_ns, period_ns + margin_ns, trials);
    step.details["reader"] = {{"period_ms", static_cast<double>(period_ns) / 1e6},
                              {"sched", realtime ? "SCHED_FIFO 40" : "SCHED_OTHER"},
                              {"reads", shared.reads.load()},
                              {"read_errors", shared.read_errors.load()},
                              {"overruns", shared.overruns.load()}};
    section.steps.push_back(std::move(step));
  }
  shared.stop.store(true, std::memory_order_release);
  reader.join();

  // The outputs: set and read back, the drive enable only when confirmed.
  std::uint32_t word = 0;
  for (const config::GpioLineConfig& line : device.gpio.outputs) {
    const std::string role = gpio_line_role(device, line, true);
    if (role != "drive_enable" && role != "fault_lamp") continue;
    const ResolvedLine resolved = gpio_check_resolve(chips, line, role);
    section.steps.push_back(gpio_check_output(
        bench, gpio, role, role == "drive_enable" ? "drive enable" : "fault lamp", line.bit,
        resolved, word));
  }
  gpio.deactivate();
  return section;
}

}  // namespace trainer::hil
