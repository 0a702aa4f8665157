// CanTransport: classic CAN frames (`struct can_frame`, <linux/can.h>) over one file
// descriptor, without blocking.
//
// Two ways to get one:
//  - open_socketcan("can0", filters, options): a raw SocketCAN socket (PF_CAN, SOCK_RAW,
//    CAN_RAW) bound to a named interface, with receive filters for the identifiers in use,
//    error frames enabled (CAN_RAW_ERR_FILTER: bus-off, controller problems, lost
//    arbitration, protocol violations, missing ACK, restarts, TX timeouts) and the kernel's
//    receive-queue drop counter (SO_RXQ_OVFL).
//  - from_fd(fd): any descriptor that carries one `struct can_frame` per message, e.g. one end
//    of socketpair(AF_UNIX, SOCK_SEQPACKET) in tests; frames pass unfiltered.
//
// RT use: receive() and send() never block (MSG_DONTWAIT), never allocate and move at most
// the caller's span per call (one recvmmsg / sendmmsg system call, so a cycle's frames cost
// one call each way). Every frame that could not be moved is counted: kernel queue full on
// send (ENOBUFS/EAGAIN), frames the kernel dropped on receive (SO_RXQ_OVFL), truncated or
// malformed messages. Counters are plain integers owned by the calling thread.
//
// The transport owns its descriptor (closed on destruction); it is movable, not copyable.
#pragma once

#include <linux/can.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "trainer/core/expected.hpp"

namespace trainer::hal::socketcan {

// Most frames one receive() or send() call moves; bigger spans are cut to this.
inline constexpr std::size_t kMaxFramesPerCall = 64;

struct CanCounters {
  std::uint64_t rx_frames = 0;          // data/remote frames delivered to the caller
  std::uint64_t rx_error_frames = 0;    // error frames (CAN_ERR_FLAG) delivered to the caller
  std::uint64_t rx_kernel_drops = 0;    // frames the kernel dropped (receive queue full)
  std::uint64_t rx_malformed = 0;       // messages not the size of a can_frame
  std::uint64_t rx_calls = 0;           // receive() calls that reached the kernel
  std::uint64_t tx_frames = 0;          // frames the kernel accepted
  std::uint64_t tx_dropped = 0;         // frames refused: queue full or an error
  std::uint64_t tx_calls = 0;
  std::uint64_t io_errors = 0;          // system calls failing with something else than EAGAIN
  int last_errno = 0;                   // errno of the last such failure (0 = none)
};

struct CanFilter {
  canid_t id = 0;
  canid_t mask = 0;
};

struct SocketCanOptions {
  bool error_frames = true;        // CAN_RAW_ERR_FILTER = the classes listed above
  bool receive_own_frames = false;  // CAN_RAW_RECV_OWN_MSGS
  int receive_buffer_bytes = 0;    // SO_RCVBUF when > 0
};

class CanTransport {
 public:
  // Raw SocketCAN socket on `interface`. Errors name the interface and what to do, e.g. a
  // kernel without CAN ("modprobe can-raw"), an unknown interface ("ip link add ..."), an
  // interface that is down ("ip link set can0 up type can bitrate 1000000"). At most
  // CAN_RAW_FILTER_MAX filters; none = receive everything.
  static core::Expected<CanTransport> open_socketcan(std::string_view interface,
                                                     std::span<const CanFilter> filters,
                                                     const SocketCanOptions& options = {});
  // Takes ownership of `fd` (closed even on error) and makes it non-blocking.
  static core::Expected<CanTransport> from_fd(int fd, std::string name);

  CanTransport(CanTransport&& other) noexcept;
  CanTransport& operator=(CanTransport&& other) noexcept;
  CanTransport(const CanTransport&) = delete;
  CanTransport& operator=(const CanTransport&) = delete;
  ~CanTransport();

  // Moves up to min(out.size(), kMaxFramesPerCall) waiting frames into `out`; returns how
  // many (0 when none is waiting). Never blocks.
  std::size_t receive(std::span<can_frame> out) noexcept;
  // Queues up to min(frames.size(), kMaxFramesPerCall) frames in order; returns how many the
  // kernel took. The rest are counted as tx_dropped (a CAN master must not wait here).
  std::size_t send(std::span<const can_frame> frames) noexcept;
  bool send_one(const can_frame& frame) noexcept { return send({&frame, 1}) == 1; }

  // Setup path only: waits up to `timeout_ns` for a frame to be readable (poll). Returns
  // false on timeout.
  bool wait_readable(std::int64_t timeout_ns) const noexcept;

  const CanCounters& counters() const noexcept { return counters_; }
  const std::string& name() const noexcept { return name_; }
  int fd() const noexcept { return fd_; }
  bool is_socketcan() const noexcept { return socketcan_; }

 private:
  CanTransport(int fd, std::string name, bool socketcan) noexcept;

  int fd_ = -1;
  std::string name_;
  bool socketcan_ = false;
  std::uint32_t last_kernel_drop_count_ = 0;  // SO_RXQ_OVFL is a running total
  CanCounters counters_{};
};

// A connected pair of transports over socketpair(AF_UNIX, SOCK_SEQPACKET): what one sends
// the other receives, frame by frame. For tests and for the simulated drive's loopback mode.
struct CanTransportPair {
  CanTransport a;
  CanTransport b;
};
core::Expected<CanTransportPair> make_transport_pair(std::string name_a, std::string name_b);

}  // namespace trainer::hal::socketcan
