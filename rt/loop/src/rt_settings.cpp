// apply_rt_settings and the kernel/stack helpers declared in rt_settings.hpp. Linux/glibc.
#include "trainer/loop/rt_settings.hpp"

#include "error_text.hpp"

#include <alloca.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <string>

namespace trainer::loop {

namespace {

// Room left below the prefaulted region for the frames that run after it (the loop itself,
// signal delivery, library calls), so prefaulting never reaches the guard page.
constexpr std::size_t kStackMarginBytes = std::size_t{64} * 1024;

using detail::error_text;

std::string policy_name(int policy) {
  switch (policy) {
    case SCHED_FIFO: return "SCHED_FIFO";
    case SCHED_OTHER: return "SCHED_OTHER";
    case SCHED_RR: return "SCHED_RR";
    case SCHED_BATCH: return "SCHED_BATCH";
    case SCHED_IDLE: return "SCHED_IDLE";
    default: return "policy " + std::to_string(policy);
  }
}

// Whole contents of a small kernel file (/proc, /sys). POSIX read rather than iostreams: these
// files report size 0 and are read until EOF.
std::optional<std::string> read_small_file(const char* path) {
  const int descriptor = open(path, O_RDONLY | O_CLOEXEC);
  if (descriptor < 0) return std::nullopt;
  std::string contents;
  char buffer[4096];
  for (;;) {
    const ssize_t got = read(descriptor, buffer, sizeof buffer);
    if (got > 0) {
      contents.append(buffer, static_cast<std::size_t>(got));
    } else if (got == 0 || errno != EINTR) {
      break;
    }
  }
  close(descriptor);
  return contents;
}

// Bytes between the caller's frame and the lowest usable address of the calling thread's
// stack, minus kStackMarginBytes; nullopt when the stack bounds cannot be read.
std::optional<std::size_t> stack_room_bytes() {
  pthread_attr_t attributes;
  if (pthread_getattr_np(pthread_self(), &attributes) != 0) return std::nullopt;
  void* lowest = nullptr;
  std::size_t size_bytes = 0;
  const int result = pthread_attr_getstack(&attributes, &lowest, &size_bytes);
  pthread_attr_destroy(&attributes);
  if (result != 0) return std::nullopt;
  const auto low = reinterpret_cast<std::uintptr_t>(lowest);
  const auto here = reinterpret_cast<std::uintptr_t>(__builtin_frame_address(0));
  if (here <= low || here > low + size_bytes) return std::nullopt;
  const std::uintptr_t room = here - low;
  return room > kStackMarginBytes ? room - kStackMarginBytes : 0;
}

void lock_memory(const RtRequest& request, RtReport& report) {
  if (!request.lock_memory) return;
  const std::string advice =
      " Run as root or grant CAP_IPC_LOCK, or raise the locked-memory limit (ulimit -l "
      "unlimited, or 'memlock unlimited' in /etc/security/limits.conf); without it the loop "
      "can stall on page faults.";
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    const int error_number = errno;
    report.warnings.push_back(
        "memory locking requested, memory not locked: mlockall(MCL_CURRENT|MCL_FUTURE) failed: " +
        error_text(error_number) + "." + advice);
    return;
  }
  // Sanitizer runtimes intercept mlockall and return success without locking: trust the
  // kernel's count instead of the return value.
  const std::optional<std::uint64_t> locked_kib = locked_memory_kib();
  if (locked_kib && *locked_kib == 0) {
    report.warnings.push_back(
        "memory locking requested, memory not locked: mlockall(MCL_CURRENT|MCL_FUTURE) returned "
        "success but /proc/self/status shows VmLck 0 kB (a sanitizer runtime ignores mlockall; "
        "use a non-sanitizer build for timing runs).");
    return;
  }
  report.memory_locked = true;
}

void prefault(const RtRequest& request, RtReport& report) {
  std::size_t bytes = request.stack_prefault_bytes;
  if (bytes == 0) return;
  const std::optional<std::size_t> room = stack_room_bytes();
  if (room && bytes > *room) {
    report.warnings.push_back(
        "stack prefault of " + std::to_string(bytes) + " bytes requested, " +
        std::to_string(*room) +
        " bytes prefaulted: that is all the calling thread's stack "
        "holds below the current frame (minus a " +
        std::to_string(kStackMarginBytes) +
        "-byte margin). Start the RT thread with a larger stack (RtThread::start stack_bytes).");
    bytes = *room;
  }
  prefault_stack(bytes);
  report.stack_prefaulted_bytes = bytes;
}

void apply_scheduling(const RtRequest& request, RtReport& report) {
  const int max_priority = sched_get_priority_max(SCHED_FIFO);
  const int min_priority = sched_get_priority_min(SCHED_FIFO);
  const bool valid_priority = request.priority >= 0 && request.priority <= max_priority;
  if (!valid_priority) {
    report.warnings.push_back("scheduling priority " + std::to_string(request.priority) +
                              " requested: expected 0 (SCHED_OTHER) or " +
                              std::to_string(min_priority) + ".." + std::to_string(max_priority) +
                              " (SCHED_FIFO); the thread keeps its current policy.");
  }

  int set_error = 0;
  int current_policy = SCHED_OTHER;
  sched_param current{};
  pthread_getschedparam(pthread_self(), &current_policy, &current);
  if (valid_priority && request.priority > 0) {
    sched_param wanted{};
    wanted.sched_priority = request.priority;
    set_error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &wanted);
  } else if (valid_priority && current_policy != SCHED_OTHER) {
    // Leaving a real-time policy is always permitted; do it so the request holds even when
    // the thread inherited SCHED_FIFO from its creator.
    sched_param wanted{};
    wanted.sched_priority = 0;
    set_error = pthread_setschedparam(pthread_self(), SCHED_OTHER, &wanted);
  }

