#include "trainer/hil/operators.hpp"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <iostream>
#include <string>

namespace trainer::hil {

namespace {

std::atomic<bool> g_interrupted{false};

extern "C" void hil_on_signal(int /*signal*/) { g_interrupted.store(true); }

// Runs `/bin/sh -c "<command> <action>"` and waits for it; true when it exits 0.
bool run_action(const std::string& command, std::string_view action) {
  const std::string line = command + " " + std::string(action);
  const pid_t child = ::fork();
  if (child < 0) {
    std::cerr << "hil: --act: fork failed: " << std::strerror(errno) << '\n';
    return false;
  }
  if (child == 0) {
    ::execl("/bin/sh", "sh", "-c", line.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  while (::waitpid(child, &status, 0) < 0) {
    if (errno != EINTR) return false;
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return true;
  std::cerr << "hil: --act: '" << line << "' failed (status " << status << "): step skipped\n";
  return false;
}

}  // namespace

bool ConsoleOperator::request(std::string_view action, std::string_view instruction) {
  if (!options_.act_command.empty()) return run_action(options_.act_command, action);
  if (!options_.interactive) return false;
  std::cout << ">>> " << instruction << "\n    [" << action
            << "] press Enter when done, or s + Enter to skip: " << std::flush;
  std::string answer;
  if (!std::getline(std::cin, answer)) return false;
  return answer != "s" && answer != "S";
}

bool ConsoleOperator::confirm(std::string_view question) {
  if (options_.yes) return true;
  if (!options_.interactive) return false;
  std::cout << "??? " << question << " [y/N] " << std::flush;
  std::string answer;
  if (!std::getline(std::cin, answer)) return false;
  return answer == "y" || answer == "Y" || answer == "yes";
}

void install_interrupt_handler() {
  struct sigaction action {};
  action.sa_handler = hil_on_signal;
  ::sigemptyset(&action.sa_mask);
  ::sigaction(SIGINT, &action, nullptr);
  ::sigaction(SIGTERM, &action, nullptr);
}

bool interrupted() noexcept { return g_interrupted.load(); }
void set_interrupted(bool value) noexcept { g_interrupted.store(value); }

void throw_if_interrupted() {
  if (g_interrupted.load()) throw Interrupted();
}

}  // namespace trainer::hil
