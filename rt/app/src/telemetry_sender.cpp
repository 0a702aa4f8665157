#include "trainer/app/telemetry_sender.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>

namespace trainer::app {
namespace {

std::int64_t sender_clock_ns(clockid_t clock) noexcept {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

core::Expected<std::unique_ptr<TelemetrySender>> TelemetrySender::create(
    const config::TelemetryConfig& config, const std::string& origin) {
  if (auto rate = check_rate(config, origin); !rate) return std::move(rate).error();
  const std::string where = origin + ": ";
  // Keys as the device file's messages name them, or bare after a command-line option.
  const std::string key = origin.rfind("--", 0) == 0 ? "" : "telemetry.";
  sockaddr_storage destination{};
  socklen_t length = 0;
  std::string shown;
  auto* v4 = reinterpret_cast<sockaddr_in*>(&destination);
  auto* v6 = reinterpret_cast<sockaddr_in6*>(&destination);
  if (inet_pton(AF_INET, config.address.c_str(), &v4->sin_addr) == 1) {
    v4->sin_family = AF_INET;
    v4->sin_port = htons(config.port);
    length = sizeof(sockaddr_in);
    shown = config.address + ":" + std::to_string(config.port);
  } else if (inet_pton(AF_INET6, config.address.c_str(), &v6->sin6_addr) == 1) {
    v6->sin6_family = AF_INET6;
    v6->sin6_port = htons(config.port);
    length = sizeof(sockaddr_in6);
    shown = "[" + config.address + "]:" + std::to_string(config.port);
  } else {
    return core::make_error(where + key + "address = \"" + config.address +
                            "\": expected a numeric IPv4 or IPv6 address");
  }
  std::unique_ptr<TelemetrySender> sender(new TelemetrySender());
  sender->fd_ = socket(destination.ss_family, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (sender->fd_ < 0)
    return core::make_error(where + "cannot open a UDP socket: " + std::strerror(errno));
  // Nothing is ever read from this socket: keep what the kernel may queue for it small.
  const int smallest = 1;  // the kernel rounds it up to its minimum
  (void)setsockopt(sender->fd_, SOL_SOCKET, SO_RCVBUF, &smallest, sizeof smallest);
  if (config.source_port != 0) {
    sockaddr_storage local{};
    local.ss_family = destination.ss_family;
    if (destination.ss_family == AF_INET) {
      reinterpret_cast<sockaddr_in*>(&local)->sin_port = htons(config.source_port);
    } else {
      reinterpret_cast<sockaddr_in6*>(&local)->sin6_port = htons(config.source_port);
    }
    if (bind(sender->fd_, reinterpret_cast<const sockaddr*>(&local), length) != 0) {
      return core::make_error(where + key + "source_port = " + std::to_string(config.source_port) +
                              ": " + std::strerror(errno));
    }
  }
  if (connect(sender->fd_, reinterpret_cast<const sockaddr*>(&destination), length) != 0) {
    return core::make_error(where + "destination " + shown + ": " + std::strerror(errno));
  }
  sockaddr_storage bound{};
  socklen_t bound_length = sizeof bound;
  if (getsockname(sender->fd_, reinterpret_cast<sockaddr*>(&bound), &bound_length) == 0) {
    sender->stats_.source_port =
        ntohs(bound.ss_family == AF_INET ? reinterpret_cast<sockaddr_in*>(&bound)->sin_port
                                         : reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port);
  }
  sender->allocate(config.rate_hz);
  sender->stats_.destination = shown;
  return sender;
}

core::Expected<void> TelemetrySender::check_rate(const config::TelemetryConfig& config,
                                                 const std::string& origin) {
  const std::string key = origin.rfind("--", 0) == 0 ? "" : "telemetry.";
  if (config.rate_hz < 30 || config.rate_hz > 120)
    return core::make_error(origin + ": " + key + "rate_hz = " + std::to_string(config.rate_hz) +
                            ": expected 30 to 120");
  return {};
}

void TelemetrySender::allocate(std::uint32_t rate_hz) {
  period_ns_ = 1'000'000'000 / static_cast<std::int64_t>(rate_hz);
  frame_ = std::make_unique<telemetry::Frame>();
  datagram_.resize(telemetry::kMaxDatagramBytes);
  size_counts_.assign(kSizeBins, 0);
  stats_.rate_hz = rate_hz;
  const std::int64_t wall = sender_clock_ns(CLOCK_REALTIME);
  stats_.stream_id = static_cast<std::uint32_t>(
      static_cast<std::uint64_t>(wall) ^ (static_cast<std::uint64_t>(wall) >> 32) ^
      (static_cast<std::uint64_t>(getpid()) << 16));
}

core::Expected<std::unique_ptr<TelemetrySender>> TelemetrySender::create_unsent(
    const config::TelemetryConfig& config, const std::string& origin) {
  if (auto rate = check_rate(config, origin); !rate) return std::move(rate).error();
  std::unique_ptr<TelemetrySender> sender(new TelemetrySender());
  sender->allocate(config.rate_hz);
  return sender;
}

TelemetrySender::~TelemetrySender() {
  if (fd_ >= 0) close(fd_);
}

std::int64_t TelemetrySender::ns_until_due(std::int64_t now_ns) const noexcept {
  return has_sent_ ? next_due_ns_ - now_ns : 0;
}

void TelemetrySender::fill_frame(const TelemetrySnapshot& snapshot,
                                 telemetry::Frame& frame) noexcept {
  frame.cycle = snapshot.cycle;
  frame.cycle_time_ns = snapshot.time_ns;
  frame.latched_faults = snapshot.latched_faults;
  frame.flags = snapshot.contacts_truncated ? telemetry::kFlagContactsTruncated : 0U;
  frame.model_count = std::min<std::uint32_t>(snapshot.model_count, telemetry::kMaxModels);
  for (std::size_t m = 0; m < frame.model_count; ++m) {
    const telemetry::ModelState& from = snapshot.models[m];
    telemetry::ModelState& to = frame.models[m];
    // Only the used part of each array (the rest of the snapshot's is stale).
    to.kind = from.kind;
    to.scene_index = from.scene_index;
    to.flags = from.flags;
    to.image_checksum = from.image_checksum;
    to.mode_count = from.kind == telemetry::ModelKind::modal ? from.mode_count : 0;
    to.load_count = from.kind == telemetry::ModelKind::modal ? from.load_count : 0;
    to.contact_count = from.kind == telemetry::ModelKind::tensor ? from.contact_count : 0;
    to.particle_count = from.kind == telemetry::ModelKind::catheter ? from.particle_count : 0;
    std::copy_n(from.modal_coordinates.begin(), to.mode_count, to.modal_coordinates.begin());
    std::copy_n(from.loads.begin(), to.load_count, to.loads.begin());
    std::copy_n(from.contacts.begin(), to.contact_count, to.contacts.begin());
    std::copy_n(from.particles_m.begin(), to.particle_count, to.particles_m.begin());
  }
  frame.instrument_count =
      std::min<std::uint32_t>(snapshot.instrument_count, telemetry::kMaxInstruments);
  for (std::size_t i = 0; i < frame.instrument_count; ++i) {
    const InstrumentTelemetry& from = snapshot.instruments[i];
    telemetry::InstrumentState& to = frame.instruments[i];
    to.flags = from.stream_flags;
    to.grip_rad = from.joints[4];
    to.tip_m = from.tip_m;
    to.hinge_m = from.hinge_m;
    to.shaft_start_m = from.shaft_start_m;
    to.opening_direction = from.opening_direction;
    to.force_n = from.force_n;
  }
  frame.contact_count = std::min<std::uint32_t>(snapshot.contact_count, telemetry::kMaxContacts);
  std::copy_n(snapshot.contacts.begin(), frame.contact_count, frame.contacts.begin());
}

namespace {

float sender_squared_norm(const std::array<float, 3>& v) noexcept {
  return v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
}

}  // namespace

bool TelemetrySender::trim_to_budget(telemetry::Frame& frame, std::size_t budget_bytes) noexcept {
  if (telemetry::encoded_size(frame) <= budget_bytes) return false;
  // Largest first, so that trimming drops from the end.
  std::sort(frame.contacts.begin(), frame.contacts.begin() + frame.contact_count,
            [](const telemetry::ContactPoint& a, const telemetry::ContactPoint& b) {
              return sender_squared_norm(a.force_n) > sender_squared_norm(b.force_n);
            });
  for (std::size_t m = 0; m < frame.model_count; ++m) {
    telemetry::ModelState& model = frame.models[m];
    std::sort(model.loads.begin(), model.loads.begin() + model.load_count,
              [](const telemetry::NodeLoad& a, const telemetry::NodeLoad& b) {
                return sender_squared_norm(a.force_n) > sender_squared_norm(b.force_n);
              });
  }
  constexpr std::uint32_t kContactsKept = 4;
  const auto drop_smallest_load = [&frame]() noexcept {
    // The smallest last load over the models (each model's loads are sorted).
    std::size_t pick = frame.model_count;
    float smallest = 0.0F;
    for (std::size_t m = 0; m < frame.model_count; ++m) {
      const telemetry::ModelState& model = frame.models[m];
      if (model.load_count == 0) continue;
      const float n = sender_squared_norm(model.loads[model.load_count - 1].force_n);
      if (pick == frame.model_count || n < smallest) {
        pick = m;
        smallest = n;
      }
    }
    if (pick == frame.model_count) return false;
    --frame.models[pick].load_count;
    frame.models[pick].flags |= telemetry::kModalLoadsTruncated;
    return true;
  };
  while (telemetry::encoded_size(frame) > budget_bytes) {
    if (frame.contact_count > kContactsKept) {
      --frame.contact_count;
      frame.flags |= telemetry::kFlagContactsTruncated;
    } else if (!drop_smallest_load()) {
      if (frame.contact_count == 0) break;
      --frame.contact_count;
      frame.flags |= telemetry::kFlagContactsTruncated;
    }
  }
  return true;
}

void TelemetrySender::send_snapshot(const TelemetrySnapshot& snapshot, std::int64_t now_ns,
                                    std::uint32_t extra_flags) noexcept {
  telemetry::Frame& frame = *frame_;
  fill_frame(snapshot, frame);
  frame.flags |= extra_flags;
  frame.stream_id = stats_.stream_id;
  frame.sequence = sequence_;
  frame.send_time_ns = now_ns;
  frame.send_wall_ns = sender_clock_ns(CLOCK_REALTIME);
  frame.has_metrics = metrics_ != nullptr;
  if (metrics_ != nullptr) {
    frame.metrics = *metrics_;
    frame.metrics.instrument_count = static_cast<std::uint8_t>(
        std::min<std::uint32_t>(frame.metrics.instrument_count, frame.instrument_count));
  }
  if (trim_to_budget(frame, kFrameBudgetBytes)) ++stats_.trimmed;
  if (telemetry::encoded_size(frame) > kFrameBudgetBytes) ++stats_.over_budget;
  const telemetry::EncodeResult encoded = telemetry::encode(frame, datagram_);
  if (!encoded.ok()) {
    ++stats_.encode_errors;
    return;
  }
  ++sequence_;
  last_cycle_sent_ = snapshot.cycle;
  if (sink_) sink_(std::span<const std::byte>(datagram_.data(), encoded.bytes), frame);
  if (fd_ < 0) return;
  const ssize_t sent = send(fd_, datagram_.data(), encoded.bytes, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (sent < 0) {
    const int error = errno;
    ++stats_.send_errors;
    stats_.last_errno = error;
    if (error == ECONNREFUSED) {
      ++stats_.refused;
    } else if (error == EAGAIN || error == EWOULDBLOCK || error == ENOBUFS) {
      ++stats_.buffer_full;
    } else {
      ++stats_.other_errors;
    }
    return;
  }
  ++stats_.frames_sent;
  const auto bytes = static_cast<std::uint32_t>(encoded.bytes);
  if (stats_.frames_sent == 1 || bytes < stats_.bytes_min) stats_.bytes_min = bytes;
  if (bytes > stats_.bytes_max) stats_.bytes_max = bytes;
  ++size_counts_[std::min<std::size_t>(bytes, kSizeBins - 1)];
}

void TelemetrySender::send_if_due(const TelemetrySnapshot& snapshot,
                                  std::int64_t now_ns) noexcept {
  if (has_sent_ && now_ns < next_due_ns_) return;
  // Absolute schedule; after a stall of more than a period, restart from now.
  next_due_ns_ = has_sent_ && now_ns - next_due_ns_ < period_ns_ ? next_due_ns_ + period_ns_
                                                                 : now_ns + period_ns_;
  if (has_sent_ && snapshot.cycle == last_cycle_sent_) {
    ++stats_.stale_skipped;
    return;
  }
  has_sent_ = true;
  send_snapshot(snapshot, now_ns, 0);
}

void TelemetrySender::send_final(const TelemetrySnapshot& snapshot,
                                 std::int64_t now_ns) noexcept {
  send_snapshot(snapshot, now_ns, telemetry::kFlagRunEnded);
}

TelemetrySenderStats TelemetrySender::stats() const {
  TelemetrySenderStats stats = stats_;
  std::uint64_t seen = 0;
  const std::uint64_t half = (stats.frames_sent + 1) / 2;
  for (std::size_t b = 0; b < size_counts_.size() && stats.frames_sent > 0; ++b) {
    seen += size_counts_[b];
    if (seen >= half) {
      stats.bytes_p50 = static_cast<std::uint32_t>(b);
      break;
    }
  }
  return stats;
}

}  // namespace trainer::app
