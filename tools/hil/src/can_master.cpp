#include "can_master.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "trainer/hal_canopen/cia402.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/sync.hpp"
#include "trainer/hal_socketcan/canopen_device.hpp"
#include "trainer/hil/operators.hpp"

namespace trainer::hil::can {

namespace co = trainer::hal::canopen;
namespace sc = trainer::hal::socketcan;

bool operation_enabled(std::uint16_t statusword) noexcept {
  return co::decode_statusword(statusword) == co::PowerState::operation_enabled;
}

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = std::ceil(p / 100.0 * static_cast<double>(values.size()));
  const auto index = static_cast<std::size_t>(std::clamp(rank, 1.0, static_cast<double>(values.size())));
  return values[index - 1];
}

Master::Master(sc::CanTransport& bus, std::int64_t slow_motion, std::int64_t period_ns,
               std::uint8_t master_node, std::int64_t heartbeat_ns)
    : bus_(bus),
      clock_(slow_motion),
      slow_motion_(slow_motion < 1 ? 1 : slow_motion),
      period_ns_(period_ns),
      master_node_(master_node),
      heartbeat_ns_(heartbeat_ns) {}

Master::~Master() { torque_off(); }

void Master::clear_events() noexcept {
  for (MasterDrive& drive : drives) {
    drive.emcy_code.reset();
    drive.emcy_ns = 0;
    drive.booted = false;
  }
}

void Master::torque_off() noexcept {
  const sc::PdoLayout& layout = sc::pdo_layout();
  for (MasterDrive& drive : drives) {
    can_frame rpdo{};
    rpdo.can_id = co::cob_id(co::FrameKind::rpdo, drive.node, 1);
    const std::array<std::int64_t, 2> values = {0, 0};  // disable voltage, zero torque
    (void)layout.rpdo1.pack(values, rpdo);
    (void)bus_.send_one(rpdo);
    drive.enable = false;
    drive.target_permille = 0;
  }
  (void)bus_.send_one(co::encode_sync());
  for (const MasterDrive& drive : drives) {
    (void)bus_.send_one(co::encode_nmt(co::NmtCommand::enter_pre_operational, drive.node));
  }
}

void Master::handle(const can_frame& frame) noexcept {
  const co::FrameClass kind = co::classify(frame);
  if (!kind.ok()) return;
  const std::int64_t now = clock_.now_ns();
  for (MasterDrive& drive : drives) {
    if (drive.node != kind.node_id) continue;
    if (kind.kind == co::FrameKind::tpdo && kind.pdo_number == 1) {
      std::array<std::int64_t, 3> values{};
      if (!sc::pdo_layout().tpdo1.unpack(frame, values)) return;
      drive.statusword = static_cast<std::uint16_t>(values[0]);
      drive.position = static_cast<std::int32_t>(values[1]);
      drive.torque_permille = static_cast<std::int16_t>(values[2]);
      if (record && !drive.answered_last_sync) {
        recorded.round_trip_ns.push_back(static_cast<double>(now - last_sync_ns_));
      }
      drive.tpdo_seen = true;
      drive.tpdo_ns = now;
      drive.answered_last_sync = true;
    } else if (kind.kind == co::FrameKind::emcy) {
      const auto emcy = co::decode_emcy(frame);
      if (emcy && emcy->error_code != 0 && !drive.emcy_code) {
        drive.emcy_code = emcy->error_code;
        drive.emcy_ns = now;
      }
    } else if (kind.kind == co::FrameKind::heartbeat) {
      const auto beat = co::decode_heartbeat(frame);
      if (beat && beat->state == co::NmtState::boot_up) drive.booted = true;
    }
  }
}

void Master::cycle() {
  throw_if_interrupted();
  if (!started_) {
    started_ = true;
    next_ns_ = clock_.now_ns();
    next_heartbeat_ns_ = next_ns_;
  }
  clock_.sleep_until_ns(next_ns_);
  const sc::PdoLayout& layout = sc::pdo_layout();
  std::array<can_frame, sc::kMaxFramesPerCall> out{};
  std::size_t count = 0;
  for (MasterDrive& drive : drives) {
    const co::PowerState state = co::decode_statusword(drive.statusword);
    drive.controlword = co::next_controlword(
        state, drive.enable ? co::PowerTarget::operation_enabled : co::PowerTarget::disabled,
        drive.controlword);
    const bool torque = drive.enable && state == co::PowerState::operation_enabled;
    const std::array<std::int64_t, 2> values = {drive.controlword,
                                                torque ? drive.target_permille : 0};
    can_frame& rpdo = out[count++];
    rpdo.can_id = co::cob_id(co::FrameKind::rpdo, drive.node, 1);
    (void)layout.rpdo1.pack(values, rpdo);
    if (record && drive.tpdo_seen && !drive.answered_last_sync && recorded.syncs > 0) {
      ++recorded.missing_tpdos;
    }
    drive.answered_last_sync = false;
  }
  out[count++] = co::encode_sync();
  const std::int64_t now = clock_.now_ns();
  if (record && recorded.syncs > 0) {
    recorded.sync_interval_error_ns.push_back(
        std::fabs(static_cast<double>(now - last_sync_ns_ - period_ns_)));
  }
  if (record) ++recorded.syncs;
  last_sync_ns_ = now;
  if (heartbeat_on && now >= next_heartbeat_ns_) {
    out[count++] = co::encode_heartbeat(master_node_, co::NmtState::operational);
    last_heartbeat_ns_ = now;
    next_heartbeat_ns_ += heartbeat_ns_;
    if (next_heartbeat_ns_ <= now) next_heartbeat_ns_ = now + heartbeat_ns_;
  }
  (void)bus_.send(std::span(out.data(), count));
  next_ns_ += period_ns_;
  if (clock_.now_ns() > next_ns_ + 20 * period_ns_) next_ns_ = clock_.now_ns();  // no bursts
  std::array<can_frame, sc::kMaxFramesPerCall> in{};
  for (;;) {
    const std::size_t received = bus_.receive(in);
    for (std::size_t i = 0; i < received; ++i) handle(in[i]);
    const std::int64_t left = next_ns_ - clock_.now_ns();
    if (left <= 0) break;
    if (received == 0) (void)bus_.wait_readable(left * slow_motion_);
  }
}

}  // namespace trainer::hil::can
