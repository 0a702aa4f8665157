// Shared fixtures of the simulated drive tests: a one-instrument bench (five drives, nodes 1..5)
// behind a SimDriveBus on one end of a socketpair, and on the other end a MASTER MADE OF
// HAND-WRITTEN FRAMES (CiA 301 / CiA 402 byte layouts spelt out here, not the project's master
// nor the protocol library's encoders), with a manual clock for the protocol timers.
#pragma once

#include <gtest/gtest.h>
#include <linux/can.h>

#include <algorithm>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "trainer/hal_simdrive/sim_drive_bus.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace trainer::hal::simdrive::test_support {

inline constexpr std::int64_t kSyncPeriodNs = 1'000'000;
inline constexpr std::uint32_t kVendor = 0x00545252;
inline constexpr std::uint32_t kProduct = 0x00000402;
inline constexpr std::uint32_t kRatedMnm = 60;  // 0x6076 of every test drive

// One instrument, gear 20 revolute joints, a 10 mm capstan for insertion (the hal/sim bench).
inline hal::sim::SimInstrumentParams test_instrument(std::string name) {
  hal::sim::SimInstrumentParams instrument;
  instrument.name = std::move(name);
  const auto revolute = [](double gear, double current_limit) {
    hal::JointScale scale;
    scale.kind = hal::JointKind::revolute;
    scale.counts_per_rev = 4096;
    scale.gear_ratio = gear;
    scale.torque_constant_nm_per_a = 0.03;
    scale.current_limit_a = current_limit;
    return scale;
  };
  instrument.scales[0] = revolute(20.0, 3.0);
  instrument.scales[1] = revolute(20.0, 3.0);
  hal::JointScale insertion;
  insertion.kind = hal::JointKind::prismatic;
  insertion.counts_per_rev = 4096;
  insertion.gear_ratio = 10.0;
  insertion.capstan_radius_m = 0.01;
  insertion.torque_constant_nm_per_a = 0.025;
  insertion.current_limit_a = 2.5;
  instrument.scales[2] = insertion;
  instrument.scales[3] = revolute(12.0, 1.0);  // 1 A: 30 mN·m = 500 permille of 60 mN·m
  instrument.scales[4] = revolute(20.0, 2.0);
  instrument.plant[0] = {0.002, 5.0, 0.1, -0.6, 0.6};
  instrument.plant[1] = {0.002, 5.0, 0.1, -0.6, 0.6};
  instrument.plant[2] = {0.15, 1500.0, 15.0, 0.0, 0.25};
  instrument.plant[3] = {0.0002, 0.5, 0.02, -3.14, 3.14};
  instrument.plant[4] = {0.0001, 0.5, 0.01, 0.0, 0.8};
  return instrument;
}

inline SimDriveBusParams test_bus_params(std::string script = "builtin:hold") {
  SimDriveBusParams params;
  params.name = "test_drives";
  params.sync_period_ns = kSyncPeriodNs;
  params.plant.name = "test_plant";
  params.plant.plant_substep_ns = 100'000;
  params.plant.script = std::move(script);
  params.plant.instruments.push_back(test_instrument("left"));
  for (std::uint8_t node = 1; node <= 5; ++node) {
    SimDriveNodeParams drive;
    drive.node_id = node;
    drive.identity = {kVendor, kProduct, 7, 1000U + node};
    drive.motor_rated_torque_mnm = kRatedMnm;
    drive.scale = params.plant.instruments[0].scales[node - 1U];
    params.nodes.push_back(drive);
  }
  params.digital_inputs_node = 1;
  params.digital_outputs_node = 1;
  return params;
}

// --- hand-written frames ---------------------------------------------------------------------

