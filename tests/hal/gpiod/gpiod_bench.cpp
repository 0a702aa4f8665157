// The guest side of the bench VM's GPIO tests (tests/benchvm/gpio_*_test.sh), against a
// gpio-sim chip made by tests/benchvm/gpio_sim_chip.sh:
//
//   gpiod_bench list CHIP
//       libgpiod's view of the chip, gpioinfo style: "line N: 'name' consumer direction".
//   gpiod_bench configure CHIP
//       GpioDevice::configure() against the chip, case by case (lines by name and by offset,
//       a missing chip, a missing line, a line used by another request, a line the kernel
//       holds as an output named as an input, the same line twice): prints "case: ok" or
//       "case: error: <message>" per case.
//   gpiod_bench presses CHIP PULL_FILE N PERIOD_US
//       The press trials: the backend's read_digital_inputs() every PERIOD_US (absolute
//       sleeps, SCHED_FIFO when allowed) on the e-stop line (named "estop"), while a second
//       thread presses N times through PULL_FILE (the line's gpio-sim pull: pull-up, then
//       pull-down), each press at a random phase of the period and held for a random 5..60 %
//       of a period, the next one only after two reads saw the release. Prints the counts:
//       presses, latched (a read reported the e-stop active after the press began and before
//       the next one), pulses seen only through their events, press lengths, latency in
//       reads, heap allocations in the reading thread. Exit 0 when every press was latched.
#include <fcntl.h>
#include <gpiod.h>
#include <pthread.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/hal_gpiod/gpio_device.hpp"

namespace gpio = trainer::hal::gpiod;

