#include "trainer/hal_socketcan/can_transport.hpp"

#include <fcntl.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <utility>

namespace trainer::hal::socketcan {

namespace {

// The error classes a CAN master must see: the bus going away, the controller struggling,
// and frames that never made it.
constexpr can_err_mask_t kErrorClasses = CAN_ERR_TX_TIMEOUT | CAN_ERR_LOSTARB | CAN_ERR_CRTL |
                                         CAN_ERR_PROT | CAN_ERR_TRX | CAN_ERR_ACK |
                                         CAN_ERR_BUSOFF | CAN_ERR_BUSERROR | CAN_ERR_RESTARTED;

std::string errno_text(int error) { return std::string(std::strerror(error)); }

core::Error socket_error(std::string_view interface, std::string_view step, int error) {
  std::string message = "CAN interface '" + std::string(interface) + "': " + std::string(step) +
                        " failed: " + errno_text(error);
  if (error == EAFNOSUPPORT || error == EPROTONOSUPPORT) {
    message += " (this kernel has no SocketCAN raw sockets: load them with 'modprobe can-raw')";
  }
  return core::make_error(std::move(message));
}

// Closes a descriptor on scope exit unless released.
class FdGuard {
 public:
  explicit FdGuard(int fd) noexcept : fd_(fd) {}
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }
  int release() noexcept { return std::exchange(fd_, -1); }
  int get() const noexcept { return fd_; }

 private:
  int fd_;
};

// Whether the interface is administratively up and running; errno-style error otherwise.
core::Expected<void> check_interface_up(int fd, std::string_view interface) {
  ifreq request{};
  std::memcpy(request.ifr_name, interface.data(), interface.size());
  if (::ioctl(fd, SIOCGIFFLAGS, &request) != 0) {
    return socket_error(interface, "SIOCGIFFLAGS", errno);
  }
  const auto flags = static_cast<unsigned>(request.ifr_flags);
  if ((flags & IFF_UP) == 0U) {
    return core::make_error("CAN interface '" + std::string(interface) +
                            "' is down: bring it up first, e.g. 'ip link set " +
                            std::string(interface) + " up type can bitrate 1000000' (or for a " +
                            "virtual bus 'ip link set " + std::string(interface) + " up')");
  }
  return {};
}

}  // namespace

core::Expected<CanTransport> CanTransport::open_socketcan(std::string_view interface,
                                                          std::span<const CanFilter> filters,
                                                          const SocketCanOptions& options) {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    return core::make_error("CAN interface name '" + std::string(interface) +
                            "': expected 1.." + std::to_string(IFNAMSIZ - 1) + " characters");
  }
  if (filters.size() > CAN_RAW_FILTER_MAX) {
    return core::make_error("CAN interface '" + std::string(interface) + "': " +
                            std::to_string(filters.size()) + " receive filters, expected at most " +
                            std::to_string(CAN_RAW_FILTER_MAX));
  }
  FdGuard fd(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
  if (fd.get() < 0) return socket_error(interface, "socket(PF_CAN, SOCK_RAW, CAN_RAW)", errno);

  const std::string name(interface);
  const unsigned index = ::if_nametoindex(name.c_str());
  if (index == 0) {
    const int error = errno;
    return core::make_error("CAN interface '" + name + "' does not exist (" + errno_text(error) +
                            "): check 'ip -details link show " + name +
                            "'; a virtual bus for tests is 'ip link add dev " + name +
                            " type vcan && ip link set " + name + " up'");
  }
  if (auto up = check_interface_up(fd.get(), interface); !up) return std::move(up).error();

  std::array<can_filter, CAN_RAW_FILTER_MAX> raw_filters{};
  for (std::size_t i = 0; i < filters.size(); ++i) {
    raw_filters[i].can_id = filters[i].id;
    raw_filters[i].can_mask = filters[i].mask;
  }
  if (!filters.empty() &&
      ::setsockopt(fd.get(), SOL_CAN_RAW, CAN_RAW_FILTER, raw_filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0) {
    return socket_error(interface, "setsockopt(CAN_RAW_FILTER)", errno);
  }
  if (options.error_frames) {
    const can_err_mask_t mask = kErrorClasses;
    if (::setsockopt(fd.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) != 0) {
      return socket_error(interface, "setsockopt(CAN_RAW_ERR_FILTER)", errno);
    }
  }
  const int own = options.receive_own_frames ? 1 : 0;
  if (::setsockopt(fd.get(), SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own) != 0) {
    return socket_error(interface, "setsockopt(CAN_RAW_RECV_OWN_MSGS)", errno);
  }
  const int on = 1;
  if (::setsockopt(fd.get(), SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {
    return socket_error(interface, "setsockopt(SO_RXQ_OVFL)", errno);
  }
  if (options.receive_buffer_bytes > 0 &&
      ::setsockopt(fd.get(), SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes,
                   sizeof options.receive_buffer_bytes) != 0) {
    return socket_error(interface, "setsockopt(SO_RCVBUF)", errno);
  }
  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(index);
  if (::bind(fd.get(), reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    return socket_error(interface, "bind", errno);
  }
  return CanTransport(fd.release(), name, true);
}

core::Expected<CanTransport> CanTransport::from_fd(int fd, std::string name) {
  FdGuard guard(fd);
  if (fd < 0) return core::make_error("CAN transport '" + name + "': invalid file descriptor");
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) != 0) {
    return core::make_error("CAN transport '" + name + "': fcntl(O_NONBLOCK) failed: " +
                            errno_text(errno));
  }
  return CanTransport(guard.release(), std::move(name), false);
}

CanTransport::CanTransport(int fd, std::string name, bool socketcan) noexcept
    : fd_(fd), name_(std::move(name)), socketcan_(socketcan) {}

CanTransport::CanTransport(CanTransport&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      name_(std::move(other.name_)),
      socketcan_(other.socketcan_),
      last_kernel_drop_count_(other.last_kernel_drop_count_),
      counters_(other.counters_) {}

CanTransport& CanTransport::operator=(CanTransport&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    name_ = std::move(other.name_);
    socketcan_ = other.socketcan_;
    last_kernel_drop_count_ = other.last_kernel_drop_count_;
    counters_ = other.counters_;
  }
  return *this;
}

CanTransport::~CanTransport() {
  if (fd_ >= 0) ::close(fd_);
}

std::size_t CanTransport::receive(std::span<can_frame> out) noexcept {
  const std::size_t wanted = std::min(out.size(), kMaxFramesPerCall);
  if (wanted == 0 || fd_ < 0) return 0;
  // Per-message control space for the SO_RXQ_OVFL drop counter (a u32).
  constexpr std::size_t kControlBytes = CMSG_SPACE(sizeof(std::uint32_t));
  std::array<mmsghdr, kMaxFramesPerCall> messages{};
  std::array<iovec, kMaxFramesPerCall> vectors{};
  alignas(cmsghdr) std::array<std::array<unsigned char, kControlBytes>, kMaxFramesPerCall>
      control{};
  for (std::size_t i = 0; i < wanted; ++i) {
    vectors[i].iov_base = &out[i];
    vectors[i].iov_len = sizeof(can_frame);
    messages[i].msg_hdr.msg_iov = &vectors[i];
    messages[i].msg_hdr.msg_iovlen = 1;
    if (socketcan_) {
      messages[i].msg_hdr.msg_control = control[i].data();
      messages[i].msg_hdr.msg_controllen = kControlBytes;
    }
  }
  ++counters_.rx_calls;
  const int received =
      ::recvmmsg(fd_, messages.data(), static_cast<unsigned>(wanted), MSG_DONTWAIT, nullptr);
  if (received < 0) {
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      ++counters_.io_errors;
      counters_.last_errno = errno;
    }
    return 0;
  }
  // Keep the good frames packed at the front of `out`.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(received); ++i) {
    msghdr& header = messages[i].msg_hdr;
    for (cmsghdr* c = CMSG_FIRSTHDR(&header); c != nullptr; c = CMSG_NXTHDR(&header, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t total = 0;
        std::memcpy(&total, CMSG_DATA(c), sizeof total);
        counters_.rx_kernel_drops += total - last_kernel_drop_count_;
        last_kernel_drop_count_ = total;
      }
    }
    if (messages[i].msg_len != sizeof(can_frame) || (header.msg_flags & MSG_TRUNC) != 0) {
      ++counters_.rx_malformed;
      continue;
    }
    if (kept != i) out[kept] = out[i];
    if ((out[kept].can_id & CAN_ERR_FLAG) != 0U) {
      ++counters_.rx_error_frames;
    } else {
      ++counters_.rx_frames;
    }
    ++kept;
  }
  return kept;
}