inline can_frame raw_frame(canid_t id, std::initializer_list<std::uint8_t> bytes) {
  can_frame frame{};
  frame.can_id = id;
  frame.len = static_cast<std::uint8_t>(bytes.size());
  std::copy(bytes.begin(), bytes.end(), frame.data);
  return frame;
}
inline std::uint8_t byte_of(std::uint32_t value, unsigned n) {
  return static_cast<std::uint8_t>((value >> (8 * n)) & 0xFFU);
}
inline std::uint16_t le16(const can_frame& frame, std::size_t at) {
  return static_cast<std::uint16_t>(frame.data[at] | (frame.data[at + 1] << 8));
}
inline std::uint32_t le32(const can_frame& frame, std::size_t at) {
  return static_cast<std::uint32_t>(frame.data[at]) |
         (static_cast<std::uint32_t>(frame.data[at + 1]) << 8) |
         (static_cast<std::uint32_t>(frame.data[at + 2]) << 16) |
         (static_cast<std::uint32_t>(frame.data[at + 3]) << 24);
}
// NMT: id 0, {command specifier, node} (CiA 301 7.2.8.3.1).
inline can_frame nmt_frame(std::uint8_t command, std::uint8_t node) {
  return raw_frame(0x000, {command, node});
}
inline constexpr std::uint8_t kNmtStart = 0x01, kNmtStop = 0x02, kNmtPreOperational = 0x80,
                              kNmtResetNode = 0x81, kNmtResetCommunication = 0x82;
inline can_frame sync_frame() {
  return raw_frame(0x080, {});
}
inline can_frame heartbeat_frame(std::uint8_t node, std::uint8_t state) {
  return raw_frame(0x700U + node, {state});
}
// Expedited SDO download (CiA 301 7.2.4.3.3): 0x23/0x27/0x2B/0x2F for 4/3/2/1 bytes.
inline can_frame sdo_download(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                              std::uint32_t value, unsigned size) {
  const auto command = static_cast<std::uint8_t>(0x23 | ((4U - size) << 2));
  return raw_frame(0x600U + node,
                   {command, byte_of(index, 0), byte_of(index, 1), sub, byte_of(value, 0),
                    byte_of(value, 1), byte_of(value, 2), byte_of(value, 3)});
}
inline can_frame sdo_upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  return raw_frame(0x600U + node, {0x40, byte_of(index, 0), byte_of(index, 1), sub, 0, 0, 0, 0});
}

inline std::vector<can_frame> with_id(const std::vector<can_frame>& frames, canid_t id) {
  std::vector<can_frame> out;
  for (const can_frame& frame : frames) {
    if (frame.can_id == id) out.push_back(frame);
  }
  return out;
}
inline bool has_id(const std::vector<can_frame>& frames, canid_t id) {
  return !with_id(frames, id).empty();
}

struct SdoResult {
  std::uint32_t abort = 0;  // 0 = done
  std::uint32_t value = 0;  // upload: the expedited value
  bool answered = false;
};

// The bus under test and the master's end of the socketpair, on a manual protocol clock.
class DriveHarness {
 public:
  explicit DriveHarness(SimDriveBusParams params = test_bus_params()) {
    auto pair = socketcan::make_transport_pair("master", "drives");
    EXPECT_TRUE(pair) << (pair ? "" : pair.error().message);
    master_ = std::make_unique<socketcan::CanTransport>(std::move(pair->a));
    auto created = SimDriveBus::create(std::move(params), std::move(pair->b));
    EXPECT_TRUE(created) << (created ? "" : created.error().message);
    bus_ = std::move(*created);
  }

  SimDriveBus& bus() { return *bus_; }
  std::int64_t now() const { return now_ns_; }
  socketcan::CanTransport& master() { return *master_; }

