// Heartbeat codec and consumer (CiA 301 v4.2, 7.2.8.3.2, objects 0x1016/0x1017).
#include "trainer/hal_canopen/heartbeat.hpp"

#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

namespace {

constexpr std::int64_t kNanosecondsPerMillisecond = 1'000'000;

constexpr std::uint8_t event_bit(HeartbeatEvent event) noexcept {
  return static_cast<std::uint8_t>(1U << static_cast<unsigned>(event));
}

}  // namespace

can_frame encode_heartbeat(std::uint8_t node_id, NmtState state) noexcept {
  const std::uint8_t data[1] = {static_cast<std::uint8_t>(state)};
  return make_frame(static_cast<std::uint16_t>(kCobHeartbeatBase + (node_id & 0x7FU)), data);
}

std::optional<HeartbeatMessage> decode_heartbeat(const can_frame& frame) noexcept {
  if ((frame.can_id & ~CAN_SFF_MASK) != 0 || frame.len != 1) {  // flags or id bits above 10
    return std::nullopt;
  }
  const std::uint16_t id = frame_id(frame);
  if (id <= kCobHeartbeatBase || id > kCobHeartbeatBase + kMaxNodeId) return std::nullopt;
  const auto state = nmt_state_from_byte(frame.data[0]);
  if (!state) return std::nullopt;
  return HeartbeatMessage{static_cast<std::uint8_t>(id - kCobHeartbeatBase), *state};
}

core::Status HeartbeatConsumer::add(std::uint8_t node_id, std::uint16_t consumer_time_ms) noexcept {
  if (!is_valid_node_id(node_id)) {
    return {core::StatusCode::invalid_argument, "heartbeat consumer: node id outside 1..127"};
  }
  if (find(node_id) != nullptr) {
    return {core::StatusCode::invalid_argument, "heartbeat consumer: node already monitored"};
  }
  if (consumer_time_ms == 0) return core::Status::ok();  // CiA 301: entry not used
  if (count_ == kCapacity) {
    return {core::StatusCode::capacity_exceeded, "heartbeat consumer: too many nodes"};
  }
  Node& node = nodes_[count_++];
  node = Node{};
  node.status.node_id = node_id;
  node.status.consumer_time_ms = consumer_time_ms;
  return core::Status::ok();
}

core::Status HeartbeatConsumer::add_entry(std::uint32_t entry_0x1016) noexcept {
  if ((entry_0x1016 >> 24) != 0) {
    return {core::StatusCode::invalid_argument, "heartbeat consumer: reserved bits 31..24 set"};
  }
  const ConsumerEntry entry = decode_consumer_entry(entry_0x1016);
  if (entry.node_id == 0 || entry.time_ms == 0) return core::Status::ok();  // unused entry
  return add(entry.node_id, entry.time_ms);
}

HeartbeatConsumer::Node* HeartbeatConsumer::find(std::uint8_t node_id) noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    if (nodes_[i].status.node_id == node_id) return &nodes_[i];
  }
  return nullptr;
}

const NodeHeartbeatStatus* HeartbeatConsumer::status(std::uint8_t node_id) const noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    if (nodes_[i].status.node_id == node_id) return &nodes_[i].status;
  }
  return nullptr;
}

bool HeartbeatConsumer::on_frame(const can_frame& frame, std::int64_t now_ns) noexcept {
  const auto message = decode_heartbeat(frame);
  if (!message) return false;
  Node* node = find(message->node_id);
  if (node == nullptr) return false;
  NodeHeartbeatStatus& status = node->status;
  if (status.health == NodeHealth::timed_out) node->pending |= event_bit(HeartbeatEvent::recovered);
  if (message->state == NmtState::boot_up) {
    status.health = NodeHealth::booted;
    ++status.boot_up_count;
    node->pending |= event_bit(HeartbeatEvent::boot_up);
  } else {
    if (status.state && *status.state != message->state && *status.state != NmtState::boot_up) {
      node->pending |= event_bit(HeartbeatEvent::state_changed);
    }
    status.health = NodeHealth::alive;
  }
  status.state = message->state;
  status.last_heard_ns = now_ns;
  return true;
}

void HeartbeatConsumer::on_time(std::int64_t now_ns) noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    Node& node = nodes_[i];
    NodeHeartbeatStatus& status = node.status;
    if (status.health != NodeHealth::alive) continue;
    const std::int64_t limit_ns =
        static_cast<std::int64_t>(status.consumer_time_ms) * kNanosecondsPerMillisecond;
    if (now_ns - status.last_heard_ns > limit_ns) {
      status.health = NodeHealth::timed_out;
      ++status.timeout_count;
      node.pending |= event_bit(HeartbeatEvent::timed_out);
    }
  }
}

std::optional<HeartbeatEventRecord> HeartbeatConsumer::next_event() noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    Node& node = nodes_[i];
    if (node.pending == 0) continue;
    for (unsigned bit = 0; bit < 8; ++bit) {
      const auto mask = static_cast<std::uint8_t>(1U << bit);
      if ((node.pending & mask) == 0) continue;
      node.pending = static_cast<std::uint8_t>(node.pending & ~mask);
      return HeartbeatEventRecord{node.status.node_id, static_cast<HeartbeatEvent>(bit),
                                  node.status.state};
    }
  }
  return std::nullopt;
}

bool HeartbeatConsumer::all_alive() const noexcept {
  for (std::size_t i = 0; i < count_; ++i) {
    if (nodes_[i].status.health != NodeHealth::alive) return false;
  }
  return true;
}

const char* to_string(NodeHealth health) noexcept {
  switch (health) {
    case NodeHealth::not_seen: return "not seen";
    case NodeHealth::booted: return "booted";
    case NodeHealth::alive: return "alive";
    case NodeHealth::timed_out: return "timed out";
  }
  return "?";
}

const char* to_string(HeartbeatEvent event) noexcept {
  switch (event) {
    case HeartbeatEvent::timed_out: return "timed out";
    case HeartbeatEvent::recovered: return "recovered";
    case HeartbeatEvent::boot_up: return "boot-up";
    case HeartbeatEvent::state_changed: return "state changed";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
