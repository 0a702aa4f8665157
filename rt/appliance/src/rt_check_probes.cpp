// The nine checks of the RT self-check, each a function of the files below the root and the
// request (rt_check.hpp). The fixes name the command or kernel argument that removes the
// failure; docs/appliance.md explains them.
#include <algorithm>
#include <charconv>
#include <cstdint>
#include <sstream>

#include "trainer/appliance/rt_check.hpp"

namespace trainer::appliance {

namespace {

std::string trimmed(std::string_view text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '\t'))
    text.remove_suffix(1);
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  return std::string(text);
}

std::vector<std::string> rtc_words(std::string_view text, std::string_view separators = " \t\n") {
  std::vector<std::string> words;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find_first_of(separators, start);
    const std::size_t stop = end == std::string_view::npos ? text.size() : end;
    if (stop > start) words.emplace_back(text.substr(start, stop - start));
    start = stop + 1;
  }
  return words;
}

bool contains_cpu(const std::vector<int>& cpus, int cpu) {
  return std::find(cpus.begin(), cpus.end(), cpu) != cpus.end();
}

// The CPU list a kernel argument names on the command line ("isolcpus=managed_irq,domain,2-3"
// gives 2-3), nullopt when the argument is absent.
std::optional<std::vector<int>> cmdline_cpus(const std::string& cmdline, std::string_view key) {
  for (const std::string& word : rtc_words(cmdline)) {
    if (word.rfind(std::string(key) + "=", 0) != 0) continue;
    std::string_view value = std::string_view(word).substr(key.size() + 1);
    // isolcpus flags come before the list: skip words that are not digits.
    while (!value.empty() && !(value.front() >= '0' && value.front() <= '9')) {
      const std::size_t comma = value.find(',');
      value = comma == std::string_view::npos ? std::string_view{} : value.substr(comma + 1);
    }
    auto cpus = parse_cpu_list(value);
    return cpus ? *cpus : std::vector<int>{};
  }
  return std::nullopt;
}

std::optional<std::uint64_t> rtc_number(std::string_view text) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  return value;
}

RtCheckResult result_of(RtCheckId id, RtOutcome outcome, std::string detail, std::string fix = {}) {
  RtCheckResult result;
  result.id = id;
  result.outcome = outcome;
  result.detail = std::move(detail);
  if (outcome != RtOutcome::pass) result.fix = std::move(fix);
  return result;
}

RtCheckResult check_preempt_rt(const SystemFiles& files) {
  const auto realtime = files.read("/sys/kernel/realtime");
  const std::string version = trimmed(files.read("/proc/sys/kernel/version").value_or(""));
  const std::string release = trimmed(files.read("/proc/sys/kernel/osrelease").value_or("?"));
  if (realtime && trimmed(*realtime) == "1") {
    return result_of(RtCheckId::preempt_rt, RtOutcome::pass,
                     "PREEMPT_RT kernel " + release + " (/sys/kernel/realtime = 1)");
  }
  if (version.find("PREEMPT_RT") != std::string::npos) {
    return result_of(RtCheckId::preempt_rt, RtOutcome::pass,
                     "PREEMPT_RT kernel " + release + " (" + version + ")");
  }
  return result_of(RtCheckId::preempt_rt, RtOutcome::fail,
                   "kernel " + release + " is not PREEMPT_RT (" + version + ")",
                   "apt install linux-image-rt-amd64, then boot the -rt kernel");
}