  std::vector<can_frame> power_on() {
    bus_->power_on(now_ns_);
    return receive();
  }
  // Sends `frames`, lets `advance_ns` pass, polls the bus once, returns what it sent.
  std::vector<can_frame> exchange(std::initializer_list<can_frame> frames,
                                  std::int64_t advance_ns = 0) {
    for (const can_frame& frame : frames) EXPECT_TRUE(master_->send_one(frame));
    return poll(advance_ns);
  }
  std::vector<can_frame> poll(std::int64_t advance_ns = 0) {
    now_ns_ += advance_ns;
    if (master_heartbeat_period_ns_ > 0 &&
        now_ns_ - last_master_heartbeat_ns_ >= master_heartbeat_period_ns_) {
      EXPECT_TRUE(master_->send_one(heartbeat_frame(master_node_, 0x05)));
      last_master_heartbeat_ns_ = now_ns_;
    }
    next_deadline_ns_ = bus_->poll(now_ns_);
    return receive();
  }
  // From now on every poll() that finds `period_ns` passed since the last one first sends the
  // master's heartbeat (operational), as a live master would; starting with one now.
  void keep_master_alive(std::uint8_t master_node, std::int64_t period_ns) {
    master_node_ = master_node;
    master_heartbeat_period_ns_ = period_ns;
    last_master_heartbeat_ns_ = now_ns_ - period_ns;
  }
  void stop_master_heartbeat() { master_heartbeat_period_ns_ = 0; }
  std::int64_t last_master_heartbeat() const { return last_master_heartbeat_ns_; }
  std::vector<can_frame> receive() {
    std::vector<can_frame> out;
    std::array<can_frame, 64> buffer{};
    for (;;) {
      const std::size_t count = master_->receive(buffer);
      out.insert(out.end(), buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(count));
      if (count < buffer.size()) break;
    }
    return out;
  }
  // One SYNC period: the clock moves one period, then SYNC (after `before`, e.g. RPDOs).
  std::vector<can_frame> sync(std::initializer_list<can_frame> before = {}) {
    for (const can_frame& frame : before) EXPECT_TRUE(master_->send_one(frame));
    EXPECT_TRUE(master_->send_one(sync_frame()));
    return poll(kSyncPeriodNs);
  }

