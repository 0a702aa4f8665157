// The RT self-check of the machine the trainer runs on (`trainer --check-rt`, and before arming
// when the trainer applies RT settings): is the kernel PREEMPT_RT, is the loop's CPU isolated,
// can the process hold a CPU wake-up latency request, which frequency governor runs that CPU,
// is SMT active, is RT throttling on, are the memlock and rtprio limits enough, and do the IRQ
// threads of the CAN/USB interfaces run at a priority no lower than the loop's. Each check
// passes, warns or fails, with what it saw and the fix (a command or a kernel argument).
//
// Every input is a file under a root directory (SystemFiles): /proc/self/limits and
// /proc/self/status give the limits and capabilities, /proc/sys/kernel/version the uname
// version, /proc/<pid>/{comm,stat} the IRQ threads. Tests build such trees; the trainer reads "/".
// Setup path: allocates, never throws.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace trainer::appliance {

enum class RtCheckId : std::uint8_t {
  preempt_rt,
  isolated_cpu,
  cpu_dma_latency,
  cpu_governor,
  smt,
  rt_throttling,
  memlock,
  rtprio,
  irq_threads,
};
inline constexpr std::size_t kRtCheckCount = 9;
// The names the scene's loop.rt_check_fatal and the output use, in RtCheckId order.
inline constexpr std::array<std::string_view, kRtCheckCount> kRtCheckNames = {
    "preempt_rt",    "isolated_cpu", "cpu_dma_latency", "cpu_governor", "smt",
    "rt_throttling", "memlock",      "rtprio",          "irq_threads"};
std::string_view to_string(RtCheckId id) noexcept;
std::optional<RtCheckId> rt_check_from_name(std::string_view name) noexcept;

// pass: the property the loop wants is there. warn: partly there, or it cannot be told, or it
// costs latency without breaking the loop. fail: missing. Only a fail of a check the scene lists
// as fatal stops the trainer (and makes `trainer --check-rt` exit 1).
enum class RtOutcome : std::uint8_t { pass, warn, fail };
std::string_view to_string(RtOutcome outcome) noexcept;

struct RtCheckResult {
  RtCheckId id{};
  RtOutcome outcome = RtOutcome::pass;
  std::string detail;  // what was seen
  std::string fix;     // empty on pass
  bool fatal = false;  // outcome is fail and the scene lists the check as fatal
};

// What the scene and device file ask of the machine.
struct RtCheckRequest {
  int cpu = -1;                             // loop.cpu; -1 = not pinned
  int priority = 0;                         // loop.priority; 0 = SCHED_OTHER
  bool lock_memory = false;                 // loop.lock_memory
  int cpu_dma_latency_us = -1;              // loop.cpu_dma_latency_us; -1 = no request
  std::vector<std::string> can_interfaces;  // SocketCAN interfaces the device file names
  bool usb = false;                         // the device file's backend is usb
  std::vector<RtCheckId> fatal;             // loop.rt_check_fatal
};

// Reads files below a root directory: SystemFiles("/") is the live system.
class SystemFiles {
 public:
  explicit SystemFiles(std::filesystem::path root = "/");
  // Absolute path as on the target ("/proc/cmdline"), mapped below the root.
  std::filesystem::path map(std::string_view absolute) const;
  std::optional<std::string> read(std::string_view absolute) const;
  // Names of the entries of a directory (empty when absent).
  std::vector<std::string> list(std::string_view absolute) const;
  bool exists(std::string_view absolute) const;
  bool writable(std::string_view absolute) const;  // access(W_OK)
  // The target path a symlink resolves to, relative to the root ("" when not a link).
  std::string resolve(std::string_view absolute) const;

 private:
  std::filesystem::path root_;
};

std::vector<RtCheckResult> run_rt_check(const SystemFiles& files, const RtCheckRequest& request);

// "0-3,8,10-11" -> {0,1,2,3,8,10,11}; nullopt on a malformed list. Empty text -> empty set.
std::optional<std::vector<int>> parse_cpu_list(std::string_view text);

// Human-readable report: one line per check, the fix under a non-passing one, a summary line.
std::string format_rt_check(const std::vector<RtCheckResult>& results);
// True when a fatal check failed.
bool rt_check_failed(const std::vector<RtCheckResult>& results) noexcept;

}  // namespace trainer::appliance