RtCheckResult check_isolated_cpu(const SystemFiles& files, const RtCheckRequest& request) {
  if (request.cpu < 0) {
    return result_of(RtCheckId::isolated_cpu, RtOutcome::warn,
                     "the scene does not pin the loop (loop.cpu = -1)",
                     "set loop.cpu in the scene to an isolated CPU");
  }
  const std::string cpu = std::to_string(request.cpu);
  const std::string cmdline = files.read("/proc/cmdline").value_or("");
  std::vector<int> isolated =
      parse_cpu_list(files.read("/sys/devices/system/cpu/isolated").value_or(""))
          .value_or(std::vector<int>{});
  if (auto from_cmdline = cmdline_cpus(cmdline, "isolcpus")) {
    isolated.insert(isolated.end(), from_cmdline->begin(), from_cmdline->end());
  }
  std::vector<int> nohz =
      parse_cpu_list(files.read("/sys/devices/system/cpu/nohz_full").value_or(""))
          .value_or(std::vector<int>{});
  if (auto from_cmdline = cmdline_cpus(cmdline, "nohz_full")) {
    nohz.insert(nohz.end(), from_cmdline->begin(), from_cmdline->end());
  }
  const std::vector<int> rcu = cmdline_cpus(cmdline, "rcu_nocbs").value_or(std::vector<int>{});
  const std::string all_args = "isolcpus=" + cpu + " nohz_full=" + cpu + " rcu_nocbs=" + cpu +
                               " irqaffinity=<the other CPUs>";
  const std::string fix_text =
      "add to GRUB_CMDLINE_LINUX in /etc/default/grub: " + all_args + "; update-grub; reboot";
  if (!contains_cpu(isolated, request.cpu)) {
    return result_of(RtCheckId::isolated_cpu, RtOutcome::fail,
                     "loop CPU " + cpu + " is not isolated (isolcpus)", fix_text);
  }
  std::string missing;
  if (!contains_cpu(nohz, request.cpu)) missing += " nohz_full";
  if (!contains_cpu(rcu, request.cpu)) missing += " rcu_nocbs";
  if (!missing.empty()) {
    return result_of(RtCheckId::isolated_cpu, RtOutcome::warn,
                     "loop CPU " + cpu + " is isolated but not in" + missing, fix_text);
  }
  return result_of(RtCheckId::isolated_cpu, RtOutcome::pass,
                   "loop CPU " + cpu + " is isolated, nohz_full and rcu_nocbs");
}

RtCheckResult check_cpu_dma_latency(const SystemFiles& files, const RtCheckRequest& request) {
  const std::string when = request.cpu_dma_latency_us < 0
                               ? " (the scene makes no request: loop.cpu_dma_latency_us = -1)"
                               : "";
  if (!files.exists("/dev/cpu_dma_latency")) {
    return result_of(RtCheckId::cpu_dma_latency, RtOutcome::fail,
                     "/dev/cpu_dma_latency is absent" + when,
                     "a kernel with CONFIG_PM_QOS (every Debian kernel); or boot with "
                     "intel_idle.max_cstate=1 processor.max_cstate=1");
  }
  if (!files.writable("/dev/cpu_dma_latency")) {
    return result_of(RtCheckId::cpu_dma_latency, RtOutcome::fail,
                     "/dev/cpu_dma_latency is not writable by this user" + when,
                     "the package's udev rule (60-trainer.rules) gives group trainer write "
                     "access; run as user trainer, or chgrp trainer /dev/cpu_dma_latency && "
                     "chmod g+w /dev/cpu_dma_latency");
  }
  return result_of(RtCheckId::cpu_dma_latency, RtOutcome::pass,
                   "/dev/cpu_dma_latency is writable" + when);
}

RtCheckResult check_cpu_governor(const SystemFiles& files, const RtCheckRequest& request) {
  const int cpu = std::max(request.cpu, 0);
  const std::string path =
      "/sys/devices/system/cpu/cpu" + std::to_string(cpu) + "/cpufreq/scaling_governor";
  const auto governor = files.read(path);
  if (!governor) {
    return result_of(RtCheckId::cpu_governor, RtOutcome::warn,
                     "CPU " + std::to_string(cpu) +
                         " has no cpufreq governor (no cpufreq driver: the kernel does not "
                         "scale it; firmware may)",
                     "set the firmware's power profile to maximum performance (no C-states, "
                     "no turbo) on the appliance");
  }
  const std::string name = trimmed(*governor);
  if (name == "performance") {
    return result_of(RtCheckId::cpu_governor, RtOutcome::pass,
                     "CPU " + std::to_string(cpu) + " governor: performance");
  }
  return result_of(RtCheckId::cpu_governor, RtOutcome::fail,
                   "CPU " + std::to_string(cpu) + " governor: " + name +
                       " (frequency changes add wake-up latency)",
                   "echo performance > " + path +
                       " (at boot: cpufrequtils GOVERNOR=performance, or cpupower "
                       "frequency-set -g performance)");
}

RtCheckResult check_smt(const SystemFiles& files, const RtCheckRequest& request) {
  const auto active = files.read("/sys/devices/system/cpu/smt/active");
  if (!active || trimmed(*active) != "1") {
    return result_of(RtCheckId::smt, RtOutcome::pass,
                     active ? "SMT is not active" : "no SMT control (single thread per core)");
  }
  if (request.cpu >= 0) {
    const auto siblings =
        parse_cpu_list(files
                           .read("/sys/devices/system/cpu/cpu" + std::to_string(request.cpu) +
                                 "/topology/thread_siblings_list")
                           .value_or(""));
    const std::vector<int> isolated =
        parse_cpu_list(files.read("/sys/devices/system/cpu/isolated").value_or(""))
            .value_or(std::vector<int>{});
    if (siblings && !siblings->empty() &&
        std::all_of(siblings->begin(), siblings->end(),
                    [&](int cpu) { return contains_cpu(isolated, cpu); })) {
      return result_of(RtCheckId::smt, RtOutcome::pass,
                       "SMT is active, and every sibling of loop CPU " +
                           std::to_string(request.cpu) + " is isolated too");
    }
  }
  return result_of(RtCheckId::smt, RtOutcome::warn,
                   "SMT is active: the loop CPU's sibling thread shares its core and caches",
                   "boot with nosmt (or echo off > /sys/devices/system/cpu/smt/control), or "
                   "isolate the loop CPU's siblings too");
}