std::size_t CanTransport::send(std::span<const can_frame> frames) noexcept {
  if (frames.empty()) return 0;
  const std::size_t wanted = std::min(frames.size(), kMaxFramesPerCall);
  std::array<mmsghdr, kMaxFramesPerCall> messages{};
  std::array<iovec, kMaxFramesPerCall> vectors{};
  for (std::size_t i = 0; i < wanted; ++i) {
    // sendmmsg does not write through iov_base; the cast only satisfies iovec's type.
    vectors[i].iov_base = const_cast<can_frame*>(&frames[i]);  // NOLINT
    vectors[i].iov_len = sizeof(can_frame);
    messages[i].msg_hdr.msg_iov = &vectors[i];
    messages[i].msg_hdr.msg_iovlen = 1;
  }
  ++counters_.tx_calls;
  const int sent = fd_ < 0 ? -1
                           : ::sendmmsg(fd_, messages.data(), static_cast<unsigned>(wanted),
                                        MSG_DONTWAIT | MSG_NOSIGNAL);
  std::size_t accepted = 0;
  if (sent < 0) {
    if (errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS) {
      ++counters_.io_errors;
      counters_.last_errno = errno;
    }
  } else {
    accepted = static_cast<std::size_t>(sent);
  }
  counters_.tx_frames += accepted;
  counters_.tx_dropped += frames.size() - accepted;
  return accepted;
}

bool CanTransport::wait_readable(std::int64_t timeout_ns) const noexcept {
  pollfd request{fd_, POLLIN, 0};
  const auto timeout_ms = static_cast<int>(std::clamp<std::int64_t>(
      (timeout_ns + 999'999) / 1'000'000, 0, std::int64_t{1} << 30));
  const int ready = ::poll(&request, 1, timeout_ms);
  return ready > 0 && (request.revents & POLLIN) != 0;
}

core::Expected<CanTransportPair> make_transport_pair(std::string name_a, std::string name_b) {
  std::array<int, 2> fds{-1, -1};
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, fds.data()) != 0) {
    return core::make_error("socketpair(AF_UNIX, SOCK_SEQPACKET) failed: " + errno_text(errno));
  }
  auto a = CanTransport::from_fd(fds[0], std::move(name_a));
  if (!a) {
    ::close(fds[1]);
    return std::move(a).error();
  }
  auto b = CanTransport::from_fd(fds[1], std::move(name_b));
  if (!b) return std::move(b).error();
  return CanTransportPair{std::move(*a), std::move(*b)};
}

}  // namespace trainer::hal::socketcan
