// SimDriveBus: setup, the poll loop (frames, SYNC, timers), the plant per SYNC, fault injection
// and the filtered transmit path.
#include "trainer/hal_simdrive/sim_drive_bus.hpp"

#include <linux/can/error.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <utility>

#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/sync.hpp"

namespace trainer::hal::simdrive {

namespace co = trainer::hal::canopen;

namespace {

constexpr std::int64_t kBusNoDeadline = std::numeric_limits<std::int64_t>::max();

bool lasting_kind(FaultKind kind) noexcept {
  return kind == FaultKind::drop || kind == FaultKind::delay || kind == FaultKind::corrupt ||
         kind == FaultKind::silent || kind == FaultKind::lost_sync || kind == FaultKind::push;
}

}  // namespace

SimDriveBus::SimDriveBus(SimDriveBusParams params, socketcan::CanTransport transport)
    : params_(std::move(params)),
      transport_(std::move(transport)),
      events_(params_.event_capacity),
      plant_(plant_clock_, params_.plant) {
  node_of_id_.fill(-1);
}

SimDriveBus::~SimDriveBus() {
  plant_.deactivate();
}

core::Expected<std::unique_ptr<SimDriveBus>> SimDriveBus::create(
    SimDriveBusParams params, socketcan::CanTransport transport) {
  std::unique_ptr<SimDriveBus> bus(new SimDriveBus(std::move(params), std::move(transport)));
  if (auto ready = bus->setup(); !ready) return std::move(ready).error();
  return bus;
}

core::Expected<void> SimDriveBus::setup() {
  const std::string who = "simdrive '" + params_.name + "': ";
  if (params_.sync_period_ns <= 0 || params_.sync_period_ns % params_.plant.plant_substep_ns != 0) {
    return core::make_error(who + "SYNC period " + std::to_string(params_.sync_period_ns) +
                            " ns is not a positive whole multiple of the plant sub-step (" +
                            std::to_string(params_.plant.plant_substep_ns) +
                            " ns): the plant would not advance exactly one period per SYNC");
  }
  if (auto configured = plant_.configure(); !configured)
    return core::make_error(who + configured.error().message);
  if (params_.nodes.size() != plant_.channel_count()) {
    return core::make_error(who + std::to_string(params_.nodes.size()) + " drives for " +
                            std::to_string(plant_.channel_count()) +
                            " plant channels: expected one drive per joint");
  }
  for (std::size_t i = 0; i < params_.nodes.size(); ++i) {
    const SimDriveNodeParams& node_params = params_.nodes[i];
    auto node = SimDriveNode::create(node_params, events_);
    if (!node) return core::make_error(who + plant_.channel_name(i) + ": " + node.error().message);
    if (node_of_id_[node_params.node_id] >= 0) {
      return core::make_error(
          who + plant_.channel_name(i) + ": node id " + std::to_string(node_params.node_id) +
          " already used by " +
          plant_.channel_name(static_cast<std::size_t>(node_of_id_[node_params.node_id])));
    }
    node_of_id_[node_params.node_id] = static_cast<std::int16_t>(i);
    nodes_.push_back(std::move(*node));
  }
  for (const auto& [key, id] : {std::pair{"digital_inputs_node", params_.digital_inputs_node},
                                std::pair{"digital_outputs_node", params_.digital_outputs_node}}) {
    if (id != -1 && (id < 1 || id > 127 || node_of_id_[static_cast<std::size_t>(id)] < 0)) {
      return core::make_error(who + key + " = " + std::to_string(id) +
                              ": expected -1 or the node id of a drive");
    }
  }
  return {};
}

std::int64_t SimDriveBus::node_index(std::uint8_t node_id) const noexcept {
  return node_id <= co::kMaxNodeId ? node_of_id_[node_id] : -1;
}

const SimDriveNode* SimDriveBus::find_node(std::uint8_t node_id) const noexcept {
  const std::int64_t index = node_index(node_id);
  return index < 0 ? nullptr : nodes_[static_cast<std::size_t>(index)].get();
}

void SimDriveBus::log_bus(EventKind kind, std::uint8_t node, std::uint32_t a, std::uint32_t b,
                          const char* cause, const char* text) noexcept {
  DriveEvent event;
  event.t_ns = now_ns_;
  event.sync = syncs_;
  event.node = node;
  event.kind = kind;
  event.a = a;
  event.b = b;
  event.cause = cause;
  if (text != nullptr) {
    std::size_t i = 0;
    for (; i + 1 < event.text.size() && text[i] != '\0'; ++i) event.text[i] = text[i];
    event.text[i] = '\0';
  }
  (void)events_.push(event);
}

// ------------------------------------------------------------------------------ poll

void SimDriveBus::power_on(std::int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  for (auto& node : nodes_) node->power_on(now_ns, syncs_);
  collect_tx();
  send_pending();
}

std::int64_t SimDriveBus::poll(std::int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  {
    const std::lock_guard lock(mailbox_mutex_);
    for (const FaultSpec& spec : mailbox_) (void)mailbox_taken_.push_back(spec);
    mailbox_.clear();
    stats_.faults_refused += mailbox_refused_;
    mailbox_refused_ = 0;
  }
  for (const FaultSpec& spec : mailbox_taken_) (void)inject(spec, now_ns);
  mailbox_taken_.clear();
  fire_due_faults(false);

  std::size_t handled = 0;
  bool more_waiting = false;
  while (handled < kMaxFramesPerPoll) {
    const std::size_t room = std::min(rx_.size(), kMaxFramesPerPoll - handled);
    const std::size_t count = transport_.receive(std::span(rx_.data(), room));
    for (std::size_t i = 0; i < count; ++i) handle_frame(rx_[i]);
    handled += count;
    if (count < room) break;
    more_waiting = handled >= kMaxFramesPerPoll;
  }
  if (more_waiting) ++stats_.polls_frame_budget_hit;

  for (auto& node : nodes_) node->on_time(now_ns, syncs_);
  collect_tx();
  send_pending();
  write_plant();

  std::int64_t next = more_waiting ? now_ns : kBusNoDeadline;
  for (const auto& node : nodes_) next = std::min(next, node->next_deadline_ns(now_ns));
  if (!delayed_.empty()) next = std::min(next, delayed_[0].release_ns);
  if (plant_started_) {
    for (const Scheduled& entry : schedule_) {
      if (!entry.fired && entry.spec.at_ns) next = std::min(next, start_ns_ + *entry.spec.at_ns);
    }
  }
  return next;
}

void SimDriveBus::handle_frame(const can_frame& frame) noexcept {
  ++stats_.frames_received;
  if (co::is_error_frame(frame)) {
    ++stats_.error_frames_received;
    return;
  }
  if (co::decode_sync(frame)) {
    handle_sync();
    return;
  }
  if (bus_off_.active) return;  // off the bus: the nodes hear nothing
  for (auto& node : nodes_) (void)node->on_frame(frame, now_ns_, syncs_);
  if (!plant_started_ && co::is_data_frame_with_id(frame, co::kCobNmt)) {
    for (const auto& node : nodes_) {
      if (node->nmt_state() == co::NmtState::operational) {
        start_plant();
        break;
      }
    }
  }
}

void SimDriveBus::start_plant() noexcept {
  // The only allocation poll() makes: SimDevice::activate() builds its message prefix.
  if (!plant_.activate()) return;
  plant_started_ = true;
  start_ns_ = now_ns_;
  syncs_since_start_ = 0;
  log_bus(EventKind::plant_started, 0, 0, 0, "first NMT start", nullptr);
}

void SimDriveBus::handle_sync() noexcept {
  ++syncs_;
  ++stats_.syncs;
  plant_clock_.advance_ns(params_.sync_period_ns);
  (void)plant_.read_encoders(std::span(samples_.data(), nodes_.size()));
  if (plant_started_) {
    ++syncs_since_start_;
    fire_due_faults(true);
  }
  std::uint32_t levels = 0;
  (void)plant_.read_digital_inputs(levels);
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    SimDriveNode& node = *nodes_[i];
    if (bus_off_.active) continue;
    NodeFaults& faults = faults_[i];
    if (faults.lost_sync.active) {
      ++node_stats_[i].syncs_ignored;
      count_down(faults.lost_sync, node.node_id(), "lost_sync ended");
      continue;
    }
    PlantSample sample;
    sample.position_counts = samples_[i].counts;
    sample.velocity_counts_per_s =
        plant_.true_velocity(i) / node.params().scale.position_per_count();
    sample.digital_inputs =
        node.node_id() == params_.digital_inputs_node ? (levels & 0xFFFFU) << 16 : 0U;
    node.on_sync(sample, now_ns_, syncs_);
  }
  write_plant();
  if (params_.digital_outputs_node > 0) {
    const SimDriveNode& outputs = *nodes_[static_cast<std::size_t>(
        node_of_id_[static_cast<std::size_t>(params_.digital_outputs_node)])];
    const std::uint32_t wanted = outputs.digital_outputs() >> 16;
    const std::uint32_t wired = (1U << hal::sim::kDigitalOutputCount) - 1U;
    (void)plant_.write_digital_outputs(wanted & wired);
  }
  collect_tx();
  send_pending();
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    NodeFaults& faults = faults_[i];
    const std::uint8_t id = nodes_[i]->node_id();
    count_down(faults.drop, id, "drop ended");
    count_down(faults.delay, id, "delay ended");
    count_down(faults.corrupt, id, "corrupt ended");
    count_down(faults.silent, id, "silent ended");
    count_down(faults.push, id, "push ended");
  }
  count_down(bus_off_, 0, "bus_off ended");
}

