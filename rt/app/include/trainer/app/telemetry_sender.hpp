// The telemetry stream's sender (docs/telemetry.md): on the supervisor thread — the one
// non-RT reader of the telemetry triple buffer — at the device file's [telemetry] rate_hz
// (30–120), the newest snapshot becomes one wire-format frame (rt/telemetry) and one UDP
// datagram to the graphics host.
//
// The socket is non-blocking and connected to the destination, so the kernel drops
// datagrams from any other source and ICMP "port unreachable" comes back as ECONNREFUSED on a
// later send: every send error is counted, none is fatal, and nothing here can block the
// supervisor (a full socket buffer drops the frame). The sender never reads from its socket
// (its receive buffer is set to the minimum): traffic toward the appliance reaches no code.
//
// The same object encodes the frames a session recording keeps (channel 2, docs/recording.md):
// with a frame sink set, every frame encoded is handed to it (then sent, if there is a
// destination); create_unsent() makes one with no socket, for a recording without a stream.
//
// Memory: the frame (25 KiB) and the datagram buffer are allocated at create(); sending a
// frame allocates nothing (TelemetrySender.SendingAllocatesNothing).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "trainer/app/telemetry.hpp"
#include "trainer/config/device.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::app {

struct TelemetrySenderStats {
  std::string destination;  // "address:port" as configured ("[v6]:port" for IPv6)
  std::uint32_t rate_hz = 0;
  std::uint16_t source_port = 0;  // the local port the frames leave from
  std::uint32_t stream_id = 0;
  std::uint64_t frames_sent = 0;
  std::uint64_t send_errors = 0;      // every failed send(), by kind below
  std::uint64_t refused = 0;          // ECONNREFUSED: nobody listening (ICMP port unreachable)
  std::uint64_t buffer_full = 0;      // EAGAIN/ENOBUFS: the socket's buffer was full, dropped
  std::uint64_t other_errors = 0;     // any other errno (network down, unreachable...)
  int last_errno = 0;
  std::uint64_t encode_errors = 0;    // a snapshot that did not encode (never expected)
  std::uint64_t stale_skipped = 0;    // due, but no snapshot newer than the last one sent
  std::uint64_t trimmed = 0;          // frames cut to the byte budget (loads, contacts dropped)
  std::uint64_t over_budget = 0;      // frames still above the budget after trimming (sent)
  std::uint32_t bytes_min = 0;
  std::uint32_t bytes_p50 = 0;
  std::uint32_t bytes_max = 0;
};

class TelemetrySender {
 public:
  // A frame above this many bytes is trimmed before it is sent: the smallest contact points
  // beyond the 4 largest go first, then the smallest static-correction loads, then the other
  // contact points (frame flag / modal flag "truncated" set). 1 KiB: the target for
  // the cbd scene, and below an Ethernet payload (1,472 bytes), so no frame is fragmented.
  // Model coordinates, particles and instruments are never dropped: a scene whose frame
  // is still larger is sent whole and counted in over_budget.
  static constexpr std::size_t kFrameBudgetBytes = 1024;

  // Setup path: opens the socket (non-blocking, connected to config.address:port). Errors
  // start with `origin` (where the settings came from: the device file's path, or
  // "--telemetry"), then the key ("telemetry.address" in a device file) and the reason.
  static core::Expected<std::unique_ptr<TelemetrySender>> create(
      const config::TelemetryConfig& config, const std::string& origin);
  // Setup path: a sender with no destination (frames are encoded for the sink only, never
  // sent); rate_hz as in create(), same errors.
  static core::Expected<std::unique_ptr<TelemetrySender>> create_unsent(
      const config::TelemetryConfig& config, const std::string& origin);
  ~TelemetrySender();
  // Called with every frame encoded (its bytes, valid during the call, and the frame), before
  // it is sent. Setup path only.
  using FrameSink = std::function<void(std::span<const std::byte>, const telemetry::Frame&)>;
  void set_frame_sink(FrameSink sink) { sink_ = std::move(sink); }
  bool sends() const noexcept { return fd_ >= 0; }
  // The session's trainee metrics to carry in every frame from now on (wire format 1.1,
  // section 18; at most as many instruments as the frame has); nullptr: none. The caller owns
  // it and updates it on this (the supervisor) thread between sends.
  void set_metrics(const telemetry::SessionMetrics* metrics) noexcept { metrics_ = metrics; }
  TelemetrySender(const TelemetrySender&) = delete;
  TelemetrySender& operator=(const TelemetrySender&) = delete;

  // Nanoseconds (CLOCK_MONOTONIC) until the next frame is due; ≤ 0 when due now.
  std::int64_t ns_until_due(std::int64_t now_ns) const noexcept;
  // When due: encodes `snapshot` (if newer than the last one sent) and sends it. The schedule
  // is absolute (no drift); after a stall it restarts from now instead of sending a burst.
  void send_if_due(const TelemetrySnapshot& snapshot, std::int64_t now_ns) noexcept;
  // The last frame of a run (frame flag "run ended"), sent whatever the schedule.
  void send_final(const TelemetrySnapshot& snapshot, std::int64_t now_ns) noexcept;

  TelemetrySenderStats stats() const;
  // The snapshot → frame mapping (the frame's header fields from `sequence` and the clocks).
  static void fill_frame(const TelemetrySnapshot& snapshot, telemetry::Frame& frame) noexcept;
  // Cuts `frame` to `budget_bytes` as described at kFrameBudgetBytes; true if it cut anything.
  static bool trim_to_budget(telemetry::Frame& frame, std::size_t budget_bytes) noexcept;

 private:
  TelemetrySender() = default;
  void send_snapshot(const TelemetrySnapshot& snapshot, std::int64_t now_ns,
                     std::uint32_t extra_flags) noexcept;

  static core::Expected<void> check_rate(const config::TelemetryConfig& config,
                                         const std::string& origin);
  void allocate(std::uint32_t rate_hz);
  int fd_ = -1;
  FrameSink sink_;
  const telemetry::SessionMetrics* metrics_ = nullptr;
  std::int64_t period_ns_ = 0;
  std::int64_t next_due_ns_ = 0;
  bool has_sent_ = false;
  std::uint64_t last_cycle_sent_ = 0;
  std::uint64_t sequence_ = 0;
  std::unique_ptr<telemetry::Frame> frame_;
  std::vector<std::byte> datagram_;
  // Frames per size in bytes (exact up to kSizeBins − 1; larger ones in the last bin).
  static constexpr std::size_t kSizeBins = 4097;
  std::vector<std::uint64_t> size_counts_;
  TelemetrySenderStats stats_;
};

}  // namespace trainer::app
