// apply_rt_settings, kernel_is_preempt_rt, prefault_stack. The report must agree with what the
// kernel says afterwards (pthread_getschedparam, sched_getaffinity, VmLck), whether the test
// runs as root (requests obtained) or not (fallbacks with warnings). Each request is applied
// on a fresh RtThread so scheduling and affinity changes die with it; memory locking is
// process-wide and is undone with munlockall.
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/utsname.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "trainer/loop/rt_settings.hpp"
#include "trainer/loop/rt_thread.hpp"

namespace trainer::loop {
namespace {

bool any_warning_contains(const RtReport& report, const std::string& text) {
  for (const std::string& warning : report.warnings) {
    if (warning.find(text) != std::string::npos) return true;
  }
  return false;
}

// What the kernel says about the calling thread, read independently of the code under test.
struct ThreadState {
  std::string policy;
  int priority = -1;
  int single_cpu = -1;  // -1 when more than one CPU is allowed
};

ThreadState read_thread_state() {
  ThreadState state;
  int policy = -1;
  sched_param parameter{};
  EXPECT_EQ(pthread_getschedparam(pthread_self(), &policy, &parameter), 0);
  state.policy = policy == SCHED_FIFO ? "SCHED_FIFO" : policy == SCHED_OTHER ? "SCHED_OTHER" : "?";
  state.priority = parameter.sched_priority;
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  EXPECT_EQ(sched_getaffinity(0, sizeof allowed, &allowed), 0);  // 0 = the calling thread
  if (CPU_COUNT(&allowed) == 1) {
    for (std::size_t cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
      if (CPU_ISSET(cpu, &allowed)) state.single_cpu = static_cast<int>(cpu);
    }
  }
  return state;
}

struct Outcome {
  RtReport report;
  ThreadState state;
  std::optional<std::uint64_t> locked_kib;
};

// Applies `request` on a new thread and reads the kernel's view right after, on that thread.
Outcome apply_on_fresh_thread(const RtRequest& request) {
  Outcome outcome;
  auto thread = RtThread::start([&] {
    outcome.report = apply_rt_settings(request);
    outcome.state = read_thread_state();
    outcome.locked_kib = locked_memory_kib();
  });
  EXPECT_TRUE(thread.has_value()) << (thread ? "" : thread.error().message);
  if (thread) thread->join();
  if (outcome.report.memory_locked) munlockall();
  return outcome;
}

void expect_report_matches_kernel(const RtRequest& request, const Outcome& outcome) {
  const RtReport& report = outcome.report;
  EXPECT_EQ(report.policy, outcome.state.policy);
  EXPECT_EQ(report.priority, outcome.state.priority);
  EXPECT_EQ(report.cpu, outcome.state.single_cpu);

  const std::string wanted_policy = request.priority > 0 ? "SCHED_FIFO" : "SCHED_OTHER";
  const bool scheduling_obtained =
      report.policy == wanted_policy && report.priority == request.priority;
  EXPECT_EQ(!scheduling_obtained, any_warning_contains(report, wanted_policy + " priority"))
      << "a warning is expected exactly when the scheduling request was not obtained";
  if (!scheduling_obtained && request.priority > 0) {
    EXPECT_TRUE(any_warning_contains(report, "CAP_SYS_NICE"));
  }

  if (request.cpu >= 0) {
    EXPECT_EQ(report.cpu != request.cpu, any_warning_contains(report, "pinning to CPU"));
  }

  if (request.lock_memory) {
    ASSERT_TRUE(outcome.locked_kib.has_value());
    EXPECT_EQ(report.memory_locked, *outcome.locked_kib > 0);
    EXPECT_EQ(!report.memory_locked, any_warning_contains(report, "memory not locked"));
  } else {
    EXPECT_FALSE(report.memory_locked);
  }

  utsname names{};
  ASSERT_EQ(uname(&names), 0);
  EXPECT_EQ(report.kernel_release, names.release);
  EXPECT_EQ(report.kernel_version, names.version);
  EXPECT_EQ(report.preempt_rt, kernel_is_preempt_rt());
}

TEST(RtSettings, FifoPinnedLockedReportMatchesKernel) {
  RtRequest request;
  request.priority = 10;
  request.cpu = 0;
  request.lock_memory = true;
  request.stack_prefault_bytes = std::size_t{128} * 1024;
  const Outcome outcome = apply_on_fresh_thread(request);
  expect_report_matches_kernel(request, outcome);
  EXPECT_EQ(outcome.report.stack_prefaulted_bytes, 128u * 1024u);
  for (const std::string& warning : outcome.report.warnings)
    std::cout << "warning: " << warning << "\n";
}

TEST(RtSettings, OtherPolicyUnpinnedHasNoSchedulingWarnings) {
  RtRequest request;
  request.priority = 0;
  request.cpu = -1;
  request.lock_memory = false;
  const Outcome outcome = apply_on_fresh_thread(request);
  expect_report_matches_kernel(request, outcome);
  EXPECT_EQ(outcome.report.policy, "SCHED_OTHER");
  EXPECT_TRUE(outcome.report.warnings.empty());
}

TEST(RtSettings, OutOfRangeRequestsFallBackWithWarnings) {
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  ASSERT_GT(online, 0);
  RtRequest request;
  request.priority = 150;
  request.cpu = static_cast<int>(online) + 3;
  request.lock_memory = false;
  const Outcome outcome = apply_on_fresh_thread(request);
  EXPECT_EQ(outcome.report.policy, outcome.state.policy);
  EXPECT_EQ(outcome.report.cpu, outcome.state.single_cpu);
  EXPECT_TRUE(any_warning_contains(outcome.report, "priority 150 requested"));
  EXPECT_TRUE(any_warning_contains(outcome.report, "CPUs are online"));
  EXPECT_EQ(outcome.report.warnings.size(), 2u);
}

TEST(RtSettings, StackPrefaultIsClampedToTheThreadStack) {
  RtReport report;
  auto thread = RtThread::start(
      [&] {
        RtRequest request;
        request.lock_memory = false;
        request.stack_prefault_bytes = 4u << 20;  // more than the 1 MiB stack
        report = apply_rt_settings(request);
      },
      std::size_t{1} << 20);
  ASSERT_TRUE(thread.has_value()) << thread.error().message;
  thread->join();
  EXPECT_GT(report.stack_prefaulted_bytes, 0u);
  EXPECT_LT(report.stack_prefaulted_bytes, std::size_t{1} << 20);
  EXPECT_TRUE(any_warning_contains(report, "stack prefault of 4194304 bytes requested"));
}

// As root the requests above are obtained; this runs the refusal path for real by dropping to
// an unprivileged user in a child process (no capabilities, rtprio limit from the system).
TEST(RtSettings, UnprivilegedChildGetsFallbackConsistentWithKernel) {
  if (geteuid() != 0) GTEST_SKIP() << "not root: the other tests already run unprivileged";
  int pipe_ends[2];
  ASSERT_EQ(pipe(pipe_ends), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    close(pipe_ends[0]);
    std::string verdict;
    if (setgid(65534) != 0 || setuid(65534) != 0) {
      verdict = "skip: cannot drop to uid 65534";
    } else {
      RtRequest request;
      request.priority = 20;
      request.cpu = 0;
      request.lock_memory = false;
      const RtReport report = apply_rt_settings(request);
      const ThreadState state = read_thread_state();
      const bool consistent = report.policy == state.policy && report.priority == state.priority &&
                              report.cpu == state.single_cpu;
      const bool fifo = report.policy == "SCHED_FIFO";
      const bool warned = any_warning_contains(report, "SCHED_FIFO priority 20 requested") &&
                          any_warning_contains(report, "Operation not permitted");
      verdict = !consistent ? "fail: report disagrees with the kernel"
                : fifo      ? "skip: rtprio limit lets uid 65534 use SCHED_FIFO"
                : !warned   ? "fail: refused without the expected warning"
                            : "ok";
    }
    const ssize_t written = write(pipe_ends[1], verdict.data(), verdict.size());
    _exit(written == static_cast<ssize_t>(verdict.size()) ? 0 : 1);
  }
  close(pipe_ends[1]);
  std::string verdict;
  char buffer[256];
  ssize_t got = 0;
  while ((got = read(pipe_ends[0], buffer, sizeof buffer)) > 0) {
    verdict.append(buffer, static_cast<std::size_t>(got));
  }
  close(pipe_ends[0]);
  int child_status = 0;
  ASSERT_EQ(waitpid(child, &child_status, 0), child);
  ASSERT_TRUE(WIFEXITED(child_status));
  if (verdict.rfind("skip", 0) == 0) GTEST_SKIP() << verdict;
  EXPECT_EQ(verdict, "ok");
}

TEST(RtSettings, PreemptRtDecisionAgreesWithSysKernelRealtime) {
  utsname names{};
  ASSERT_EQ(uname(&names), 0);
  const bool uname_says_rt = std::string(names.version).find("PREEMPT_RT") != std::string::npos;
  // stdio rather than iostreams: GCC 12 -Wnull-dereference misfires inside istreambuf_iterator.
  std::FILE* file = std::fopen("/sys/kernel/realtime", "r");
  if (file != nullptr) {
    const int first = std::fgetc(file);
    std::fclose(file);
    EXPECT_EQ(kernel_is_preempt_rt(), first == '1' || uname_says_rt);
  } else {
    EXPECT_EQ(kernel_is_preempt_rt(), uname_says_rt);
  }
}

TEST(RtSettings, PreemptRtDecisionFromEvidence) {
  EXPECT_TRUE(kernel_is_preempt_rt(std::string_view("1\n"), "#1 SMP PREEMPT_DYNAMIC"));
  EXPECT_FALSE(kernel_is_preempt_rt(std::string_view("0\n"), "#1 SMP PREEMPT_DYNAMIC"));
  EXPECT_TRUE(kernel_is_preempt_rt(std::nullopt, "#1 SMP PREEMPT_RT Debian 6.1.0-rt"));
  EXPECT_FALSE(kernel_is_preempt_rt(std::nullopt, "#1 SMP PREEMPT_DYNAMIC Fri"));
  EXPECT_FALSE(kernel_is_preempt_rt(std::string_view(""), ""));
}

// Residency of the pages in [low, high) according to mincore.
std::size_t resident_pages(std::uintptr_t low, std::uintptr_t high, std::size_t page_bytes,
                           std::size_t* total) {
  *total = (high - low) / page_bytes;
  std::vector<unsigned char> residency(*total);
  // Page-aligned addresses are computed as integers; the cast back is the point.
  void* start = reinterpret_cast<void*>(low);  // NOLINT(performance-no-int-to-ptr)
  if (mincore(start, high - low, residency.data()) != 0) return 0;
  std::size_t resident = 0;
  for (unsigned char page : residency) resident += page & 1u;
  return resident;
}

TEST(RtSettings, PrefaultStackMakesThePagesResident) {
  constexpr std::size_t kPrefaultBytes = std::size_t{2} << 20;
  const auto page_bytes = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  std::size_t total = 0;
  std::size_t resident_before = 0;
  std::size_t resident_after = 0;
  bool dropped = false;
  auto thread = RtThread::start(
      [&] {
        const auto frame = reinterpret_cast<std::uintptr_t>(__builtin_frame_address(0));
        // The probed range ends 64 KiB below this frame (below anything in use) and starts far
        // enough above the prefault's lower end to lie inside it.
        const std::uintptr_t high = (frame - std::uintptr_t{64} * 1024) / page_bytes * page_bytes;
        const std::uintptr_t low = high - (kPrefaultBytes - std::size_t{128} * 1024);
        // Start from non-resident pages whatever the stack's history (glibc reuses cached stacks):
        // the range is unused stack, so dropping it is harmless. Fails if memory is locked.
        void* start = reinterpret_cast<void*>(low);  // NOLINT(performance-no-int-to-ptr)
        dropped = madvise(start, high - low, MADV_DONTNEED) == 0;
        resident_before = resident_pages(low, high, page_bytes, &total);
        prefault_stack(kPrefaultBytes);
        resident_after = resident_pages(low, high, page_bytes, &total);
      },
      std::size_t{8} << 20);
  ASSERT_TRUE(thread.has_value()) << thread.error().message;
  thread->join();
  if (!dropped) GTEST_SKIP() << "madvise(MADV_DONTNEED) refused (memory locked?)";
  ASSERT_GT(total, 0u);
  EXPECT_EQ(resident_before, 0u);
  EXPECT_EQ(resident_after, total);
}

TEST(CpuLatencyRequest, NoRequestHoldsNothing) {
  const CpuLatencyRequest none = CpuLatencyRequest::hold(-1);
  EXPECT_FALSE(none.held());
  EXPECT_EQ(none.latency_us(), -1);
  EXPECT_TRUE(none.warning().empty());
}

TEST(CpuLatencyRequest, HeldWhilePermittedElseWarns) {
  // As root the PM QoS device accepts the request; otherwise the refusal must be explained.
  CpuLatencyRequest request = CpuLatencyRequest::hold(0);
  const bool can_open = ::access("/dev/cpu_dma_latency", W_OK) == 0;
  EXPECT_EQ(request.held(), can_open) << request.warning();
  if (request.held()) {
    EXPECT_EQ(request.latency_us(), 0);
    // Moving keeps exactly one owner of the descriptor.
    CpuLatencyRequest moved = std::move(request);
    EXPECT_TRUE(moved.held());
    EXPECT_FALSE(request.held());  // NOLINT(bugprone-use-after-move): checking the moved-from state
  } else {
    EXPECT_NE(request.warning().find("/dev/cpu_dma_latency"), std::string::npos);
  }
}

}  // namespace
}  // namespace trainer::loop