void SimDriveBus::count_down(Lasting& lasting, std::uint8_t node, const char* what) noexcept {
  if (!lasting.active || lasting.syncs_left == 0) return;  // inactive, or until cleared
  if (--lasting.syncs_left == 0) {
    lasting.active = false;
    log_bus(EventKind::fault_cleared, node, 0, 0, nullptr, what);
  }
}

void SimDriveBus::write_plant() noexcept {
  // The plant clock stands at the last SYNC between SYNCs, so a torque a drive removes between
  // two SYNCs (a fault reaction) is held as zero from the last SYNC on: the sim errs on the
  // side of less torque.
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    (void)nodes_[i]->take_output_changed();
    const DriveOutput& output = nodes_[i]->output();
    commands_[i] = {static_cast<float>(output.effort), output.enabled};
    if (faults_[i].push.active) {  // the hand acts whether or not the drive is on
      commands_[i] = {static_cast<float>((output.enabled ? output.effort : 0.0) +
                                         faults_[i].push_effort),
                      true};
    }
  }
  if (plant_.state() == hal::LifecycleState::active)
    (void)plant_.write_actuators(std::span(commands_.data(), nodes_.size()));
}

// ------------------------------------------------------------------------------ faults

core::Status SimDriveBus::inject(const FaultSpec& spec, std::int64_t now_ns) noexcept {
  now_ns_ = now_ns;
  const bool needs_node =
      spec.kind != FaultKind::bus_off && !(spec.kind == FaultKind::clear && spec.node_id == 0);
  if (needs_node && node_index(spec.node_id) < 0) {
    ++stats_.faults_refused;
    return {core::StatusCode::invalid_argument, "fault: no drive with that node id on this bus"};
  }
  if (spec.scheduled()) {
    if (!schedule_.push_back(Scheduled{spec, false})) {
      ++stats_.faults_refused;
      return {core::StatusCode::capacity_exceeded, "fault: schedule full"};
    }
    return core::Status::ok();
  }
  apply_fault(spec);
  return core::Status::ok();
}

