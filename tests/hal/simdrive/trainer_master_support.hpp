// The trainer's CiA 402 master (hal/socketcan CanopenDevice) as the simulated drives' tests
// run it: the device file config/devices/canopen_vcan.toml turned into the master's parameters
// by rt/app's canopen_params_from, its deadlines widened (see kWideDeadlineNs), and cycled on
// the monotonic clock like the trainer's loop (read_encoders, read_actuator_status,
// write_actuators) every 4 ms (= the SYNC period: the file says sync_period_us = 0), not the
// scene's 1 ms: where the drives run in another thread or process (configure, the program
// test), being descheduled on a shared 2-core machine must not make a TPDO1 two SYNCs late.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "trainer/app/device_wiring.hpp"
#include "trainer/config/device.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"

namespace trainer::hal::simdrive::test_support {

// The file's identities, node ids, rated torques, mechanism, abort-connection option and
// heartbeat PERIODS are used as they are; the deadlines (drive heartbeat consumer, the master's
// drive heartbeat timeout, RPDO deadline) become 200 ms and the SDO timeout 500 ms, so threads
// and processes on a shared 2-core machine do not trip them by being descheduled.
inline constexpr std::int64_t kLoopPeriodNs = 4'000'000;
inline constexpr std::int64_t kWideDeadlineNs = 200'000'000;

using socketcan::CanopenDevice;
using socketcan::CanopenDeviceParams;

inline std::int64_t monotonic_now() {
  core::MonotonicClock clock;
  return clock.now_ns();
}

inline config::DeviceConfig vcan_device() {
  auto device =
      config::load_device(std::string(TRAINER_SOURCE_DIR) + "/config/devices/canopen_vcan.toml");
  EXPECT_TRUE(device) << (device ? "" : device.error().message);
  config::DeviceConfig config = std::move(*device);
  config.canopen.drive_heartbeat_consumer_ns = kWideDeadlineNs;
  config.canopen.drive_heartbeat_timeout_ns = kWideDeadlineNs;
  config.canopen.rpdo_timeout_ns = kWideDeadlineNs;
  config.canopen.sdo_timeout_ns = 500'000'000;
  return config;
}

// The master's parameters as the trainer makes them (rt/app canopen_params_from), for a scene
// whose loop runs at kLoopPeriodNs on this device.
inline CanopenDeviceParams master_params(const config::DeviceConfig& device) {
  config::SceneConfig scene;
  scene.device = device;
  scene.loop.period_ns = kLoopPeriodNs;
  return app::canopen_params_from(scene);
}

// The same for drives in another PROCESS (the simdrive program): the oldest TPDO used is also
// widened to kWideDeadlineNs (50 SYNCs), because a process descheduled for two 4 ms periods on
// a loaded 2-core machine (a parallel build, ctest -j2) would otherwise latch pdo_timeout. The
// in-process lockstep tests keep the trainer's kMaxPdoAgeSyncs and test it.
inline CanopenDeviceParams process_master_params(const config::DeviceConfig& device) {
  CanopenDeviceParams params = master_params(device);
  params.max_pdo_age_syncs = static_cast<std::uint32_t>(kWideDeadlineNs / kLoopPeriodNs);
  return params;
}

struct CycleResult {
  hal::ReturnCode encoders = hal::ReturnCode::ok;
  hal::ReturnCode status = hal::ReturnCode::ok;
  hal::ReturnCode actuators = hal::ReturnCode::ok;
  bool deactivate() const {
    return encoders == hal::ReturnCode::deactivate || status == hal::ReturnCode::deactivate ||
           actuators == hal::ReturnCode::deactivate;
  }
  bool error() const {
    return encoders == hal::ReturnCode::error || status == hal::ReturnCode::error ||
           actuators == hal::ReturnCode::error;
  }
};

// The master on `transport`, cycled by the caller's thread.
class TrainerMaster {
 public:
  TrainerMaster(const config::DeviceConfig& device, socketcan::CanTransport transport)
      : TrainerMaster(master_params(device), std::move(transport)) {}
  TrainerMaster(CanopenDeviceParams params, socketcan::CanTransport transport)
      : master_(std::make_unique<CanopenDevice>(clock_, std::move(params), std::move(transport))) {}

  CanopenDevice& master() { return *master_; }
  std::size_t channels() const { return master_->encoder_count(); }
  const std::vector<hal::EncoderSample>& samples() const { return samples_; }
  const std::vector<hal::ActuatorStatus>& status() const { return status_; }

  void bring_up() {
    auto configured = master_->configure();
    ASSERT_TRUE(configured) << configured.error().message;
    auto activated = master_->activate();
    ASSERT_TRUE(activated) << activated.error().message;
    samples_.assign(channels(), {});
    status_.assign(channels(), {});
    commands_.assign(channels(), {});
    next_cycle_ns_ = clock_.now_ns();
  }
  // Every channel enabled with `fraction` of its drive's maximum effort, alternating in sign.
  void command(double fraction) {
    const CanopenDeviceParams& params = master_->params();
    for (std::size_t i = 0; i < channels(); ++i) {
      const double max_effort = params.drives[i].scale.max_effort();
      commands_[i] = {static_cast<float>((i % 2 == 0 ? fraction : -fraction) * max_effort), true};
    }
  }
  // One loop cycle as the trainer runs it (read, status, write), then `after_write` (the drives'
  // turn when they run in lockstep), then wait for the next period.
  template <class AfterWrite>
  CycleResult cycle(AfterWrite&& after_write) {
    CycleResult result;
    result.encoders = master_->read_encoders(samples_);
    result.status = master_->read_actuator_status(status_);
    result.actuators = master_->write_actuators(commands_);
    after_write();
    next_cycle_ns_ += kLoopPeriodNs;
    clock_.sleep_until_ns(next_cycle_ns_);
    if (clock_.now_ns() > next_cycle_ns_ + 20 * kLoopPeriodNs)
      next_cycle_ns_ = clock_.now_ns();  // no bursts
    return result;
  }
  CycleResult cycle() {
    return cycle([] {});
  }
  bool all_enabled() const {
    return std::all_of(status_.begin(), status_.end(),
                       [](const hal::ActuatorStatus& s) { return s.enabled; });
  }

 private:
  core::MonotonicClock clock_;
  std::unique_ptr<CanopenDevice> master_;
  std::vector<hal::EncoderSample> samples_;
  std::vector<hal::ActuatorStatus> status_;
  std::vector<hal::ActuatorCommand> commands_;
  std::int64_t next_cycle_ns_ = 0;
};

}  // namespace trainer::hal::simdrive::test_support
