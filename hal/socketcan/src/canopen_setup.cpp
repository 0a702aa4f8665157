#include "trainer/hal_socketcan/canopen_setup.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <utility>
#include <vector>

#include "trainer/core/fixed_vector.hpp"

#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_canopen/pdo.hpp"

namespace trainer::hal::socketcan::detail {

namespace co = trainer::hal::canopen;

namespace {

using SteadyClock = std::chrono::steady_clock;

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             SteadyClock::now().time_since_epoch())
      .count();
}

std::string hex(std::uint32_t value, int digits) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%0*X", digits, value);
  return text;
}

std::string object_name(std::uint16_t index, std::uint8_t sub) {
  return hex(index, 4) + ":" + hex(sub, 2).substr(2);
}

// Rated torque read back may differ from the file by the drive's mN·m rounding.
constexpr double kRatedTorqueTolerance = 0.005;


}  // namespace

std::string drive_who(const CanopenDeviceParams& params, std::size_t index) {
  const DriveParams& drive = params.drives[index];
  return "node " + std::to_string(drive.node_id) + " (" + drive.channel_name + ")";
}

SetupBus::SetupBus(CanTransport& transport, std::string bus_name, std::int64_t sdo_timeout_ns)
    : transport_(transport), bus_name_(std::move(bus_name)) {
  sdo_.set_response_timeout_ns(sdo_timeout_ns);
}

bool SetupBus::wait_for(std::int64_t timeout_ns,
                        const std::function<bool(const can_frame&)>& done) {
  const std::int64_t deadline = steady_now_ns() + timeout_ns;
  std::array<can_frame, kMaxFramesPerCall> frames{};
  for (;;) {
    const std::size_t count = transport_.receive(frames);
    for (std::size_t i = 0; i < count; ++i) {
      if (done(frames[i])) return true;
    }
    const std::int64_t left = deadline - steady_now_ns();
    if (left <= 0) return false;
    if (count == 0) (void)transport_.wait_readable(std::min<std::int64_t>(left, 5'000'000));
  }
}

core::Expected<void> SetupBus::run_transfer(const std::string& who, const char* verb,
                                            std::uint16_t index, std::uint8_t sub) {
  while (sdo_.busy()) {
    while (auto tx = sdo_.next_tx()) {
      if (!transport_.send_one(*tx)) {
        sdo_.abort(co::kAbortGeneral);
        return core::make_error(who + ": SDO " + verb + " of " + object_name(index, sub) +
                                " could not be sent on " + bus_name_ + " (transmit queue full " +
                                "or interface down)");
      }
    }
    (void)wait_for(5'000'000, [&](const can_frame& frame) {
      return sdo_.on_frame(frame, steady_now_ns()) && !sdo_.busy();
    });
    sdo_.on_time(steady_now_ns());
  }
  // The abort the client queued on a timeout or protocol error goes out too.
  while (auto tx = sdo_.next_tx()) (void)transport_.send_one(*tx);
  if (sdo_.status() == co::SdoStatus::done) return {};
  const std::uint32_t code = sdo_.abort_code();
  std::string message = who + ": SDO " + verb + " of object " + object_name(index, sub);
  if (sdo_.status() == co::SdoStatus::timed_out) {
    message += " got no answer on " + bus_name_ + " within " +
               std::to_string(sdo_.response_timeout_ns() / 1'000'000) +
               " ms (canopen.sdo_timeout_ms): is the node powered, its id right, the bitrate "
               "the bus's?";
  } else {
    message += std::string(" was aborted by the ") +
               (sdo_.aborted_by_server() ? "drive" : "master") + " with " + hex(code, 8) + " (" +
               co::describe_sdo_abort(code) + ")";
  }
  return core::make_error(std::move(message));
}

