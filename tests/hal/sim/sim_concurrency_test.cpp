// Fault injection from a non-RT thread while the loop thread runs the RT calls: every control
// is an atomic, so TSan (tsan preset, label `concurrency`) must see no race, and the loop must
// only ever observe the return codes the injected faults allow.
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "sim_test_support.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::hal::sim {
namespace {

using test_support::bench_params;
using test_support::Commands;
using test_support::kMillisecondNs;
using test_support::Samples;
using test_support::Statuses;

TEST(SimDeviceConcurrency, FaultsInjectedFromAnotherThreadWhileTheLoopRuns) {
  core::ManualClock clock;  // touched by the loop thread only (late replies sleep on it)
  SimDevice device(clock, bench_params({"left", "right"}, "builtin:sweep"));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());

  std::atomic<bool> stop{false};
  std::atomic<int> injector_rounds{0};
  std::thread injector([&] {
    int round = 0;
    while (!stop.load(std::memory_order_acquire)) {
      const auto channel = static_cast<std::size_t>(round % 10);
      (void)device.inject_stuck_encoder(channel, round % 3 == 0);
      (void)device.inject_drive_fault(channel, round % 7 == 0);
      device.inject_read_failures(static_cast<std::uint32_t>(round % 2));
      device.inject_late_reply(10'000 + round % 5, static_cast<std::uint32_t>(round % 3));
      device.set_estop(round % 4 == 0);
      device.set_enable_switch(round % 5 != 0);
      (void)device.digital_output_levels();
      ++round;
      injector_rounds.store(round, std::memory_order_relaxed);
      std::this_thread::yield();
    }
    // Leave everything healthy.
    for (std::size_t channel = 0; channel < kMaxChannels; ++channel) {
      (void)device.inject_stuck_encoder(channel, false);
      (void)device.inject_drive_fault(channel, false);
    }
    device.inject_read_failures(0);
    device.inject_late_reply(0, 0);
    device.set_estop(false);
    device.set_enable_switch(true);
  });

  Samples samples{};
  Commands commands{};
  for (std::size_t channel = 0; channel < device.actuator_count(); ++channel) {
    commands[channel] = {0.01F, true};
  }
  Statuses statuses{};
  int read_errors = 0;
  int deactivates = 0;
  const int kCycles = 20'000;
  for (int cycle = 0; cycle < kCycles || injector_rounds.load(std::memory_order_relaxed) < 100;
       ++cycle) {
    clock.advance_ns(kMillisecondNs);
    const ReturnCode read = device.read_encoders(samples);
    ASSERT_NE(read, ReturnCode::deactivate) << "encoders never ask to deactivate";
    if (read == ReturnCode::error) {
      ++read_errors;
      for (std::size_t channel = 0; channel < device.encoder_count(); ++channel) {
        ASSERT_FALSE(samples[channel].valid);
      }
    }
    const ReturnCode write = device.write_actuators(commands);
    ASSERT_NE(write, ReturnCode::error) << "commands are finite and the device is active";
    if (write == ReturnCode::deactivate) ++deactivates;
    (void)device.read_actuator_status(statuses);
    std::uint32_t levels = 0;
    ASSERT_EQ(device.read_digital_inputs(levels), ReturnCode::ok);
    ASSERT_EQ(levels & ~0b11U, 0U) << "only the e-stop and enable bits exist";
  }
  stop.store(true, std::memory_order_release);
  injector.join();

  // Healthy again: every call succeeds and every sample is valid.
  clock.advance_ns(kMillisecondNs);
  ASSERT_EQ(device.read_encoders(samples), ReturnCode::ok);
  ASSERT_EQ(device.write_actuators(commands), ReturnCode::ok);
  ASSERT_EQ(device.read_actuator_status(statuses), ReturnCode::ok);
  for (std::size_t channel = 0; channel < device.encoder_count(); ++channel) {
    EXPECT_TRUE(samples[channel].valid);
    EXPECT_FALSE(statuses[channel].fault);
  }
  // Not asserted exactly (thread interleaving decides), only reported.
  RecordProperty("read_errors", read_errors);
  RecordProperty("deactivates", deactivates);
}

}  // namespace
}  // namespace trainer::hal::sim