  SdoResult sdo(const can_frame& request) {
    const std::vector<can_frame> frames = exchange({request});
    SdoResult result;
    for (const can_frame& frame : frames) {
      if (frame.can_id != 0x580U + (request.can_id - 0x600U) || frame.len != 8) continue;
      result.answered = true;
      if (frame.data[0] == 0x80) {
        result.abort = le32(frame, 4);
      } else if ((frame.data[0] & 0xE0) == 0x40 && (frame.data[0] & 0x02) != 0) {
        const unsigned empty = (frame.data[0] & 0x01) != 0 ? (frame.data[0] >> 2) & 3U : 0U;
        result.value = le32(frame, 4);
        if (empty > 0) result.value &= 0xFFFFFFFFU >> (8 * empty);
      }
    }
    return result;
  }
  std::uint32_t write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                      unsigned size) {
    const SdoResult result = sdo(sdo_download(node, index, sub, value, size));
    EXPECT_TRUE(result.answered) << "no SDO answer from node " << int{node};
    return result.abort;
  }
  std::uint32_t read(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    const SdoResult result = sdo(sdo_upload(node, index, sub));
    EXPECT_TRUE(result.answered) << "no SDO answer from node " << int{node};
    EXPECT_EQ(result.abort, 0U) << std::hex << "read 0x" << index << ":" << int{sub}
                                << " aborted 0x" << result.abort;
    return result.value;
  }

  // The trainer's layout configured by hand (CiA 301 7.5.2.35/36 sequence, spelt out): RPDO1
  // {0x6040, 0x6071} and TPDO1 {0x6041, 0x6064, 0x6077}, both synchronous every SYNC.
  void map_trainer_pdos(std::uint8_t node, std::uint16_t rpdo_event_timer_ms = 0) {
    EXPECT_EQ(write(node, 0x1400, 1, 0x80000200U + node, 4), 0U);
    EXPECT_EQ(write(node, 0x1400, 2, 1, 1), 0U);
    EXPECT_EQ(write(node, 0x1400, 5, rpdo_event_timer_ms, 2), 0U);
    EXPECT_EQ(write(node, 0x1600, 0, 0, 1), 0U);
    EXPECT_EQ(write(node, 0x1600, 1, 0x60400010, 4), 0U);
    EXPECT_EQ(write(node, 0x1600, 2, 0x60710010, 4), 0U);
    EXPECT_EQ(write(node, 0x1600, 0, 2, 1), 0U);
    EXPECT_EQ(write(node, 0x1400, 1, 0x00000200U + node, 4), 0U);
    EXPECT_EQ(write(node, 0x1800, 1, 0xC0000180U + node, 4), 0U);
    EXPECT_EQ(write(node, 0x1800, 2, 1, 1), 0U);
    EXPECT_EQ(write(node, 0x1A00, 0, 0, 1), 0U);
    EXPECT_EQ(write(node, 0x1A00, 1, 0x60410010, 4), 0U);
    EXPECT_EQ(write(node, 0x1A00, 2, 0x60640020, 4), 0U);
    EXPECT_EQ(write(node, 0x1A00, 3, 0x60770010, 4), 0U);
    EXPECT_EQ(write(node, 0x1A00, 0, 3, 1), 0U);
    EXPECT_EQ(write(node, 0x1800, 1, 0x40000180U + node, 4), 0U);
  }
  static can_frame rpdo1(std::uint8_t node, std::uint16_t controlword,
                         std::int16_t torque_permille) {
    const auto torque = static_cast<std::uint16_t>(torque_permille);
    return raw_frame(0x200U + node, {byte_of(controlword, 0), byte_of(controlword, 1),
                                     byte_of(torque, 0), byte_of(torque, 1)});
  }
  // Walks `node` (trainer PDOs mapped, operational) to Operation enabled with `torque`: shutdown,
  // switch on, enable operation, one SYNC each. Returns the last SYNC's frames.
  std::vector<can_frame> enable(std::uint8_t node, std::int16_t torque) {
    (void)sync({rpdo1(node, 0x06, 0)});
    (void)sync({rpdo1(node, 0x07, 0)});
    return sync({rpdo1(node, 0x0F, torque)});
  }

  std::vector<DriveEvent> events() {
    std::vector<DriveEvent> out;
    DriveEvent event;
    while (bus_->events().pop(event)) out.push_back(event);
    return out;
  }
  std::int64_t next_deadline() const { return next_deadline_ns_; }

 private:
  std::unique_ptr<socketcan::CanTransport> master_;
  std::unique_ptr<SimDriveBus> bus_;
  std::int64_t now_ns_ = 5'000'000'000;
  std::int64_t next_deadline_ns_ = 0;
  std::uint8_t master_node_ = 127;
  std::int64_t master_heartbeat_period_ns_ = 0;
  std::int64_t last_master_heartbeat_ns_ = 0;
};

inline std::vector<DriveEvent> of_kind(const std::vector<DriveEvent>& events, EventKind kind,
                                       std::uint8_t node = 0) {
  std::vector<DriveEvent> out;
  for (const DriveEvent& event : events) {
    if (event.kind == kind && (node == 0 || event.node == node)) out.push_back(event);
  }
  return out;
}

// Statusword state bits (CiA 402 Table 30) read without the library.
inline bool is_operation_enabled(std::uint16_t statusword) {
  return (statusword & 0x6F) == 0x27;
}
inline bool is_switch_on_disabled(std::uint16_t statusword) {
  return (statusword & 0x4F) == 0x40;
}
inline bool is_fault(std::uint16_t statusword) {
  return (statusword & 0x4F) == 0x08;
}
inline bool is_ready_to_switch_on(std::uint16_t statusword) {
  return (statusword & 0x6F) == 0x21;
}
inline bool is_switched_on(std::uint16_t statusword) {
  return (statusword & 0x6F) == 0x23;
}

}  // namespace trainer::hal::simdrive::test_support