core::Expected<void> SetupBus::write(const std::string& who, std::uint8_t node,
                                     std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                                     std::size_t size) {
  std::array<std::uint8_t, 4> bytes{};
  for (std::size_t i = 0; i < 4; ++i) bytes[i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
  if (auto started = sdo_.start_download(node, index, sub, std::span(bytes.data(), size),
                                         steady_now_ns());
      !started) {
    return core::make_error(who + ": SDO write of " + object_name(index, sub) +
                            " could not start: " + started.detail());
  }
  return run_transfer(who, "write", index, sub);
}

core::Expected<std::uint32_t> SetupBus::read(const std::string& who, std::uint8_t node,
                                             std::uint16_t index, std::uint8_t sub) {
  std::array<std::uint8_t, 4> bytes{};
  if (auto started = sdo_.start_upload(node, index, sub, bytes, steady_now_ns()); !started) {
    return core::make_error(who + ": SDO read of " + object_name(index, sub) +
                            " could not start: " + started.detail());
  }
  if (auto done = run_transfer(who, "read", index, sub); !done) return std::move(done).error();
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < sdo_.transferred_bytes() && i < 4; ++i) {
    value |= static_cast<std::uint32_t>(bytes[i]) << (8 * i);
  }
  return value;
}

core::Expected<std::vector<std::uint8_t>> SetupBus::read_bytes(const std::string& who,
                                                               std::uint8_t node,
                                                               std::uint16_t index,
                                                               std::uint8_t sub,
                                                               std::size_t max_bytes) {
  std::vector<std::uint8_t> bytes(max_bytes);
  if (auto started = sdo_.start_upload(node, index, sub, bytes, steady_now_ns()); !started) {
    return core::make_error(who + ": SDO read of " + object_name(index, sub) +
                            " could not start: " + started.detail());
  }
  if (auto done = run_transfer(who, "read", index, sub); !done) return std::move(done).error();
  bytes.resize(std::min(sdo_.transferred_bytes(), max_bytes));
  return bytes;
}

core::Expected<void> reset_and_wait_for_boot(SetupBus& bus, const CanopenDeviceParams& params) {
  std::vector<bool> booted(params.drives.size(), false);
  std::size_t waiting = params.drives.size();
  for (const DriveParams& drive : params.drives) {
    if (!bus.send(co::encode_nmt(co::NmtCommand::reset_communication, drive.node_id))) {
      return core::make_error(params.name + ": NMT reset communication to node " +
                              std::to_string(drive.node_id) + " could not be sent on " +
                              bus.bus_name());
    }
  }
  (void)bus.wait_for(params.boot_timeout_ns, [&](const can_frame& frame) {
    const auto beat = co::decode_heartbeat(frame);
    if (!beat || beat->state != co::NmtState::boot_up) return false;
    for (std::size_t i = 0; i < params.drives.size(); ++i) {
      if (params.drives[i].node_id == beat->node_id && !booted[i]) {
        booted[i] = true;
        --waiting;
      }
    }
    return waiting == 0;
  });
  for (std::size_t i = 0; i < booted.size(); ++i) {
    if (booted[i]) continue;
    return core::make_error(
        drive_who(params, i) + " did not answer on " + bus.bus_name() +
        ": no boot-up message within " + std::to_string(params.boot_timeout_ns / 1'000'000) +
        " ms of NMT reset communication (canopen.boot_timeout_ms); check the drive's power, "
        "its node id (" + params.drives[i].config_key + ".node_id) and the bus bitrate");
  }
  return {};
}