  int obtained_policy = SCHED_OTHER;
  sched_param obtained{};
  const int read_error = pthread_getschedparam(pthread_self(), &obtained_policy, &obtained);
  if (read_error != 0) {
    report.policy = "unknown";
    report.warnings.push_back("pthread_getschedparam failed: " + error_text(read_error) +
                              "; the scheduling policy obtained is unknown.");
    return;
  }
  report.policy = policy_name(obtained_policy);
  report.priority = obtained.sched_priority;
  if (!valid_priority) return;  // already warned

  const int wanted_policy = request.priority > 0 ? SCHED_FIFO : SCHED_OTHER;
  const int wanted_priority = request.priority;
  if (obtained_policy == wanted_policy && obtained.sched_priority == wanted_priority) return;
  const std::string reason =
      set_error != 0 ? "pthread_setschedparam failed: " + error_text(set_error)
                     : "pthread_setschedparam succeeded but the policy read back differs";
  std::string warning = policy_name(wanted_policy) + " priority " +
                        std::to_string(wanted_priority) + " requested, obtained " + report.policy +
                        " priority " + std::to_string(report.priority) + ": " + reason + ".";
  if (wanted_policy == SCHED_FIFO) {
    warning +=
        " Run as root or grant CAP_SYS_NICE (setcap cap_sys_nice+ep <binary>), or raise "
        "the real-time priority limit to at least " +
        std::to_string(wanted_priority) + " (ulimit -r, or 'rtprio' in /etc/security/limits.conf).";
  }
  report.warnings.push_back(std::move(warning));
}

void apply_affinity(const RtRequest& request, RtReport& report) {
  const long online_cpus = sysconf(_SC_NPROCESSORS_ONLN);
  int set_error = 0;
  std::string not_attempted_reason;
  if (request.cpu < -1) {
    not_attempted_reason =
        "expected -1 (don't pin) or a CPU number 0.." + std::to_string(online_cpus - 1);
  } else if (request.cpu >= 0 && (request.cpu >= online_cpus || request.cpu >= CPU_SETSIZE)) {
    not_attempted_reason = "only " + std::to_string(online_cpus) + " CPUs are online (0.." +
                           std::to_string(online_cpus - 1) + ")";
  } else if (request.cpu >= 0) {
    cpu_set_t wanted;
    CPU_ZERO(&wanted);
    CPU_SET(static_cast<std::size_t>(request.cpu), &wanted);
    set_error = pthread_setaffinity_np(pthread_self(), sizeof wanted, &wanted);
  }

  cpu_set_t obtained;
  CPU_ZERO(&obtained);
  const int read_error = pthread_getaffinity_np(pthread_self(), sizeof obtained, &obtained);
  if (read_error != 0) {
    report.cpu = -1;
    report.warnings.push_back("pthread_getaffinity_np failed: " + error_text(read_error) +
                              "; the CPU affinity obtained is unknown.");
    return;
  }
  report.cpu = -1;
  if (CPU_COUNT(&obtained) == 1) {
    for (std::size_t cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
      if (CPU_ISSET(cpu, &obtained)) {
        report.cpu = static_cast<int>(cpu);
        break;
      }
    }
  }

  if (request.cpu == -1 || report.cpu == request.cpu) return;
  const std::string obtained_text =
      report.cpu >= 0 ? "pinned to CPU " + std::to_string(report.cpu)
                      : "not pinned (" + std::to_string(CPU_COUNT(&obtained)) + " CPUs allowed)";
  std::string reason;
  if (!not_attempted_reason.empty()) {
    reason = "not attempted: " + not_attempted_reason;
  } else if (set_error != 0) {
    reason = "pthread_setaffinity_np failed: " + error_text(set_error) +
             ". Check that the CPU is in this process's allowed set (taskset -cp <pid>, the "
             "cgroup cpuset) and online";
  } else {
    reason = "pthread_setaffinity_np succeeded but the mask read back differs";
  }
  report.warnings.push_back("pinning to CPU " + std::to_string(request.cpu) +
                            " requested, thread " + obtained_text + ": " + reason + ".");
}

}  // namespace

