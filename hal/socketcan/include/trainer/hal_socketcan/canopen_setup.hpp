// The CiA 402 master's setup path (configure / activate): blocking SDO exchanges, boot-up
// detection and the drive configuration sequence, over the device's transport. Setup only:
// allocates, blocks up to the device file's timeouts (on the steady clock, whatever clock
// the RT cycle uses), never runs in the RT cycle. Public for the bring-up tool (tools/hil),
// which configures one drive at a time the way the trainer does.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/hal_canopen/sdo_client.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"

namespace trainer::hal::socketcan::detail {

class SetupBus {
 public:
  SetupBus(CanTransport& transport, std::string bus_name, std::int64_t sdo_timeout_ns);

  // Expedited or segmented SDO write of the low `size` bytes of `value` (little-endian).
  // `what` names the node and object for messages ("node 3 (left.insertion)").
  core::Expected<void> write(const std::string& who, std::uint8_t node, std::uint16_t index,
                             std::uint8_t sub, std::uint32_t value, std::size_t size);
  // SDO read of an object of 1..4 bytes, zero-extended.
  core::Expected<std::uint32_t> read(const std::string& who, std::uint8_t node,
                                     std::uint16_t index, std::uint8_t sub);
  // SDO read (expedited or segmented) of up to `max_bytes` bytes, e.g. a visible string.
  core::Expected<std::vector<std::uint8_t>> read_bytes(const std::string& who, std::uint8_t node,
                                                       std::uint16_t index, std::uint8_t sub,
                                                       std::size_t max_bytes);
  // Receives frames until `done` returns true for one of them or `timeout_ns` passes;
  // every frame goes to `on_frame` (boot-ups, EMCYs ...). False on timeout.
  bool wait_for(std::int64_t timeout_ns, const std::function<bool(const can_frame&)>& done);
  bool send(const can_frame& frame) { return transport_.send_one(frame); }
  const std::string& bus_name() const noexcept { return bus_name_; }

 private:
  core::Expected<void> run_transfer(const std::string& who, const char* verb,
                                    std::uint16_t index, std::uint8_t sub);

  CanTransport& transport_;
  std::string bus_name_;
  canopen::SdoClient sdo_;
};

// NMT reset communication to every drive, then waits for each one's boot-up message.
core::Expected<void> reset_and_wait_for_boot(SetupBus& bus, const CanopenDeviceParams& params);
// Identity, modes, rated torque, mode of operation, max torque, abort-connection option,
// heartbeats, PDOs of drive `index`.
core::Expected<void> configure_drive(SetupBus& bus, const CanopenDeviceParams& params,
                                     std::size_t index, std::int32_t max_torque_permille);
// A drive in Fault gets a fault reset; one that stays faulted fails with its 0x603F code.
core::Expected<void> clear_drive_fault(SetupBus& bus, const CanopenDeviceParams& params,
                                       std::size_t index);

// "node 3 (left.insertion)"
std::string drive_who(const CanopenDeviceParams& params, std::size_t index);

}  // namespace trainer::hal::socketcan::detail