namespace {

struct Write {
  std::uint16_t index;
  std::uint8_t sub;
  std::uint32_t value;
  std::size_t size;
};

core::Expected<void> run_writes(SetupBus& bus, const std::string& who, std::uint8_t node,
                                std::span<const Write> writes) {
  for (const Write& w : writes) {
    if (auto done = bus.write(who, node, w.index, w.sub, w.value, w.size); !done) return done;
  }
  return {};
}

core::Expected<void> check_identity(SetupBus& bus, const CanopenDeviceParams& params,
                                    std::size_t index) {
  const DriveParams& drive = params.drives[index];
  const std::string who = drive_who(params, index);
  struct Expected {
    std::uint8_t sub;
    std::uint32_t value;
    const char* what;
    const char* key;
  };
  std::vector<Expected> checks = {{1, drive.vendor_id, "vendor id", "vendor_id"},
                                  {2, drive.product_code, "product code", "product_code"}};
  if (drive.revision) checks.push_back({3, *drive.revision, "revision", "revision"});
  for (const Expected& check : checks) {
    auto value = bus.read(who, drive.node_id, co::kObjectIdentity, check.sub);
    if (!value) return std::move(value).error();
    if (*value != check.value) {
      return core::make_error(who + ": identity 0x1018:" + std::to_string(check.sub) + " (" +
                              check.what + ") is " + hex(*value, 8) + ", expected " +
                              hex(check.value, 8) + " (" + drive.config_key + "." + check.key +
                              "): a different drive than the device file describes");
    }
  }
  return {};
}

// The trainer's PDO layout (canopen_device.hpp): RPDO1, RPDO2 on the outputs node, TPDO1,
// TPDO2; every other PDO switched off so the drive sends nothing the master does not read.
core::Expected<void> configure_pdos(SetupBus& bus, const CanopenDeviceParams& params,
                                    std::size_t index) {
  const DriveParams& drive = params.drives[index];
  const std::string who = drive_who(params, index);
  const std::uint8_t node = drive.node_id;
  const auto rpdo_deadline_ms = static_cast<std::uint16_t>(params.rpdo_timeout_ns / 1'000'000);
  std::vector<co::PdoConfiguration> pdos;
  const auto add = [&](co::PdoDirection direction, std::uint16_t number,
                       const co::PdoMapping& mapping, std::optional<std::uint16_t> event_timer_ms,
                       std::uint8_t every_syncs) {
    co::PdoConfiguration config;
    config.direction = direction;
    config.pdo_number = number;
    config.can_id = co::cob_id(
        direction == co::PdoDirection::receive ? co::FrameKind::rpdo : co::FrameKind::tpdo, node,
        static_cast<std::uint8_t>(number));
    config.transmission_type = every_syncs;  // synchronous, every n-th SYNC
    config.event_timer_ms = event_timer_ms;
    config.mapping = mapping;
    pdos.push_back(config);
  };
  using co::PdoDirection;
  const PdoLayout& layout = pdo_layout();
  add(PdoDirection::receive, 1, layout.rpdo1, rpdo_deadline_ms, 1);
  const bool outputs_node = params.digital_outputs_node == node;
  if (outputs_node) add(PdoDirection::receive, 2, layout.rpdo2, std::nullopt, 1);
  add(PdoDirection::transmit, 1, layout.tpdo1, std::nullopt, 1);
  const bool inputs_node = params.digital_inputs_node == node;
  add(PdoDirection::transmit, 2, layout.tpdo2, std::nullopt,
      inputs_node ? std::uint8_t{1} : kDiagnosticPdoEverySyncs);
  for (const co::PdoConfiguration& pdo : pdos) {
    core::FixedVector<co::SdoWrite, co::kMaxPdoConfigurationWrites> writes;
    if (auto planned = co::pdo_configuration_writes(pdo, writes); !planned) {
      return core::make_error(who + ": PDO configuration: " + planned.detail());
    }
    for (const co::SdoWrite& w : writes) {
      if (auto done = bus.write(who, node, w.index, w.sub, w.value, w.size); !done) return done;
    }
  }
  // Off: RPDO2 (unless the outputs node), RPDO3/4, TPDO3/4 (CiA 301: COB-ID bit 31).
  std::vector<std::pair<PdoDirection, std::uint16_t>> off = {
      {PdoDirection::receive, 3}, {PdoDirection::receive, 4},
      {PdoDirection::transmit, 3}, {PdoDirection::transmit, 4}};
  if (!outputs_node) off.emplace_back(PdoDirection::receive, 2);
  for (const auto& [direction, number] : off) {
    const std::uint16_t id = co::cob_id(
        direction == PdoDirection::receive ? co::FrameKind::rpdo : co::FrameKind::tpdo, node,
        static_cast<std::uint8_t>(number));
    if (auto done = bus.write(who, node, co::pdo_communication_index(direction, number), 1,
                              co::encode_pdo_cob_id(id, false), 4);
        !done) {
      return done;
    }
  }
  return {};
}

}  // namespace

