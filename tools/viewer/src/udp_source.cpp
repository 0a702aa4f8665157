#include "udp_source.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include <nlohmann/json.hpp>

#include "view_frame.hpp"  // realtime_now_ns

namespace trainer::viewer {

namespace {

telemetry::ModelKind wire_kind_of(config::ModelKind kind) {
  switch (kind) {
    case config::ModelKind::modal_shell: return telemetry::ModelKind::modal;
    case config::ModelKind::tet_tensor: return telemetry::ModelKind::tensor;
    case config::ModelKind::catheter: return telemetry::ModelKind::catheter;
  }
  return telemetry::ModelKind::modal;
}

}  // namespace

core::Expected<void> scene_frame_from_telemetry(const SceneAssets& assets,
                                                const telemetry::Frame& in, SceneFrame& out) {
  const std::span<const ModelAssets> models = assets.models();
  std::vector<std::uint64_t> checksums;
  for (std::size_t i = 0; i < models.size(); ++i) {
    const telemetry::ModelState* state = telemetry::find_model(in, static_cast<std::uint8_t>(i));
    if (state == nullptr) {
      return core::make_error("stream refused: frame " + std::to_string(in.sequence) +
                              " has no state for model '" + models[i].name + "' (scene index " +
                              std::to_string(i) + ")");
    }
    checksums.push_back(state->image_checksum);
  }
  if (in.model_count != models.size()) checksums.resize(in.model_count, 0);
  if (auto same = assets.check_checksums(checksums); !same) return std::move(same).error();
  if (in.instrument_count != assets.instruments().size()) {
    return core::make_error("stream refused: " + std::to_string(in.instrument_count) +
                            " instrument(s) on the stream, scene '" + assets.scene_name() +
                            "' has " + std::to_string(assets.instruments().size()));
  }

  out.sequence = in.sequence;
  out.cycle = in.cycle;
  // The appliance stamps the cycle and the send on its monotonic clock and the send also on
  // its real-time clock: the cycle's real time is the send's minus the gap between them.
  out.times.sent_ns = in.send_wall_ns;
  out.times.cycle_ns = in.send_wall_ns - (in.send_time_ns - in.cycle_time_ns);
  out.latched_faults = in.latched_faults;
  out.has_metrics = in.has_metrics;
  if (in.has_metrics) out.metrics = in.metrics;
  out.models.resize(models.size());
  for (std::size_t i = 0; i < models.size(); ++i) {
    const telemetry::ModelState& state = *telemetry::find_model(in, static_cast<std::uint8_t>(i));
    if (state.kind != wire_kind_of(models[i].kind)) {
      return core::make_error("stream refused: model '" + models[i].name +
                              "' is of another kind on the stream");
    }
    ModelState& m = out.models[i];
    m.modal_coordinates.assign(state.modal_coordinates.begin(),
                               state.modal_coordinates.begin() + state.mode_count);
    m.loads.clear();
    for (std::uint32_t l = 0; l < state.load_count; ++l) {
      m.loads.push_back(NodeLoad{state.loads[l].node, state.loads[l].force_n});
    }
    m.contacts.clear();
    for (std::uint32_t c = 0; c < state.contact_count; ++c) {
      m.contacts.push_back(
          TensorContactState{state.contacts[c].node, state.contacts[c].displacement_m});
    }
    m.particles_m.assign(state.particles_m.begin(),
                         state.particles_m.begin() + state.particle_count);
  }
  out.instruments.resize(in.instrument_count);
  for (std::uint32_t i = 0; i < in.instrument_count; ++i) {
    const telemetry::InstrumentState& s = in.instruments[i];
    InstrumentState& o = out.instruments[i];
    o.shaft_start_m = s.shaft_start_m;
    o.hinge_m = s.hinge_m;
    o.force_n = s.force_n;
    o.flags = s.flags;
    // Jaw k: hinge + L (cos(g/2) d ± sin(g/2) n), d the unit hinge → tip (wire_format.hpp).
    float d[3];
    float length = 0.0F;
    for (std::size_t a = 0; a < 3; ++a) {
      d[a] = s.tip_m[a] - s.hinge_m[a];
      length += d[a] * d[a];
    }
    length = std::sqrt(length);
    const float c = std::cos(0.5F * s.grip_rad);
    const float sn = std::sin(0.5F * s.grip_rad);
    for (std::size_t a = 0; a < 3; ++a) {
      const float along = length > 0.0F ? d[a] / length : 0.0F;
      o.jaw_tips_m[0][a] = s.hinge_m[a] + length * (c * along + sn * s.opening_direction[a]);
      o.jaw_tips_m[1][a] = s.hinge_m[a] + length * (c * along - sn * s.opening_direction[a]);
    }
  }
  out.contacts.resize(in.contact_count);
  for (std::uint32_t c = 0; c < in.contact_count; ++c) {
    out.contacts[c] =
        ContactArrow{in.contacts[c].instrument, in.contacts[c].point_m, in.contacts[c].force_n};
  }
  return {};
}

core::Expected<std::unique_ptr<UdpSource>> UdpSource::open(const SceneAssets& assets,
                                                           const std::string& endpoint) {
  const std::size_t colon = endpoint.rfind(':');
  sockaddr_in address{};
  address.sin_family = AF_INET;
  unsigned long port = 0;
  bool valid = colon != std::string::npos && colon + 1 < endpoint.size();
  if (valid) {
    char* end = nullptr;
    port = std::strtoul(endpoint.c_str() + colon + 1, &end, 10);
    valid = *end == '\0' && port <= 65535 &&
            inet_pton(AF_INET, endpoint.substr(0, colon).c_str(), &address.sin_addr) == 1;
  }
  if (!valid) {
    return core::make_error("--udp " + endpoint +
                            ": expected IPV4-ADDRESS:PORT, e.g. 0.0.0.0:47800");
  }
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  std::unique_ptr<UdpSource> source(new UdpSource(assets));
  source->fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (source->fd_ < 0) return core::make_error(std::string("udp socket: ") + std::strerror(errno));
  // Room for a few hundred frames while the page is slow: the newest still wins (Sequencer).
  const int receive_buffer = 4 << 20;
  setsockopt(source->fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof receive_buffer);
  if (bind(source->fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    return core::make_error("udp " + endpoint + ": bind: " + std::strerror(errno));
  }
  sockaddr_in bound{};
  socklen_t length = sizeof bound;
  getsockname(source->fd_, reinterpret_cast<sockaddr*>(&bound), &length);
  source->port_ = ntohs(bound.sin_port);
  source->address_ = endpoint.substr(0, colon);
  source->buffer_.resize(telemetry::kMaxDatagramBytes + 1);
  source->decoded_ = std::make_unique<telemetry::Frame>();
  return source;
}

UdpSource::~UdpSource() {
  if (fd_ >= 0) close(fd_);
}

core::Expected<bool> UdpSource::next(SceneFrame& frame, std::chrono::milliseconds timeout) {
  pollfd waiting{fd_, POLLIN, 0};
  const int ready = poll(&waiting, 1, static_cast<int>(timeout.count()));
  if (ready <= 0) return false;
  const ssize_t got = recv(fd_, buffer_.data(), buffer_.size(), MSG_DONTWAIT);
  if (got < 0) return false;
  const std::int64_t received_ns = realtime_now_ns();
  const auto size = static_cast<std::size_t>(got);
  ++datagrams_;
  bytes_total_ += static_cast<double>(size);
  bytes_max_ = std::max(bytes_max_, size);
  bytes_last_ = size;
  const telemetry::DecodeResult result = telemetry::decode({buffer_.data(), size}, *decoded_);
  if (!result.ok()) {
    ++malformed_;
    return core::make_error("malformed datagram (" + std::to_string(size) +
                            " bytes): " + telemetry::to_string(result.error) + " at byte " +
                            std::to_string(result.offset) + " (" + result.detail + ")");
  }
  if (sequencer_.offer(decoded_->stream_id, decoded_->sequence) !=
      telemetry::Sequencer::Verdict::accept) {
    return false;
  }
  if (auto converted = scene_frame_from_telemetry(assets_, *decoded_, frame); !converted) {
    ++refused_;
    return std::move(converted).error();
  }
  frame.times.received_ns = received_ns;
  return true;
}

std::string UdpSource::describe() const {
  return "udp " + address_ + ":" + std::to_string(port_) + " (telemetry wire format " +
         std::to_string(telemetry::kVersionMajor) + "." + std::to_string(telemetry::kVersionMinor) +
         ")";
}

std::string UdpSource::stats_json() const {
  const telemetry::Sequencer::Counters& c = sequencer_.counters();
  nlohmann::json stats{
      {"source", "udp"},
      {"port", port_},
      {"datagrams", datagrams_},
      {"accepted", c.accepted},
      {"lost", sequencer_.lost()},
      {"duplicates", c.duplicates},
      {"late", c.late},
      {"stale", c.stale},
      {"malformed", malformed_},
      {"refused", refused_},
      {"stream_restarts", c.stream_restarts},
      {"datagram_bytes", bytes_last_},
      {"datagram_bytes_mean", datagrams_ ? bytes_total_ / static_cast<double>(datagrams_) : 0.0},
      {"datagram_bytes_max", bytes_max_}};
  return stats.dump();
}

}  // namespace trainer::viewer
