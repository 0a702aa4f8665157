// The guest side of the bench VM's GPIO tests (tests/benchvm/gpio_*_test.sh), against a
// gpio-sim chip made by tests/benchvm/gpio_sim_chip.sh:
//
//   gpiod_bench list CHIP
//       libgpiod's view of the chip, gpioinfo style: "line N: 'name' consumer direction".
//   gpiod_bench get CHIP OFFSET
//       The line's value read through libgpiod (claimed as an input for the read).
//   gpiod_bench configure CHIP
//       GpioDevice::configure() against the chip, case by case (lines by name and by offset,
//       a missing chip, a missing line, a line used by another request, a line the kernel
//       holds as an output named as an input, the same line twice): prints "case: ok" or
//       "case: error: <message>" per case.
//   gpiod_bench presses CHIP PULL_FILE N PERIOD_US
//       The press trials: the backend's read_digital_inputs() every PERIOD_US (absolute
//       sleeps, SCHED_FIFO when allowed) on the e-stop line (named "estop"), while a second
//       thread presses N times through PULL_FILE (the line's gpio-sim pull: pull-up, then
//       pull-down), each press at a random phase of the period and held for a random 5..40 %
//       of a period, the next one only after a read reported it (or 100 reads passed: missed) and
//       two reads in a row saw the e-stop released, until N presses
//       were held one period or less (at most 3 N presses: the emulator can stretch a hold).
//       Prints the counts: presses, latched (a read reported the e-stop active after the press
//       began and before the next one), presses within one period and of those latched, press
//       lengths, latency in reads, heap allocations in the reading thread. Exit 0 when every
//       press was latched and N were within a period.
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