core::Expected<void> configure_drive(SetupBus& bus, const CanopenDeviceParams& params,
                                     std::size_t index, std::int32_t max_torque_permille) {
  const DriveParams& drive = params.drives[index];
  const std::string who = drive_who(params, index);
  const std::uint8_t node = drive.node_id;
  if (auto identity = check_identity(bus, params, index); !identity) return identity;

  auto modes = bus.read(who, node, co::kObjectSupportedDriveModes, 0);
  if (!modes) return std::move(modes).error();
  if ((*modes & co::supported_mode_bit(co::OperationMode::cyclic_synchronous_torque)) == 0U) {
    return core::make_error(who + ": supported drive modes 0x6502 = " + hex(*modes, 8) +
                            " lacks cyclic synchronous torque (bit 9): the trainer drives "
                            "torque (CST, mode 10)");
  }
  auto rated = bus.read(who, node, co::kObjectMotorRatedTorque, 0);
  if (!rated) return std::move(rated).error();
  const double rated_nm = static_cast<double>(*rated) * 1e-3;  // mN·m
  if (std::fabs(rated_nm - drive.motor_rated_torque_nm) >
      kRatedTorqueTolerance * drive.motor_rated_torque_nm) {
    char text[200];
    std::snprintf(text, sizeof text,
                  ": motor rated torque 0x6076 = %u mN·m, expected %.1f mN·m (%s."
                  "motor_rated_torque_nm = %g) within 0.5%%: the torque scale would be wrong",
                  *rated, drive.motor_rated_torque_nm * 1e3, drive.config_key.c_str(),
                  drive.motor_rated_torque_nm);
    return core::make_error(who + text);
  }

  const auto heartbeat_ms = static_cast<std::uint32_t>(params.drive_heartbeat_ns / 1'000'000);
  const auto consumer_ms =
      static_cast<std::uint16_t>(params.drive_heartbeat_consumer_ns / 1'000'000);
  const std::array<Write, 5> drive_setup = {{
      {co::kObjectModesOfOperation, 0,
       static_cast<std::uint32_t>(co::OperationMode::cyclic_synchronous_torque), 1},
      {co::kObjectMaxTorque, 0, static_cast<std::uint32_t>(max_torque_permille), 2},
      {co::kObjectAbortConnectionOption, 0, params.abort_connection_option, 2},
      {co::kObjectProducerHeartbeatTime, 0, heartbeat_ms, 2},
      {co::kObjectConsumerHeartbeatTime, 1,
       co::encode_consumer_entry(params.master_node_id, consumer_ms), 4},
  }};
  if (auto done = run_writes(bus, who, node, drive_setup); !done) return done;
  return configure_pdos(bus, params, index);
}

core::Expected<void> clear_drive_fault(SetupBus& bus, const CanopenDeviceParams& params,
                                       std::size_t index) {
  const DriveParams& drive = params.drives[index];
  const std::string who = drive_who(params, index);
  auto status = bus.read(who, drive.node_id, co::kObjectStatusword, 0);
  if (!status) return std::move(status).error();
  if (co::decode_statusword(static_cast<std::uint16_t>(*status)) == co::PowerState::fault) {
    // Fault reset is the rising edge of controlword bit 7.
    if (auto low = bus.write(who, drive.node_id, co::kObjectControlword, 0, 0x0000, 2); !low) return low;
    if (auto edge = bus.write(who, drive.node_id, co::kObjectControlword, 0, co::kCommandFaultReset, 2);
        !edge) {
      return edge;
    }
    status = bus.read(who, drive.node_id, co::kObjectStatusword, 0);
    if (!status) return std::move(status).error();
    if (co::decode_statusword(static_cast<std::uint16_t>(*status)) == co::PowerState::fault) {
      auto code = bus.read(who, drive.node_id, co::kObjectErrorCode, 0);
      const std::uint16_t error = code ? static_cast<std::uint16_t>(*code) : 0;
      return core::make_error(who + " stays in Fault after a fault reset: error code 0x603F = " +
                              hex(error, 4) + " (" + co::describe_emcy_code(error) + ")");
    }
  }
  // Shutdown: Ready to switch on, power stage off; the RT cycle enables from there.
  return bus.write(who, drive.node_id, co::kObjectControlword, 0, co::kCommandShutdown, 2);
}

}  // namespace trainer::hal::socketcan::detail