RtCheckResult check_rt_throttling(const SystemFiles& files) {
  const std::string runtime =
      trimmed(files.read("/proc/sys/kernel/sched_rt_runtime_us").value_or("?"));
  if (runtime == "-1") {
    return result_of(RtCheckId::rt_throttling, RtOutcome::pass,
                     "RT throttling is off (sched_rt_runtime_us = -1)");
  }
  const std::string period =
      trimmed(files.read("/proc/sys/kernel/sched_rt_period_us").value_or("?"));
  return result_of(RtCheckId::rt_throttling, RtOutcome::warn,
                   "RT tasks may use " + runtime + " us of every " + period +
                       " us; a loop that runs longer is stopped for the rest of the period",
                   "sysctl -w kernel.sched_rt_runtime_us=-1 (persist in /etc/sysctl.d/)");
}

// "Max locked memory   unlimited   unlimited   bytes" -> the soft limit, nullopt = unlimited.
struct SoftLimit {
  bool found = false;
  std::optional<std::uint64_t> value;  // nullopt = unlimited
};

SoftLimit soft_limit(const std::string& limits, std::string_view name) {
  std::istringstream lines(limits);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(std::string(name), 0) != 0) continue;
    const std::vector<std::string> fields = rtc_words(std::string_view(line).substr(name.size()));
    if (fields.empty()) return {};
    if (fields[0] == "unlimited") return {true, std::nullopt};
    const auto value = rtc_number(fields[0]);
    return value ? SoftLimit{true, value} : SoftLimit{};
  }
  return {};
}

// The effective capability set from /proc/self/status (hex CapEff).
std::uint64_t effective_capabilities(const SystemFiles& files) {
  std::istringstream lines(files.read("/proc/self/status").value_or(""));
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind("CapEff:", 0) != 0) continue;
    const std::string hex = trimmed(std::string_view(line).substr(7));
    std::uint64_t value = 0;
    std::from_chars(hex.data(), hex.data() + hex.size(), value, 16);
    return value;
  }
  return 0;
}

constexpr unsigned kCapIpcLock = 14;
constexpr unsigned kCapSysNice = 23;

RtCheckResult check_memlock(const SystemFiles& files, const RtCheckRequest& request) {
  const std::string why =
      request.lock_memory ? "" : " (the scene does not lock memory: loop.lock_memory = false)";
  if ((effective_capabilities(files) >> kCapIpcLock) & 1U) {
    return result_of(RtCheckId::memlock, RtOutcome::pass,
                     "CAP_IPC_LOCK held: memory locking is not limited" + why);
  }
  const SoftLimit limit =
      soft_limit(files.read("/proc/self/limits").value_or(""), "Max locked memory");
  const std::string fix =
      "LimitMEMLOCK=infinity in the unit (trainer.service has it); for a shell: "
      "'trainer - memlock unlimited' in /etc/security/limits.d/trainer.conf";
  if (!limit.found) {
    return result_of(RtCheckId::memlock, RtOutcome::warn,
                     "cannot read RLIMIT_MEMLOCK from /proc/self/limits" + why, fix);
  }
  if (!limit.value) {
    return result_of(RtCheckId::memlock, RtOutcome::pass, "RLIMIT_MEMLOCK is unlimited" + why);
  }
  return result_of(RtCheckId::memlock, request.lock_memory ? RtOutcome::fail : RtOutcome::warn,
                   "RLIMIT_MEMLOCK is " + std::to_string(*limit.value / 1024) +
                       " KiB: mlockall(MCL_FUTURE) fails once the process grows past it" + why,
                   fix);
}

