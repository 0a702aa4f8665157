// The RT self-check over constructed /proc and /sys trees: a well-set-up appliance passes every
// check; each check's fail (and warn) outcome comes from changing one file of that tree. Then
// once over the live system, where only consistency can be asserted.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "trainer/appliance/rt_check.hpp"
#include "trainer/loop/rt_settings.hpp"

namespace trainer::appliance {
namespace {

namespace fs = std::filesystem;

class RtCheckTree : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("rt_check_test_" + std::to_string(getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    // A good appliance: PREEMPT_RT, CPU 1 isolated (with its SMT sibling 3), performance
    // governor, throttling off, limits raised, no capabilities, CAN on a PCI card whose IRQ
    // thread runs above the loop.
    write("/sys/kernel/realtime", "1\n");
    write("/proc/sys/kernel/osrelease", "6.1.0-27-rt-amd64\n");
    write("/proc/sys/kernel/version", "#1 SMP PREEMPT_RT Debian 6.1.115-1 (2024-11-01)\n");
    write("/proc/cmdline",
          "BOOT_IMAGE=/vmlinuz root=/dev/sda1 isolcpus=managed_irq,domain,1,3 "
          "nohz_full=1,3 rcu_nocbs=1,3 irqaffinity=0,2 quiet\n");
    write("/sys/devices/system/cpu/isolated", "1,3\n");
    write("/sys/devices/system/cpu/nohz_full", "1,3\n");
    write("/dev/cpu_dma_latency", "");
    write("/sys/devices/system/cpu/cpu1/cpufreq/scaling_governor", "performance\n");
    write("/sys/devices/system/cpu/smt/active", "1\n");
    write("/sys/devices/system/cpu/cpu1/topology/thread_siblings_list", "1,3\n");
    write("/proc/sys/kernel/sched_rt_runtime_us", "-1\n");
    write("/proc/sys/kernel/sched_rt_period_us", "1000000\n");
    write("/proc/self/status", "Name:\ttrainer\nCapEff:\t0000000000000000\n");
    write("/proc/self/limits",
          "Limit                     Soft Limit           Hard Limit           Units     \n"
          "Max locked memory         unlimited            unlimited            bytes     \n"
          "Max realtime priority     95                   95                   \n");
    write("/sys/devices/pci0000:00/0000:00:1c.0/0000:03:00.0/net/can0/uevent", "");
    write("/sys/bus/pci/drivers/peak_pci/uevent", "");
    fs::create_directories(map("/sys/class/net/can0").parent_path());
    fs::create_symlink("../../devices/pci0000:00/0000:00:1c.0/0000:03:00.0/net/can0",
                       map("/sys/class/net/can0"));
    fs::create_symlink("../../../0000:03:00.0",
                       map("/sys/devices/pci0000:00/0000:00:1c.0/0000:03:00.0/net/can0/device"));
    fs::create_symlink("../../../../bus/pci/drivers/peak_pci",
                       map("/sys/devices/pci0000:00/0000:00:1c.0/0000:03:00.0/driver"));
    write("/proc/interrupts",
          "           CPU0       CPU1       \n"
          "  0:         36          0   IO-APIC    2-edge      timer\n"
          " 16:       1200          0   IO-APIC   16-fasteoi   peak_pci, i801_smbus\n"
          " 45:         10          0   PCI-MSI 327680-edge      xhci_hcd\n"
          "NMI:          0          0   Non-maskable interrupts\n");
    irq_thread("120", "irq/16-peak_pci", 90);
    irq_thread("121", "irq/16-i801_smbus", 50);
    irq_thread("130", "irq/45-xhci_hcd", 50);
    request_.cpu = 1;
    request_.priority = 80;
    request_.lock_memory = true;
    request_.cpu_dma_latency_us = 0;
    request_.can_interfaces = {"can0"};
  }
  void TearDown() override { fs::remove_all(root_); }

  fs::path map(const std::string& absolute) const { return root_ / absolute.substr(1); }
  void write(const std::string& absolute, const std::string& text) {
    fs::create_directories(map(absolute).parent_path());
    std::ofstream(map(absolute)) << text;
  }
  void irq_thread(const std::string& pid, const std::string& comm, int rt_priority) {
    // (Built with append: GCC 12 warns falsely about operator+ chains here.)
    std::string directory = "/proc/";
    directory.append(pid);
    write(directory + "/comm", comm + "\n");
    // Fields 3..41 after "(comm)": state, then 36 numbers, then rt_priority (40), policy (41).
    std::string stat = pid;
    stat.append(" (").append(comm).append(") S");
    for (int field = 4; field <= 39; ++field) stat += " 0";
    stat.append(" ").append(std::to_string(rt_priority)).append(" 1 0 0 0\n");
    write(directory + "/stat", stat);
  }
  RtCheckResult check(RtCheckId id) const {
    const auto results = run_rt_check(SystemFiles(root_), request_);
    EXPECT_EQ(results.size(), kRtCheckCount);
    for (const RtCheckResult& result : results) {
      if (result.id == id) return result;
    }
    ADD_FAILURE() << "no result for " << to_string(id);
    return {};
  }

  fs::path root_;
  RtCheckRequest request_;
};

TEST_F(RtCheckTree, AWellSetUpAppliancePassesEveryCheck) {
  const auto results = run_rt_check(SystemFiles(root_), request_);
  ASSERT_EQ(results.size(), kRtCheckCount);
  for (std::size_t k = 0; k < results.size(); ++k) {
    EXPECT_EQ(results[k].id, static_cast<RtCheckId>(k));
    EXPECT_EQ(results[k].outcome, RtOutcome::pass)
        << to_string(results[k].id) << ": " << results[k].detail;
    EXPECT_TRUE(results[k].fix.empty());
  }
  EXPECT_FALSE(rt_check_failed(results));
  EXPECT_NE(check(RtCheckId::irq_threads).detail.find("irq/16-peak_pci FIFO 90"),
            std::string::npos);
}

TEST_F(RtCheckTree, PreemptRtFromUnameVersionWhenSysKernelRealtimeIsAbsent) {
  fs::remove(map("/sys/kernel/realtime"));
  EXPECT_EQ(check(RtCheckId::preempt_rt).outcome, RtOutcome::pass);
  write("/proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC Debian 6.1.115-1\n");
  const RtCheckResult result = check(RtCheckId::preempt_rt);
  EXPECT_EQ(result.outcome, RtOutcome::fail);
  EXPECT_NE(result.fix.find("linux-image-rt-amd64"), std::string::npos);
}

TEST_F(RtCheckTree, FatalOnlyWhenTheSceneListsTheFailingCheck) {
  write("/sys/kernel/realtime", "0\n");
  write("/proc/sys/kernel/version", "#1 SMP PREEMPT_DYNAMIC\n");
  EXPECT_FALSE(rt_check_failed(run_rt_check(SystemFiles(root_), request_)));
  request_.fatal = {RtCheckId::memlock};  // passes: still not fatal
  EXPECT_FALSE(rt_check_failed(run_rt_check(SystemFiles(root_), request_)));
  request_.fatal = {RtCheckId::memlock, RtCheckId::preempt_rt};
  const auto results = run_rt_check(SystemFiles(root_), request_);
  EXPECT_TRUE(rt_check_failed(results));
  EXPECT_TRUE(results[0].fatal);
  EXPECT_NE(format_rt_check(results).find("FATAL preempt_rt"), std::string::npos);
  EXPECT_NE(format_rt_check(results).find("fatal (loop.rt_check_fatal): preempt_rt"),
            std::string::npos);
}

TEST_F(RtCheckTree, IsolatedCpuFailsWarnsAndPasses) {
  write("/sys/devices/system/cpu/isolated", "3\n");
  write("/proc/cmdline", "root=/dev/sda1 nohz_full=1 rcu_nocbs=1\n");
  RtCheckResult result = check(RtCheckId::isolated_cpu);
  EXPECT_EQ(result.outcome, RtOutcome::fail);
  EXPECT_NE(result.fix.find("isolcpus=1 nohz_full=1 rcu_nocbs=1"), std::string::npos);
  write("/proc/cmdline", "root=/dev/sda1 isolcpus=1\n");
  write("/sys/devices/system/cpu/nohz_full", "\n");
  result = check(RtCheckId::isolated_cpu);
  EXPECT_EQ(result.outcome, RtOutcome::warn);
  EXPECT_NE(result.detail.find("nohz_full rcu_nocbs"), std::string::npos) << result.detail;
  request_.cpu = -1;
  EXPECT_EQ(check(RtCheckId::isolated_cpu).outcome, RtOutcome::warn);
}

TEST_F(RtCheckTree, CpuDmaLatencyAbsentFails) {
  fs::remove(map("/dev/cpu_dma_latency"));
  EXPECT_EQ(check(RtCheckId::cpu_dma_latency).outcome, RtOutcome::fail);
}

TEST_F(RtCheckTree, GovernorOtherThanPerformanceFailsAndNoCpufreqWarns) {
  write("/sys/devices/system/cpu/cpu1/cpufreq/scaling_governor", "schedutil\n");
  RtCheckResult result = check(RtCheckId::cpu_governor);
  EXPECT_EQ(result.outcome, RtOutcome::fail);
  EXPECT_NE(result.detail.find("schedutil"), std::string::npos);
  EXPECT_NE(result.fix.find("echo performance > /sys/devices/system/cpu/cpu1/cpufreq/"
                            "scaling_governor"),
            std::string::npos);
  fs::remove_all(map("/sys/devices/system/cpu/cpu1/cpufreq"));
  EXPECT_EQ(check(RtCheckId::cpu_governor).outcome, RtOutcome::warn);
}

TEST_F(RtCheckTree, SmtWarnsWhenTheLoopCpuSiblingIsNotIsolated) {
  write("/sys/devices/system/cpu/isolated", "1\n");
  RtCheckResult result = check(RtCheckId::smt);
  EXPECT_EQ(result.outcome, RtOutcome::warn);
  EXPECT_NE(result.fix.find("nosmt"), std::string::npos);
  write("/sys/devices/system/cpu/smt/active", "0\n");
  EXPECT_EQ(check(RtCheckId::smt).outcome, RtOutcome::pass);
}

TEST_F(RtCheckTree, RtThrottlingOnWarns) {
  write("/proc/sys/kernel/sched_rt_runtime_us", "950000\n");
  const RtCheckResult result = check(RtCheckId::rt_throttling);
  EXPECT_EQ(result.outcome, RtOutcome::warn);
  EXPECT_NE(result.detail.find("950000 us of every 1000000 us"), std::string::npos);
  EXPECT_NE(result.fix.find("sched_rt_runtime_us=-1"), std::string::npos);
}

TEST_F(RtCheckTree, LimitsFailBelowTheSceneUnlessTheCapabilityIsHeld) {
  write("/proc/self/limits",
        "Max locked memory         65536                65536                bytes     \n"
        "Max realtime priority     0                    0                    \n");
  RtCheckResult memlock = check(RtCheckId::memlock);
  EXPECT_EQ(memlock.outcome, RtOutcome::fail);
  EXPECT_NE(memlock.detail.find("64 KiB"), std::string::npos);
  EXPECT_NE(memlock.fix.find("LimitMEMLOCK=infinity"), std::string::npos);
  RtCheckResult rtprio = check(RtCheckId::rtprio);
  EXPECT_EQ(rtprio.outcome, RtOutcome::fail);
  EXPECT_NE(rtprio.detail.find("RLIMIT_RTPRIO is 0"), std::string::npos);
  request_.lock_memory = false;
  EXPECT_EQ(check(RtCheckId::memlock).outcome, RtOutcome::warn);
  // CAP_IPC_LOCK (bit 14) and CAP_SYS_NICE (bit 23) lift the limits.
  write("/proc/self/status", "CapEff:\t0000000000804000\n");
  EXPECT_EQ(check(RtCheckId::memlock).outcome, RtOutcome::pass);
  EXPECT_EQ(check(RtCheckId::rtprio).outcome, RtOutcome::pass);
  write("/proc/self/limits", "Max realtime priority     80                   80\n");
  write("/proc/self/status", "CapEff:\t0\n");
  EXPECT_EQ(check(RtCheckId::rtprio).outcome, RtOutcome::pass);
}

TEST_F(RtCheckTree, IrqThreadBelowTheLoopFailsWithTheChrtFix) {
  irq_thread("120", "irq/16-peak_pci", 50);
  const RtCheckResult result = check(RtCheckId::irq_threads);
  EXPECT_EQ(result.outcome, RtOutcome::fail);
  EXPECT_NE(result.detail.find("irq/16-peak_pci"), std::string::npos);
  EXPECT_EQ(result.detail.find("i801_smbus "), std::string::npos) << "shares the line only";
  EXPECT_NE(result.fix.find("chrt -f -p 81 120"), std::string::npos) << result.fix;
}

TEST_F(RtCheckTree, IrqThreadsOfTheUsbHostForTheUsbBackend) {
  request_.can_interfaces.clear();
  request_.usb = true;
  RtCheckResult result = check(RtCheckId::irq_threads);
  EXPECT_EQ(result.outcome, RtOutcome::fail);
  EXPECT_NE(result.detail.find("irq/45-xhci_hcd"), std::string::npos);
  irq_thread("130", "irq/45-xhci_hcd", 85);
  EXPECT_EQ(check(RtCheckId::irq_threads).outcome, RtOutcome::pass);
}

TEST_F(RtCheckTree, IrqThreadsWarnWhenNotThreadedOrInterfaceAbsentAndPassForVcan) {
  fs::remove_all(map("/proc/120"));
  fs::remove_all(map("/proc/121"));
  EXPECT_EQ(check(RtCheckId::irq_threads).outcome, RtOutcome::warn);
  request_.can_interfaces = {"can7"};
  EXPECT_EQ(check(RtCheckId::irq_threads).outcome, RtOutcome::warn);
  write("/sys/class/net/vcan0/uevent", "");  // a virtual interface has no device link
  request_.can_interfaces = {"vcan0"};
  const RtCheckResult result = check(RtCheckId::irq_threads);
  EXPECT_EQ(result.outcome, RtOutcome::pass);
  EXPECT_NE(result.detail.find("vcan0: virtual"), std::string::npos);
}

TEST(RtCheckNames, RoundTripAndRefuseUnknown) {
  for (std::size_t k = 0; k < kRtCheckCount; ++k) {
    const auto id = static_cast<RtCheckId>(k);
    EXPECT_EQ(rt_check_from_name(to_string(id)), id);
  }
  EXPECT_FALSE(rt_check_from_name("preempt-rt"));
}

TEST(CpuList, ParsesRangesAndRefusesGarbage) {
  EXPECT_EQ(parse_cpu_list("0-2,5,7-8\n"), (std::vector<int>{0, 1, 2, 5, 7, 8}));
  EXPECT_EQ(parse_cpu_list("\n"), std::vector<int>{});
  EXPECT_FALSE(parse_cpu_list("3-1"));
  EXPECT_FALSE(parse_cpu_list("a"));
}

// The live system: every check answers, non-passing ones carry a fix, and the PREEMPT_RT
// verdict agrees with rt/loop's.
TEST(RtCheckLive, EveryCheckAnswersOnThisMachine) {
  RtCheckRequest request;
  request.cpu = 0;
  request.priority = 80;
  request.lock_memory = true;
  request.usb = true;
  const auto results = run_rt_check(SystemFiles("/"), request);
  ASSERT_EQ(results.size(), kRtCheckCount);
  for (const RtCheckResult& result : results) {
    EXPECT_FALSE(result.detail.empty()) << to_string(result.id);
    if (result.outcome != RtOutcome::pass) {
      EXPECT_FALSE(result.fix.empty()) << to_string(result.id);
    }
    EXPECT_FALSE(result.fatal);
  }
  EXPECT_EQ(results[0].outcome == RtOutcome::pass, loop::kernel_is_preempt_rt());
  std::cout << format_rt_check(results);
}

}  // namespace
}  // namespace trainer::appliance
