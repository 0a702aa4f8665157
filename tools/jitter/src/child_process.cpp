#include "child_process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <string_view>
#include <system_error>

extern char** environ;

namespace trainer::tools::jitter {

namespace {

int decode_status(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

// posix_spawn's attributes and file actions, destroyed on every return path.
struct SpawnSetup {
  posix_spawnattr_t attributes{};
  posix_spawn_file_actions_t actions{};
  SpawnSetup() {
    posix_spawnattr_init(&attributes);
    posix_spawn_file_actions_init(&actions);
  }
  ~SpawnSetup() {
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attributes);
  }
  SpawnSetup(const SpawnSetup&) = delete;
  SpawnSetup& operator=(const SpawnSetup&) = delete;
};

}  // namespace

std::optional<std::filesystem::path> find_executable(const std::string& name) {
  if (name.empty()) return std::nullopt;
  if (name.find('/') != std::string::npos) {
    if (access(name.c_str(), X_OK) == 0) return std::filesystem::path(name);
    return std::nullopt;
  }
  // jitter never changes its environment, so reading it from any thread is safe.
  const char* path_variable = std::getenv("PATH");  // NOLINT(concurrency-mt-unsafe)
  std::string_view path = path_variable != nullptr ? path_variable : "/usr/bin:/bin";
  while (true) {
    const std::size_t colon = path.find(':');
    const std::string_view directory = path.substr(0, colon);
    const std::filesystem::path candidate =
        std::filesystem::path(directory.empty() ? "." : std::string(directory)) / name;
    if (access(candidate.c_str(), X_OK) == 0 && !std::filesystem::is_directory(candidate)) {
      return candidate;
    }
    if (colon == std::string_view::npos) break;
    path.remove_prefix(colon + 1);
  }
  return std::nullopt;
}

core::Expected<ChildProcess> ChildProcess::start(const std::vector<std::string>& argv,
                                                 const std::filesystem::path& output_file,
                                                 const std::filesystem::path& working_directory) {
  if (argv.empty()) return core::make_error("no program to start");
  const auto program = find_executable(argv[0]);
  if (!program) return core::make_error("'" + argv[0] + "' not found (PATH or that path)");

  SpawnSetup setup;
  sigset_t no_signals;
  sigemptyset(&no_signals);
  sigset_t default_signals;
  sigemptyset(&default_signals);
  sigaddset(&default_signals, SIGINT);
  sigaddset(&default_signals, SIGTERM);
  posix_spawnattr_setsigmask(&setup.attributes, &no_signals);
  posix_spawnattr_setsigdefault(&setup.attributes, &default_signals);
  posix_spawnattr_setflags(&setup.attributes,
                           static_cast<short>(POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF));
  posix_spawn_file_actions_addopen(&setup.actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&setup.actions, STDOUT_FILENO, output_file.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&setup.actions, STDOUT_FILENO, STDERR_FILENO);
  if (!working_directory.empty()) {
    posix_spawn_file_actions_addchdir_np(&setup.actions, working_directory.c_str());
  }

  std::vector<char*> arguments;
  arguments.reserve(argv.size() + 1);
  for (const std::string& argument : argv) arguments.push_back(const_cast<char*>(argument.c_str()));
  arguments.push_back(nullptr);

  pid_t pid = -1;
  // Absolute, so a relative program path survives the change of working directory.
  const std::filesystem::path executable = std::filesystem::absolute(*program);
  const int error = posix_spawn(&pid, executable.c_str(), &setup.actions, &setup.attributes,
                                arguments.data(), environ);
  if (error != 0) {
    return core::make_error("cannot start " + executable.string() + ": " +
                            std::system_category().message(error));
  }
  return ChildProcess(pid);
}

ChildProcess::ChildProcess(ChildProcess&& other) noexcept
    : pid_(other.pid_), exit_status_(other.exit_status_) {
  other.pid_ = -1;
}

ChildProcess::~ChildProcess() {
  if (pid_ > 0 && !exit_status_) {
    interrupt();
    (void)wait();
  }
}

std::optional<int> ChildProcess::poll() {
  if (exit_status_ || pid_ <= 0) return exit_status_;
  int status = 0;
  const pid_t done = waitpid(pid_, &status, WNOHANG);
  if (done == pid_) exit_status_ = decode_status(status);
  return exit_status_;
}

int ChildProcess::wait() {
  if (exit_status_ || pid_ <= 0) return exit_status_.value_or(-1);
  int status = 0;
  pid_t done = -1;
  do {
    done = waitpid(pid_, &status, 0);
  } while (done < 0 && errno == EINTR);
  exit_status_ = done == pid_ ? decode_status(status) : -1;
  return *exit_status_;
}

void ChildProcess::interrupt() const {
  if (pid_ > 0 && !exit_status_) kill(pid_, SIGINT);
}

std::size_t ChildProcess::thread_count() const {
  std::error_code error;
  std::size_t threads = 0;
  for (std::filesystem::directory_iterator it("/proc/" + std::to_string(pid_) + "/task", error),
       end;
       !error && it != end; it.increment(error)) {
    ++threads;
  }
  return threads;
}

}  // namespace trainer::tools::jitter
