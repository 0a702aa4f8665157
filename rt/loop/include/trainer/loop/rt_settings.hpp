// Real-time settings of the calling thread and process: memory locking, stack prefault,
// SCHED_FIFO priority, CPU pinning, and what the kernel is. Setup path (may allocate), to be
// called on the RT thread itself before the loop is armed. Never fails: every request that
// cannot be obtained falls back to what the system allows and leaves a warning that says what
// was requested, what was obtained, why (errno text) and what to do about it. The report's
// scheduling and affinity fields are read back from the kernel, not copied from the request.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace trainer::loop {

struct RtRequest {
  int priority = 0;         // 1..99 SCHED_FIFO, 0 = SCHED_OTHER
  int cpu = -1;             // CPU to pin the calling thread to; -1 = don't pin
  bool lock_memory = true;  // mlockall(MCL_CURRENT | MCL_FUTURE), process-wide
  // Stack touched once so the loop never page-faults on it; clamped to what the calling
  // thread's stack can hold (minus a margin), with a warning.
  std::size_t stack_prefault_bytes = std::size_t{256} * 1024;
};

struct RtReport {
  // Read back with pthread_getschedparam: "SCHED_FIFO" or "SCHED_OTHER" (or "SCHED_RR",
  // "SCHED_BATCH", "SCHED_IDLE" if the thread was given one of those elsewhere).
  std::string policy;
  int priority = 0;
  // Read back with pthread_getaffinity_np: the single CPU the thread may run on, or -1 when
  // its affinity mask holds more than one CPU (not pinned).
  int cpu = -1;
  // This call locked the process memory (mlockall succeeded and /proc/self/status VmLck > 0).
  bool memory_locked = false;
  std::size_t stack_prefaulted_bytes = 0;
  // PM QoS CPU wake-up latency held for the run (CpuLatencyRequest), -1 = none held.
  int cpu_dma_latency_us = -1;
  bool preempt_rt = false;
  std::string kernel_release;         // uname -r
  std::string kernel_version;         // uname -v
  std::vector<std::string> warnings;  // one per request not obtained
};

RtReport apply_rt_settings(const RtRequest& request);

// /sys/kernel/realtime contains "1", or uname().version contains "PREEMPT_RT".
bool kernel_is_preempt_rt();
// The same decision from given evidence: the contents of /sys/kernel/realtime (nullopt when
// the file is absent) and the uname version string.
bool kernel_is_preempt_rt(std::optional<std::string_view> sys_kernel_realtime,
                          std::string_view uname_version) noexcept;

// Writes to `bytes` of stack below the caller's frame (volatile stores, one per page) so those
// pages are resident before arming. The caller guarantees its stack has room for `bytes` more.
void prefault_stack(std::size_t bytes) noexcept;

// VmLck of this process from /proc/self/status, in KiB; nullopt when it cannot be read.
std::optional<std::uint64_t> locked_memory_kib();

// Holds a PM QoS CPU wake-up latency request for its lifetime: while the file descriptor on
// /dev/cpu_dma_latency stays open, the kernel keeps every CPU out of idle states whose exit
// latency exceeds the request. Deep idle states add tens to hundreds of microseconds to a
// timer wake-up; cyclictest makes the same request (0 us) unless told --laptop, so a loop
// compared with it must make it too. Process-wide; setup path.
class CpuLatencyRequest {
 public:
  CpuLatencyRequest() = default;
  // latency_us < 0: no request. Never fails: a refusal leaves held() false with a warning.
  static CpuLatencyRequest hold(int latency_us);
  CpuLatencyRequest(CpuLatencyRequest&& other) noexcept;
  CpuLatencyRequest& operator=(CpuLatencyRequest&& other) noexcept;
  CpuLatencyRequest(const CpuLatencyRequest&) = delete;
  CpuLatencyRequest& operator=(const CpuLatencyRequest&) = delete;
  ~CpuLatencyRequest();

  bool held() const noexcept { return fd_ >= 0; }
  int latency_us() const noexcept { return held() ? latency_us_ : -1; }
  const std::string& warning() const noexcept { return warning_; }

 private:
  int fd_ = -1;
  int latency_us_ = -1;
  std::string warning_;
};

}  // namespace trainer::loop