RtCheckResult check_rtprio(const SystemFiles& files, const RtCheckRequest& request) {
  if (request.priority <= 0) {
    return result_of(RtCheckId::rtprio, RtOutcome::warn,
                     "the scene runs the loop SCHED_OTHER (loop.priority = 0)",
                     "set loop.priority (e.g. 80) in the scene");
  }
  const std::string wanted = std::to_string(request.priority);
  if ((effective_capabilities(files) >> kCapSysNice) & 1U) {
    return result_of(RtCheckId::rtprio, RtOutcome::pass,
                     "CAP_SYS_NICE held: SCHED_FIFO " + wanted + " is allowed");
  }
  const SoftLimit limit =
      soft_limit(files.read("/proc/self/limits").value_or(""), "Max realtime priority");
  const std::string fix = "LimitRTPRIO=" + wanted +
                          " (or higher) in the unit (trainer.service has 95); for a "
                          "shell: 'trainer - rtprio 95' in /etc/security/limits.d/trainer.conf";
  if (!limit.found) {
    return result_of(RtCheckId::rtprio, RtOutcome::warn,
                     "cannot read RLIMIT_RTPRIO from /proc/self/limits", fix);
  }
  if (!limit.value || *limit.value >= static_cast<std::uint64_t>(request.priority)) {
    return result_of(RtCheckId::rtprio, RtOutcome::pass,
                     "RLIMIT_RTPRIO " +
                         (limit.value ? std::to_string(*limit.value) : std::string("unlimited")) +
                         " allows SCHED_FIFO " + wanted);
  }
  return result_of(
      RtCheckId::rtprio, RtOutcome::fail,
      "RLIMIT_RTPRIO is " + std::to_string(*limit.value) + ": SCHED_FIFO " + wanted + " is refused",
      fix);
}

// IRQ numbers whose /proc/interrupts line names one of `names` (its device names after the
// counts and the chip: "  45:  0  12  IR-PCI-MSI 327680-edge  xhci_hcd").
std::vector<int> irqs_named(const std::string& interrupts, const std::vector<std::string>& names) {
  std::vector<int> irqs;
  std::istringstream lines(interrupts);
  std::string line;
  while (std::getline(lines, line)) {
    const std::size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    const auto irq = rtc_number(trimmed(std::string_view(line).substr(0, colon)));
    if (!irq) continue;  // NMI, LOC, ...
    const std::vector<std::string> fields =
        rtc_words(std::string_view(line).substr(colon + 1), " \t,");
    const bool match = std::any_of(fields.begin(), fields.end(), [&](const std::string& field) {
      return std::find(names.begin(), names.end(), field) != names.end();
    });
    if (match) irqs.push_back(static_cast<int>(*irq));
  }
  return irqs;
}

struct IrqThread {
  std::string pid;
  std::string comm;
  int policy = 0;  // 1 = SCHED_FIFO, 2 = SCHED_RR
  int rt_priority = 0;
};

// Kernel threads named irq/<irq>-<name> for one of `names` (a shared line has one thread per
// device; comm is cut to 15 characters, so <name> may be a prefix), from /proc/<pid>/comm and
// /proc/<pid>/stat (fields 40 rt_priority and 41 policy, counted after the ")" that ends the
// command name).
std::vector<IrqThread> irq_threads_of(const SystemFiles& files, int irq,
                                      const std::vector<std::string>& names) {
  std::vector<IrqThread> threads;
  const std::string prefix = "irq/" + std::to_string(irq) + "-";
  for (const std::string& pid : files.list("/proc")) {
    if (!rtc_number(pid)) continue;
    const std::string comm = trimmed(files.read("/proc/" + pid + "/comm").value_or(""));
    if (comm.rfind(prefix, 0) != 0) continue;
    const std::string action = comm.substr(prefix.size());
    if (std::none_of(names.begin(), names.end(), [&](const std::string& name) {
          return !action.empty() && name.rfind(action, 0) == 0;
        })) {
      continue;
    }
    const std::string stat = files.read("/proc/" + pid + "/stat").value_or("");
    const std::size_t paren = stat.rfind(')');
    if (paren == std::string::npos) continue;
    const std::vector<std::string> fields = rtc_words(std::string_view(stat).substr(paren + 1));
    constexpr std::size_t kRtPriorityField = 40 - 3;  // fields[0] is field 3 (state)
    constexpr std::size_t kPolicyField = 41 - 3;
    if (fields.size() <= kPolicyField) continue;
    IrqThread thread;
    thread.pid = pid;
    thread.comm = comm;
    thread.rt_priority = static_cast<int>(rtc_number(fields[kRtPriorityField]).value_or(0));
    thread.policy = static_cast<int>(rtc_number(fields[kPolicyField]).value_or(0));
    threads.push_back(std::move(thread));
  }
  return threads;
}

