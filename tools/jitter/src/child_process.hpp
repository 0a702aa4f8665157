// The external programs jitter runs (cyclictest, gnuplot): found on PATH, started with
// posix_spawn with stdout and stderr in one file, a clean signal mask and default SIGINT/SIGTERM
// handling (jitter itself keeps those blocked, see loop::StopSignals, and a child would
// otherwise inherit the block across exec), waited for, or stopped with SIGINT.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"

namespace trainer::tools::jitter {

// `name` itself when it contains a '/', else the first executable PATH entry of that name.
std::optional<std::filesystem::path> find_executable(const std::string& name);

class ChildProcess {
 public:
  // argv[0] is the program (a path, or a name found on PATH). stdout and stderr go to
  // output_file (truncated). working_directory empty = jitter's own.
  static core::Expected<ChildProcess> start(const std::vector<std::string>& argv,
                                            const std::filesystem::path& output_file,
                                            const std::filesystem::path& working_directory = {});
  ChildProcess(ChildProcess&& other) noexcept;
  ChildProcess& operator=(ChildProcess&& other) = delete;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  // A child still running is stopped (SIGINT) and reaped.
  ~ChildProcess();

  pid_t pid() const noexcept { return pid_; }
  // Exit status once it has ended (128 + signal number if a signal ended it), else nullopt.
  std::optional<int> poll();
  int wait();
  void interrupt() const;  // SIGINT: cyclictest then writes its histogram and exits
  // Threads of the running process (from /proc/PID/task); 0 when it cannot be read.
  std::size_t thread_count() const;

 private:
  explicit ChildProcess(pid_t pid) : pid_(pid) {}
  pid_t pid_ = -1;
  std::optional<int> exit_status_;
};

}  // namespace trainer::tools::jitter