int get(const char* chip, const char* offset) {
  const int value =
      gpiod_ctxless_get_value(chip, static_cast<unsigned>(std::atoi(offset)), false, "gpiod-bench");
  if (value < 0) {
    std::fprintf(stderr, "gpiod_bench: get %s %s: %s\n", chip, offset, std::strerror(errno));
    return 1;
  }
  std::printf("%d\n", value);
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
  try_case("by-name", {in_line(chip, "estop", 0), in_line(chip, "enable", 1), out_line(chip, 2, 0),
                       out_line(chip, 3, 1)});
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

// A press no read reported within this many reads counts as missed.
constexpr std::uint64_t kGiveUpReads = 100;

struct Trial {
  std::atomic<std::uint64_t> reads{0};
  std::atomic<int> current_press{-1};
  std::atomic<int> latched_press{-1};         // the last press a read reported
  std::atomic<std::uint64_t> clean_reads{0};  // consecutive reads with the e-stop inactive
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
  const int max_presses = 3 * count;
  const auto slots = static_cast<std::size_t>(max_presses);
  std::vector<std::uint8_t> latched(slots, 0);
  std::vector<std::uint64_t> press_read(slots, 0);
  std::vector<std::uint64_t> latch_read(slots, 0);
  std::vector<std::int64_t> held_ns(slots, 0);
  Trial trial;
  std::uint64_t heap = 0;
  std::uint64_t read_errors = 0;

  // Every read, for the account of a press that was missed: when, which press was current,
  // the bit reported, whether the line had changed, whether it was a pulse (latch level
  // reported against the level read).
  struct ReadTrace {
    std::int64_t t_ns;
    int press;
    std::uint8_t bit;
    std::uint8_t changed;
    std::uint8_t pulse;
  };
  std::vector<ReadTrace> trace(static_cast<std::size_t>(max_presses) * 128);
  std::vector<std::int64_t> press_t(slots, 0);
  std::vector<std::int64_t> release_t(slots, 0);
  std::thread reader([&] {
    sched_param sp{};
    // Below the kernel's IRQ threads (SCHED_FIFO 50 on PREEMPT_RT), which deliver the edge
    // events: docs/gpio.md.
    sp.sched_priority = 40;
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    trainer::core::alloc::begin_counting_this_thread();
    const std::uint64_t before = trainer::core::alloc::counted_allocations();
    std::int64_t next = now_ns();
    std::uint64_t last_changed = 0;
    std::uint64_t last_pulses = 0;
    while (!trial.done.load(std::memory_order_acquire)) {
      next += period_ns;
      sleep_until(next);
      std::uint32_t levels = 0;
      if (device.read_digital_inputs(levels) != trainer::hal::ReturnCode::ok) ++read_errors;
      // The press current AFTER the read: a read that reports the e-stop active can only have
      // seen that press (the one before was reported, then two reads saw it released, before
      // it began). Loaded before the read, a reader descheduled between the load and the read
      // (the emulator does that for tens of ms) would credit the previous press.
      const int press = trial.current_press.load(std::memory_order_acquire);
      const std::uint64_t changed_before = device.stats().changed_reads[0];
      const std::uint64_t pulses_before = device.stats().pulses_latched[0];
      (void)changed_before;
      (void)pulses_before;
      const std::uint64_t index = trial.reads.fetch_add(1, std::memory_order_acq_rel) + 1;
      if (index < trace.size()) {
        trace[index] =
            ReadTrace{now_ns(), press, static_cast<std::uint8_t>(levels & 1U),
                      static_cast<std::uint8_t>(device.stats().changed_reads[0] != last_changed),
                      static_cast<std::uint8_t>(device.stats().pulses_latched[0] != last_pulses)};
      }
      last_changed = device.stats().changed_reads[0];
      last_pulses = device.stats().pulses_latched[0];
      if ((levels & 1U) != 0) {
        trial.clean_reads.store(0, std::memory_order_release);
        if (press >= 0 && latched[static_cast<std::size_t>(press)] == 0) {
          latched[static_cast<std::size_t>(press)] = 1;
          latch_read[static_cast<std::size_t>(press)] = index;
          trial.latched_press.store(press, std::memory_order_release);
        }
      } else {
        trial.clean_reads.fetch_add(1, std::memory_order_acq_rel);
      }
    }
    heap = trainer::core::alloc::counted_allocations() - before;
    trainer::core::alloc::end_counting_this_thread();
  });

  std::mt19937_64 random(0x5EED'0016);
  std::uniform_int_distribution<std::int64_t> phase(0, period_ns - 1);
  std::uniform_int_distribution<std::int64_t> hold(period_ns / 20, period_ns * 40 / 100);
  const auto wait_reads = [&](std::uint64_t n) {
    const std::uint64_t target = trial.reads.load(std::memory_order_acquire) + n;
    while (trial.reads.load(std::memory_order_acquire) < target) usleep(200);
  };
  // The presser wakes at its phase more punctually above the reader's priority (and below the
  // IRQ threads').
  sched_param presser_sp{};
  presser_sp.sched_priority = 45;
  (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &presser_sp);
  wait_reads(2);
  // Until `count` presses were held one period or less (the emulator can stretch one), at most
  // 3 * count presses in all.
  int within_period = 0;
  int made = 0;
  for (int k = 0; k < max_presses && within_period < count; ++k) {
    const auto i = static_cast<std::size_t>(k);
    sleep_until(now_ns() + phase(random));
    const std::int64_t hold_ns = hold(random);
    trial.current_press.store(k, std::memory_order_release);
    press_read[i] = trial.reads.load(std::memory_order_acquire);
    press_t[i] = now_ns();
    if (pwrite(pull, "pull-up", 7, 0) != 7) std::perror("pull-up");
    const std::int64_t pressed = now_ns();
    sleep_until(pressed + hold_ns);
    const std::int64_t before_release = now_ns();
    if (pwrite(pull, "pull-down", 9, 0) != 9) std::perror("pull-down");
    release_t[i] = now_ns();
    // Held at least from the end of the pull-up write to the start of the pull-down write.
    held_ns[i] = before_release - pressed;
    if (held_ns[i] <= period_ns) ++within_period;
    ++made;
    // Until a read reported this press (at most kGiveUpReads), then until two reads in a row
    // saw the e-stop inactive (the release's own event makes one read report the latch level
    // too): the next press cannot be credited with this one's events.
    const std::uint64_t give_up = trial.reads.load(std::memory_order_acquire) + kGiveUpReads;
    while (trial.latched_press.load(std::memory_order_acquire) != k &&
           trial.reads.load(std::memory_order_acquire) < give_up) {
      usleep(200);
    }
    trial.clean_reads.store(0, std::memory_order_release);
    while (trial.clean_reads.load(std::memory_order_acquire) < 2) usleep(200);
  }
  wait_reads(1);
  trial.done.store(true, std::memory_order_release);
  reader.join();
  close(pull);
  device.deactivate();

  int latched_count = 0;
  int latched_within_period = 0;
  std::uint64_t max_latency = 0;
  std::vector<int> latency_hist(4, 0);
  for (std::size_t i = 0; i < static_cast<std::size_t>(made); ++i) {
    if (latched[i] == 0) {
      std::printf(
          "press %zu NOT latched (held %.3f ms); reads from the one before it (ms from "
          "the press's start, current press, bit, changed, pulse), release at %.3f ms:\n",
          i, static_cast<double>(held_ns[i]) / 1e6,
          static_cast<double>(release_t[i] - press_t[i]) / 1e6);
      const std::uint64_t first = press_read[i];
      for (std::uint64_t r = first; r < first + 8 && r < trace.size(); ++r) {
        std::printf("  read %llu: %.3f ms press %d bit %u changed %u pulse %u\n",
                    static_cast<unsigned long long>(r),
                    static_cast<double>(trace[r].t_ns - press_t[i]) / 1e6, trace[r].press,
                    trace[r].bit, trace[r].changed, trace[r].pulse);
      }
      continue;
    }
    ++latched_count;
    if (held_ns[i] <= period_ns) ++latched_within_period;
    // Reads from the start of the press to the one that reported it (1 = the next read).
    const std::uint64_t latency = latch_read[i] - press_read[i];
    max_latency = std::max(max_latency, latency);
    ++latency_hist[std::min<std::size_t>(latency, 3)];
  }
  const std::int64_t max_held =
      *std::max_element(held_ns.begin(), held_ns.begin() + std::max(made, 1));
  std::printf(
      "presses %d latched %d within_one_period %d latched_within_one_period %d "
      "max_held_ms %.3f period_ms %.3f reads %llu read_errors %llu "
      "reads_reporting_latch_against_level %llu latency_reads_1 %d latency_reads_2 %d "
      "latency_reads_3plus %d max_latency_reads %llu heap_allocations_in_reader %llu\n",
      made, latched_count, within_period, latched_within_period,
      static_cast<double>(max_held) / 1e6, static_cast<double>(period_ns) / 1e6,
      static_cast<unsigned long long>(trial.reads.load()),
      static_cast<unsigned long long>(read_errors),
      static_cast<unsigned long long>(device.stats().pulses_latched[0]), latency_hist[1],
      latency_hist[2], latency_hist[3], static_cast<unsigned long long>(max_latency),
      static_cast<unsigned long long>(heap));
  return latched_count == made && within_period >= count && heap == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  if (command == "list" && argc == 3) return list(argv[2]);
  if (command == "get" && argc == 4) return get(argv[2], argv[3]);
  if (command == "configure" && argc == 3) return configure_cases(argv[2]);
  if (command == "presses" && argc == 6) {
    return presses(argv[2], argv[3], std::atoi(argv[4]), std::atoi(argv[5]));
  }
  std::fprintf(
      stderr,
      "usage: gpiod_bench list CHIP | get CHIP OFFSET | configure CHIP | presses CHIP PULL_FILE N "
      "PERIOD_US\n");
  return 2;
}