RtCheckResult check_irq_threads(const SystemFiles& files, const RtCheckRequest& request) {
  // What to look for in /proc/interrupts: each CAN interface by name and by its driver, the
  // USB host controllers for the usb backend and for CAN adapters on USB.
  const std::vector<std::string> kUsbHosts = {"xhci_hcd", "ehci_hcd", "ohci_hcd", "uhci_hcd"};
  std::vector<std::string> names;
  std::string seen;
  std::string warnings;
  for (const std::string& interface : request.can_interfaces) {
    const std::string net = "/sys/class/net/" + interface;
    if (!files.exists(net)) {
      warnings += interface + " is absent; ";
      continue;
    }
    if (!files.exists(net + "/device")) {
      seen += interface + ": virtual, no IRQ; ";
      continue;
    }
    names.push_back(interface);
    const std::string driver = files.resolve(net + "/device/driver");
    if (!driver.empty()) names.push_back(std::filesystem::path(driver).filename().string());
    if (files.resolve(net + "/device").find("/usb") != std::string::npos) {
      names.insert(names.end(), kUsbHosts.begin(), kUsbHosts.end());
    }
  }
  if (request.usb) names.insert(names.end(), kUsbHosts.begin(), kUsbHosts.end());
  if (names.empty() && warnings.empty()) {
    return result_of(RtCheckId::irq_threads, RtOutcome::pass,
                     seen.empty() ? "the device file names no CAN or USB interface"
                                  : seen.substr(0, seen.size() - 2));
  }
  const std::vector<int> irqs = irqs_named(files.read("/proc/interrupts").value_or(""), names);
  if (irqs.empty() && !names.empty()) {
    std::string listed;
    for (const std::string& name : names) listed += (listed.empty() ? "" : "/") + name;
    warnings += "no IRQ in /proc/interrupts names " + listed + "; ";
  }
  std::string below;
  std::string fix;
  for (const int irq : irqs) {
    const std::vector<IrqThread> threads = irq_threads_of(files, irq, names);
    if (threads.empty()) {
      warnings += "IRQ " + std::to_string(irq) + " has no irq/ thread (not threaded); ";
      continue;
    }
    for (const IrqThread& thread : threads) {
      const bool fifo = thread.policy == 1 || thread.policy == 2;
      seen += thread.comm + " " + (fifo ? "FIFO " + std::to_string(thread.rt_priority) : "OTHER") +
              "; ";
      if (request.priority > 0 && (!fifo || thread.rt_priority < request.priority)) {
        below += thread.comm + " ";
        fix += "chrt -f -p " + std::to_string(std::min(request.priority + 1, 99)) + " " +
               thread.pid + "; ";
      }
    }
  }
  const std::string detail = seen.empty() ? std::string{} : seen.substr(0, seen.size() - 2);
  if (!below.empty()) {
    return result_of(
        RtCheckId::irq_threads, RtOutcome::fail,
        "below the loop's SCHED_FIFO " + std::to_string(request.priority) + ": " + below + "(" +
            detail + ")",
        fix + "at boot: a udev/systemd unit running chrt on the irq/ threads (docs/appliance.md)");
  }
  if (!warnings.empty()) {
    return result_of(
        RtCheckId::irq_threads, RtOutcome::warn,
        warnings.substr(0, warnings.size() - 2) + (detail.empty() ? "" : " (" + detail + ")"),
        "bring the interface up (docs/appliance.md, CAN setup) on a PREEMPT_RT kernel "
        "(IRQs are threads there)");
  }
  return result_of(
      RtCheckId::irq_threads, RtOutcome::pass,
      detail + (request.priority > 0 ? " (loop SCHED_FIFO " + std::to_string(request.priority) + ")"
                                     : ""));
}

}  // namespace

std::vector<RtCheckResult> run_rt_check(const SystemFiles& files, const RtCheckRequest& request) {
  std::vector<RtCheckResult> results;
  results.push_back(check_preempt_rt(files));
  results.push_back(check_isolated_cpu(files, request));
  results.push_back(check_cpu_dma_latency(files, request));
  results.push_back(check_cpu_governor(files, request));
  results.push_back(check_smt(files, request));
  results.push_back(check_rt_throttling(files));
  results.push_back(check_memlock(files, request));
  results.push_back(check_rtprio(files, request));
  results.push_back(check_irq_threads(files, request));
  for (RtCheckResult& result : results) {
    result.fatal =
        result.outcome == RtOutcome::fail &&
        std::find(request.fatal.begin(), request.fatal.end(), result.id) != request.fatal.end();
  }
  return results;
}

}  // namespace trainer::appliance