bool SimDriveBus::post(const FaultSpec& spec) noexcept {
  const std::lock_guard lock(mailbox_mutex_);
  if (mailbox_.push_back(spec)) return true;
  ++mailbox_refused_;  // added to stats_ by the polling thread
  return false;
}

void SimDriveBus::fire_due_faults(bool at_sync_only) noexcept {
  if (!plant_started_) return;
  for (Scheduled& entry : schedule_) {
    if (entry.fired) continue;
    const FaultSpec& spec = entry.spec;
    const bool due = (spec.at_sync && syncs_since_start_ >= *spec.at_sync) ||
                     (!at_sync_only && spec.at_ns && now_ns_ - start_ns_ >= *spec.at_ns);
    if (!due) continue;
    entry.fired = true;
    apply_fault(spec);
  }
}

void SimDriveBus::apply_fault(const FaultSpec& spec) noexcept {
  std::array<char, kEventTextBytes> text{};
  (void)format_fault_spec(spec, text);
  log_bus(EventKind::fault_injected, spec.node_id, 0, 0, nullptr, text.data());
  if (spec.kind == FaultKind::bus_off) {
    can_frame error{};
    error.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
    error.len = CAN_ERR_DLC;
    emit(error);
    send_pending();
    bus_off_ = {true, spec.count};
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
      ++node_stats_[i].faults_injected;
      nodes_[i]->bus_off(now_ns_, syncs_);
    }
    write_plant();
    collect_tx();  // whatever the reaction queued is suppressed: the nodes are off the bus
    return;
  }
  if (spec.kind == FaultKind::clear) {
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
      if (spec.node_id == 0 || nodes_[i]->node_id() == spec.node_id) clear_faults(i, "cleared");
    }
    if (spec.node_id == 0 && bus_off_.active) {
      bus_off_ = {};
      log_bus(EventKind::fault_cleared, 0, 0, 0, nullptr, "bus_off cleared");
    }
    return;
  }
  const auto index = static_cast<std::size_t>(node_index(spec.node_id));
  SimDriveNode& node = *nodes_[index];
  NodeFaults& faults = faults_[index];
  ++node_stats_[index].faults_injected;
  if (lasting_kind(spec.kind)) {
    const Lasting lasting{true, spec.count};
    switch (spec.kind) {
      case FaultKind::drop: faults.drop = lasting; break;
      case FaultKind::delay:
        faults.delay = lasting;
        faults.delay_ns = spec.delay_ns;
        break;
      case FaultKind::corrupt:
        faults.corrupt = lasting;
        faults.corrupt_mode = spec.corrupt_mode;
        faults.corrupt_byte = spec.corrupt_byte;
        faults.corrupt_mask = spec.corrupt_mask;
        break;
      case FaultKind::silent: faults.silent = lasting; break;
      case FaultKind::push: {
        // The hand's spring pulls the joint toward its target; pushing `move` beyond it at rest
        // takes hand_stiffness * move.
        const std::size_t per_instrument = hal::sim::kJointsPerInstrument;
        const auto& instrument = params_.plant.instruments[index / per_instrument];
        faults.push = lasting;
        faults.push_effort = instrument.plant[index % per_instrument].hand_stiffness * spec.move;
        write_plant();
        break;
      }
      default: faults.lost_sync = lasting; break;
    }
    return;
  }
  switch (spec.kind) {
    case FaultKind::emcy: node.inject_emcy(spec.code, now_ns_, syncs_); break;
    case FaultKind::encoder_jump: node.add_encoder_offset(spec.counts); break;
    case FaultKind::reboot: node.reboot(now_ns_, syncs_); break;
    default: break;
  }
  collect_tx();
  send_pending();
  write_plant();
}

