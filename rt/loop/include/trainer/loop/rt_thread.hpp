// RtThread: a pthread started with an explicit stack size (and optional name), created on the
// setup path before the loop is armed so the stack exists and can be prefaulted by the thread
// itself (apply_rt_settings). Scheduling policy is not set here: the body applies its own RT
// settings on the thread, where they can be read back and reported.
#pragma once

#include <pthread.h>

#include <cstddef>
#include <functional>
#include <string_view>

#include "trainer/core/expected.hpp"

namespace trainer::loop {

// Movable, not copyable; the destructor and move assignment join a joinable thread (they
// block until its body returns, unlike std::thread which terminates).
class RtThread {
 public:
  static constexpr std::size_t kDefaultStackBytes = std::size_t{8} << 20;
  // pthread_setname_np limit: 15 characters plus the terminator.
  static constexpr std::size_t kMaxNameLength = 15;

  // Starts `body` on a new thread with a stack of `stack_bytes` (rounded up to whole pages;
  // at least PTHREAD_STACK_MIN). `name` (<= 15 characters, empty = inherit) shows in ps -L,
  // top and trace tools. The thread inherits the caller's signal mask. An exception escaping
  // `body` terminates the program. Fails with a message when the arguments are out of range
  // or the thread cannot be created.
  static core::Expected<RtThread> start(std::function<void()> body,
                                        std::size_t stack_bytes = kDefaultStackBytes,
                                        std::string_view name = {});

  RtThread() noexcept = default;  // no thread
  RtThread(RtThread&& other) noexcept;
  RtThread& operator=(RtThread&& other) noexcept;
  RtThread(const RtThread&) = delete;
  RtThread& operator=(const RtThread&) = delete;
  ~RtThread();

  // Waits for the body to return; no effect when not joinable.
  void join();
  bool joinable() const noexcept { return joinable_; }
  // The pthread handle (valid while joinable), e.g. for pthread_getschedparam.
  pthread_t native_handle() const noexcept { return handle_; }

 private:
  explicit RtThread(pthread_t handle) noexcept : handle_(handle), joinable_(true) {}

  pthread_t handle_{};
  bool joinable_ = false;
};

}  // namespace trainer::loop