namespace {

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

void sleep_until(std::int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

int list(const char* chip_name) {
  gpiod_chip* chip = gpiod_chip_open_lookup(chip_name);
  if (chip == nullptr) {
    std::fprintf(stderr, "gpiod_bench: cannot open chip %s: %s\n", chip_name, std::strerror(errno));
    return 1;
  }
  std::printf("%s [%s] (%u lines)\n", gpiod_chip_name(chip), gpiod_chip_label(chip),
              gpiod_chip_num_lines(chip));
  for (unsigned i = 0; i < gpiod_chip_num_lines(chip); ++i) {
    gpiod_line* line = gpiod_chip_get_line(chip, i);
    const char* name = gpiod_line_name(line);
    const char* consumer = gpiod_line_consumer(line);
    std::printf("line %u: '%s' %s %s\n", i, name != nullptr ? name : "unnamed",
                consumer != nullptr ? consumer : "unused",
                gpiod_line_direction(line) == GPIOD_LINE_DIRECTION_OUTPUT ? "output" : "input");
  }
  gpiod_chip_close(chip);
  return 0;
}

gpio::LineParams in_line(const std::string& chip, const std::string& name, int bit) {
  gpio::LineParams line;
  line.config_key = "gpio.input[" + std::to_string(bit) + "]";
  line.direction = gpio::Direction::input;
  line.bit = bit;
  line.chip = chip;
  line.line_name = name;
  return line;
}

gpio::LineParams out_line(const std::string& chip, int offset, int bit) {
  gpio::LineParams line;
  line.config_key = "gpio.output[" + std::to_string(bit) + "]";
  line.direction = gpio::Direction::output;
  line.bit = bit;
  line.chip = chip;
  line.offset = offset;
  return line;
}

void try_case(const char* label, std::vector<gpio::LineParams> lines) {
  gpio::GpioDeviceParams params;
  params.name = "vm";
  params.consumer = "gpiod-bench";
  params.lines = std::move(lines);
  gpio::GpioDevice device(std::move(params));
  auto configured = device.configure();
  if (configured) {
    std::printf("%s: ok\n", label);
  } else {
    std::printf("%s: error: %s\n", label, configured.error().message.c_str());
  }
  std::fflush(stdout);
}

int configure_cases(const std::string& chip) {
  // Offsets of gpio_sim_chip.sh's bench chip: 0 estop, 1 enable, 2 drive_enable,
  // 3 fault_lamp, 4 unnamed, 5 hogged (output-high).
  try_case("by-name", {in_line(chip, "estop", 0), in_line(chip, "enable", 1),
                       out_line(chip, 2, 0), out_line(chip, 3, 1)});
  {
    gpiod_chip* by_path = gpiod_chip_open_lookup(chip.c_str());
    const std::string path = std::string("/dev/") + gpiod_chip_name(by_path);
    const std::string name = gpiod_chip_name(by_path);
    gpiod_chip_close(by_path);
    gpio::LineParams estop = in_line(path, "", 0);
    estop.offset = 0;
    try_case("by-offset", {estop, out_line(name, 2, 0)});
  }
  try_case("missing-chip", {in_line("no-such-chip", "estop", 0)});
  try_case("missing-line", {in_line(chip, "estopp", 0)});
  try_case("missing-offset", {out_line(chip, 99, 0)});
  try_case("same-line-twice", {in_line(chip, "estop", 0), out_line(chip, 0, 0)});
  try_case("hog-as-input", {in_line(chip, "hogged", 0)});
  // Another request holds the e-stop line (as another program would).
  gpiod_chip* other = gpiod_chip_open_lookup(chip.c_str());
  gpiod_line* held = gpiod_chip_find_line(other, "estop");
  if (held == nullptr || gpiod_line_request_input(held, "other-program") != 0) {
    std::printf("used-line: cannot hold the line: %s\n", std::strerror(errno));
    return 1;
  }
  try_case("used-line", {in_line(chip, "enable", 1), in_line(chip, "estop", 0)});
  gpiod_line_release(held);
  gpiod_chip_close(other);
  // Released again: configure works, the output reads back its safe level after deactivate.
  try_case("after-release", {in_line(chip, "estop", 0), out_line(chip, 2, 0)});
  return 0;
}

struct Trial {
  std::atomic<std::uint64_t> reads{0};
  std::atomic<int> current_press{-1};
  std::atomic<bool> done{false};
};

int presses(const std::string& chip, const char* pull_file, int count, int period_us) {
  gpio::GpioDeviceParams params;
  params.name = "vm";
  params.consumer = "gpiod-bench";
  params.lines = {in_line(chip, "estop", 0)};
  gpio::GpioDevice device(std::move(params));
  if (auto configured = device.configure(); !configured) {
    std::fprintf(stderr, "gpiod_bench: %s\n", configured.error().message.c_str());
    return 1;
  }
  if (auto activated = device.activate(); !activated) {
    std::fprintf(stderr, "gpiod_bench: %s\n", activated.error().message.c_str());
    return 1;
  }
  const int pull = open(pull_file, O_WRONLY | O_CLOEXEC);
  if (pull < 0) {
    std::fprintf(stderr, "gpiod_bench: open %s: %s\n", pull_file, std::strerror(errno));
    return 1;
  }
  const std::int64_t period_ns = std::int64_t{period_us} * 1000;
  std::vector<std::uint8_t> latched(static_cast<std::size_t>(count), 0);
  std::vector<std::uint64_t> press_read(static_cast<std::size_t>(count), 0);
  std::vector<std::uint64_t> latch_read(static_cast<std::size_t>(count), 0);
  std::vector<std::int64_t> held_ns(static_cast<std::size_t>(count), 0);
  Trial trial;
  std::uint64_t heap = 0;
  std::uint64_t read_errors = 0;

  std::thread reader([&] {
    sched_param sp{};
    sp.sched_priority = 80;
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    trainer::core::alloc::begin_counting_this_thread();
    const std::uint64_t before = trainer::core::alloc::counted_allocations();
    std::int64_t next = now_ns();
    while (!trial.done.load(std::memory_order_acquire)) {
      next += period_ns;
      sleep_until(next);
      // The press in progress before the read: a press that begins during the read is
      // attributed to the next read at the latest (it is latched there).
      const int press = trial.current_press.load(std::memory_order_acquire);
      std::uint32_t levels = 0;
      if (device.read_digital_inputs(levels) != trainer::hal::ReturnCode::ok) ++read_errors;
      const std::uint64_t index = trial.reads.fetch_add(1, std::memory_order_acq_rel) + 1;
      if ((levels & 1U) != 0 && press >= 0 && latched[static_cast<std::size_t>(press)] == 0) {
        latched[static_cast<std::size_t>(press)] = 1;
        latch_read[static_cast<std::size_t>(press)] = index;
      }
    }
    heap = trainer::core::alloc::counted_allocations() - before;
    trainer::core::alloc::end_counting_this_thread();
  });

  std::mt19937_64 random(0x5EED'0016);
  std::uniform_int_distribution<std::int64_t> phase(0, period_ns - 1);
  std::uniform_int_distribution<std::int64_t> hold(period_ns / 20, period_ns * 60 / 100);
  const auto wait_reads = [&](std::uint64_t n) {
    const std::uint64_t target = trial.reads.load(std::memory_order_acquire) + n;
    while (trial.reads.load(std::memory_order_acquire) < target) usleep(200);
  };
  wait_reads(2);
  for (int k = 0; k < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    sleep_until(now_ns() + phase(random));
    const std::int64_t hold_ns = hold(random);
    trial.current_press.store(k, std::memory_order_release);
    press_read[i] = trial.reads.load(std::memory_order_acquire);
    const std::int64_t down = now_ns();
    if (pwrite(pull, "pull-up", 7, 0) != 7) std::perror("pull-up");
    const std::int64_t pressed = now_ns();
    sleep_until(pressed + hold_ns);
    const std::int64_t before_release = now_ns();
    if (pwrite(pull, "pull-down", 9, 0) != 9) std::perror("pull-down");
    // Held from the end of the pull-up write to the start of the pull-down write at least,
    // from the start of one to the end of the other at most.
    held_ns[i] = before_release - pressed;
    (void)down;
    wait_reads(2);
  }
  wait_reads(1);
  trial.done.store(true, std::memory_order_release);
  reader.join();
  close(pull);
  device.deactivate();

  int latched_count = 0;
  int within_period = 0;
  std::uint64_t max_latency = 0;
  std::vector<int> latency_hist(4, 0);
  for (std::size_t i = 0; i < latched.size(); ++i) {
    if (held_ns[i] <= period_ns) ++within_period;
    if (latched[i] == 0) {
      std::printf("press %zu NOT latched (held %.3f ms)\n", i, static_cast<double>(held_ns[i]) / 1e6);
      continue;
    }
    ++latched_count;
    // Reads after the press began until the one that reported it (1 = the next read).
    const std::uint64_t latency = latch_read[i] - press_read[i];
    max_latency = std::max(max_latency, latency);
    ++latency_hist[std::min<std::size_t>(latency, 3)];
  }
  const std::int64_t max_held = *std::max_element(held_ns.begin(), held_ns.end());
  std::printf("presses %d latched %d reads_latched_against_level %llu held_within_one_period %d "
              "max_held_ms %.3f period_ms %.3f reads %llu read_errors %llu "
              "latency_reads_1 %d latency_reads_2 %d latency_reads_3plus %d max_latency_reads %llu "
              "heap_allocations_in_reader %llu\n",
              count, latched_count,
              static_cast<unsigned long long>(device.stats().pulses_latched[0]), within_period,
              static_cast<double>(max_held) / 1e6, static_cast<double>(period_ns) / 1e6,
              static_cast<unsigned long long>(trial.reads.load()),
              static_cast<unsigned long long>(read_errors), latency_hist[1], latency_hist[2],
              latency_hist[3], static_cast<unsigned long long>(max_latency),
              static_cast<unsigned long long>(heap));
  return latched_count == count && heap == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  if (command == "list" && argc == 3) return list(argv[2]);
  if (command == "configure" && argc == 3) return configure_cases(argv[2]);
  if (command == "presses" && argc == 6) {
    return presses(argv[2], argv[3], std::atoi(argv[4]), std::atoi(argv[5]));
  }
  std::fprintf(stderr,
               "usage: gpiod_bench list CHIP | configure CHIP | presses CHIP PULL_FILE N "
               "PERIOD_US\n");
  return 2;
}