void SimDriveBus::clear_faults(std::size_t index, const char* why) noexcept {
  NodeFaults& faults = faults_[index];
  const bool any = faults.drop.active || faults.delay.active || faults.corrupt.active ||
                   faults.silent.active || faults.lost_sync.active || faults.push.active;
  faults = NodeFaults{};
  write_plant();
  if (any) log_bus(EventKind::fault_cleared, nodes_[index]->node_id(), 0, 0, nullptr, why);
}

// ------------------------------------------------------------------------------ transmit

void SimDriveBus::emit(const can_frame& frame) noexcept {
  if (out_.full()) send_pending();
  (void)out_.push_back(frame);
}

void SimDriveBus::send_pending() noexcept {
  if (out_.empty()) return;
  const std::size_t sent = transport_.send(out_.span());
  stats_.frames_sent += sent;
  stats_.frames_not_sent += out_.size() - sent;
  out_.clear();
}

void SimDriveBus::release_delayed() noexcept {
  std::size_t released = 0;
  while (released < delayed_.size() && delayed_[released].release_ns <= now_ns_) {
    const Delayed& entry = delayed_[released];
    if (!bus_off_.active && !faults_[entry.node].silent.active) {
      emit(entry.frame);
      ++node_stats_[entry.node].frames_sent;
    } else {
      ++node_stats_[entry.node].frames_suppressed;
    }
    ++released;
  }
  if (released == 0) return;
  // Shift the rest to the front (the queue is short: at most the frames of `ms` of SYNCs).
  std::size_t kept = 0;
  for (std::size_t i = released; i < delayed_.size(); ++i) delayed_[kept++] = delayed_[i];
  (void)delayed_.resize(kept);
}