RtReport apply_rt_settings(const RtRequest& request) {
  RtReport report;
  utsname names{};
  if (uname(&names) == 0) {
    report.kernel_release = names.release;
    report.kernel_version = names.version;
  }
  report.preempt_rt = kernel_is_preempt_rt();
  // Lock first so the stack pages touched next stay resident (MCL_FUTURE covers them too).
  lock_memory(request, report);
  prefault(request, report);
  apply_scheduling(request, report);
  apply_affinity(request, report);
  return report;
}

bool kernel_is_preempt_rt(std::optional<std::string_view> sys_kernel_realtime,
                          std::string_view uname_version) noexcept {
  if (sys_kernel_realtime && !sys_kernel_realtime->empty() && sys_kernel_realtime->front() == '1') {
    return true;
  }
  return uname_version.find("PREEMPT_RT") != std::string_view::npos;
}

bool kernel_is_preempt_rt() {
  const std::optional<std::string> realtime = read_small_file("/sys/kernel/realtime");
  utsname names{};
  const std::string_view version = uname(&names) == 0 ? std::string_view(names.version) : "";
  return kernel_is_preempt_rt(realtime ? std::optional<std::string_view>(*realtime) : std::nullopt,
                              version);
}

// noinline: the alloca'd region must be released when this function returns, not become
// part of a caller's frame.
[[gnu::noinline]] void prefault_stack(std::size_t bytes) noexcept {
  if (bytes == 0) return;
  auto* region = static_cast<volatile unsigned char*>(alloca(bytes));
  const long page_size = sysconf(_SC_PAGESIZE);
  const std::size_t stride = page_size > 0 ? static_cast<std::size_t>(page_size) : 4096;
  // Top down, in the direction the stack grows.
  for (std::size_t offset = bytes; offset > stride; offset -= stride) region[offset - 1] = 0;
  region[0] = 0;
}

std::optional<std::uint64_t> locked_memory_kib() {
  const std::optional<std::string> status = read_small_file("/proc/self/status");
  if (!status) return std::nullopt;
  // A line like "VmLck:\t     128 kB".
  constexpr std::string_view kKey = "\nVmLck:";
  const std::size_t key = status->find(kKey);
  if (key == std::string::npos) return std::nullopt;
  std::size_t digits = status->find_first_not_of(" \t", key + kKey.size());
  if (digits == std::string::npos) return std::nullopt;
  std::uint64_t kib = 0;
  const char* first = status->data() + digits;
  const char* last = status->data() + status->size();
  const auto [end, error] = std::from_chars(first, last, kib);
  if (error != std::errc{} || end == first) return std::nullopt;
  return kib;
}

CpuLatencyRequest CpuLatencyRequest::hold(int latency_us) {
  CpuLatencyRequest request;
  if (latency_us < 0) return request;
  const char* path = "/dev/cpu_dma_latency";
  const int fd = ::open(path, O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    request.warning_ = std::string("CPU wake-up latency of ") + std::to_string(latency_us) +
                       " us not requested: cannot open " + path + ": " + std::strerror(errno) +
                       " (needs root; deep CPU idle states will add wake-up latency)";
    return request;
  }
  // The kernel takes a binary s32 in microseconds; the request lasts while fd stays open.
  const std::int32_t value = latency_us;
  if (::write(fd, &value, sizeof value) != static_cast<ssize_t>(sizeof value)) {
    request.warning_ = std::string("CPU wake-up latency of ") + std::to_string(latency_us) +
                       " us not requested: write to " + path + " failed: " + std::strerror(errno);
    ::close(fd);
    return request;
  }
  request.fd_ = fd;
  request.latency_us_ = latency_us;
  return request;
}

CpuLatencyRequest::CpuLatencyRequest(CpuLatencyRequest&& other) noexcept
    : fd_(other.fd_), latency_us_(other.latency_us_), warning_(std::move(other.warning_)) {
  other.fd_ = -1;
}

CpuLatencyRequest& CpuLatencyRequest::operator=(CpuLatencyRequest&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    latency_us_ = other.latency_us_;
    warning_ = std::move(other.warning_);
    other.fd_ = -1;
  }
  return *this;
}

CpuLatencyRequest::~CpuLatencyRequest() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace trainer::loop