void SimDriveBus::collect_tx() noexcept {
  release_delayed();
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    SimDriveNode& node = *nodes_[i];
    NodeFaults& faults = faults_[i];
    NodeBusStats& stats = node_stats_[i];
    for (const TxFrame& tx : node.tx_queue()) {
      if (bus_off_.active || faults.silent.active) {
        ++stats.frames_suppressed;
        if (tx.kind == TxKind::emcy) {
          log_bus(EventKind::emcy_sent, node.node_id(),
                  static_cast<std::uint32_t>(tx.frame.data[0] | (tx.frame.data[1] << 8)),
                  tx.frame.data[2], tx.cause,
                  bus_off_.active ? "suppressed: bus-off" : "suppressed: silent");
        }
        continue;
      }
      can_frame frame = tx.frame;
      if (tx.kind == TxKind::tpdo) {
        if (faults.drop.active) {
          ++stats.tpdos_dropped;
          continue;
        }
        if (faults.corrupt.active && tx.pdo_number == 1) {
          ++stats.tpdos_corrupted;
          if (faults.corrupt_mode == CorruptMode::length) {
            frame.len = frame.len > 0 ? static_cast<std::uint8_t>(frame.len - 1) : std::uint8_t{1};
          } else {
            frame.data[faults.corrupt_byte] =
                static_cast<std::uint8_t>(frame.data[faults.corrupt_byte] ^ faults.corrupt_mask);
          }
        }
        if (faults.delay.active) {
          if (delayed_.push_back(Delayed{now_ns_ + faults.delay_ns, i, frame})) {
            ++stats.tpdos_delayed;
          } else {
            ++stats_.delay_overflows;
          }
          continue;
        }
      }
      if (tx.kind == TxKind::emcy) {
        log_bus(EventKind::emcy_sent, node.node_id(),
                static_cast<std::uint32_t>(frame.data[0] | (frame.data[1] << 8)), frame.data[2],
                tx.cause, nullptr);
      }
      emit(frame);
      ++stats.frames_sent;
    }
    node.clear_tx_queue();
  }
}

// ------------------------------------------------------------------------------ summary

std::string SimDriveBus::summary() const {
  std::string text;
  char line[512];
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    const SimDriveNode& node = *nodes_[i];
    const NodeBusStats& stats = node_stats_[i];
    const SimDriveNode::Counters& counters = node.counters();
    std::snprintf(
        line, sizeof line,
        "  node %3u %-16s NMT %-15s power %-22s torque %5d permille; rx %llu (RPDO %llu, SDO "
        "%llu), "
        "tx %llu (TPDO %llu, dropped %llu, delayed %llu, corrupted %llu, suppressed %llu), "
        "EMCY %llu, SYNCs %llu (ignored %llu), faults %llu\n",
        static_cast<unsigned>(node.node_id()), plant_.channel_name(i).c_str(),
        co::to_string(node.nmt_state()), co::to_string(node.power_state()),
        static_cast<int>(node.torque_actual_permille()),
        static_cast<unsigned long long>(counters.frames_received),
        static_cast<unsigned long long>(counters.rpdos),
        static_cast<unsigned long long>(counters.sdo_requests),
        static_cast<unsigned long long>(stats.frames_sent),
        static_cast<unsigned long long>(counters.tpdos),
        static_cast<unsigned long long>(stats.tpdos_dropped),
        static_cast<unsigned long long>(stats.tpdos_delayed),
        static_cast<unsigned long long>(stats.tpdos_corrupted),
        static_cast<unsigned long long>(stats.frames_suppressed),
        static_cast<unsigned long long>(counters.emcys),
        static_cast<unsigned long long>(counters.syncs),
        static_cast<unsigned long long>(stats.syncs_ignored),
        static_cast<unsigned long long>(stats.faults_injected));
    text += line;
  }
  std::snprintf(line, sizeof line,
                "  bus: %llu SYNCs (%llu since the first NMT start), plant time %.3f s, frames rx "
                "%llu (error frames %llu) "
                "tx %llu (refused by the transport %llu), delay-queue overflows %llu, faults "
                "refused %llu, events %llu "
                "(dropped %llu)%s\n",
                static_cast<unsigned long long>(stats_.syncs),
                static_cast<unsigned long long>(syncs_since_start_),
                static_cast<double>(plant_.simulated_time_ns()) * 1e-9,
                static_cast<unsigned long long>(stats_.frames_received),
                static_cast<unsigned long long>(stats_.error_frames_received),
                static_cast<unsigned long long>(stats_.frames_sent),
                static_cast<unsigned long long>(stats_.frames_not_sent),
                static_cast<unsigned long long>(stats_.delay_overflows),
                static_cast<unsigned long long>(stats_.faults_refused),
                static_cast<unsigned long long>(events_.recorded()),
                static_cast<unsigned long long>(events_.dropped()),
                bus_off_.active ? ", BUS-OFF" : "");
  text += line;
  return text;
}

}  // namespace trainer::hal::simdrive
