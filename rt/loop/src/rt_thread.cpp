// RtThread: pthread_create with an explicit stack size; the body is handed over on the heap
// (setup path) and freed by the new thread once it has run.
#include "trainer/loop/rt_thread.hpp"

#include "error_text.hpp"

#include <unistd.h>

#include <climits>
#include <cstring>
#include <memory>
#include <string>
#include <utility>

namespace trainer::loop {

namespace {

using detail::error_text;

void* run_body(void* argument) noexcept {
  const std::unique_ptr<std::function<void()>> body(static_cast<std::function<void()>*>(argument));
  (*body)();
  return nullptr;
}

}  // namespace

core::Expected<RtThread> RtThread::start(std::function<void()> body, std::size_t stack_bytes,
                                         std::string_view name) {
  if (!body) return core::make_error("RtThread::start: the thread body is empty");
  if (name.size() > kMaxNameLength) {
    return core::make_error("RtThread::start: thread name '" + std::string(name) + "' has " +
                            std::to_string(name.size()) + " characters: expected at most " +
                            std::to_string(kMaxNameLength));
  }
  const auto minimum_bytes = static_cast<std::size_t>(PTHREAD_STACK_MIN);
  if (stack_bytes < minimum_bytes) {
    return core::make_error("RtThread::start: stack of " + std::to_string(stack_bytes) +
                            " bytes: expected at least PTHREAD_STACK_MIN = " +
                            std::to_string(minimum_bytes) + " bytes");
  }
  const long page_size = sysconf(_SC_PAGESIZE);
  const std::size_t page_bytes = page_size > 0 ? static_cast<std::size_t>(page_size) : 4096;
  stack_bytes = (stack_bytes + page_bytes - 1) / page_bytes * page_bytes;

  pthread_attr_t attributes;
  int result = pthread_attr_init(&attributes);
  if (result != 0) {
    return core::make_error("RtThread::start: pthread_attr_init failed: " + error_text(result));
  }
  result = pthread_attr_setstacksize(&attributes, stack_bytes);
  if (result != 0) {
    pthread_attr_destroy(&attributes);
    return core::make_error("RtThread::start: pthread_attr_setstacksize(" +
                            std::to_string(stack_bytes) + " bytes) failed: " + error_text(result));
  }
  auto payload = std::make_unique<std::function<void()>>(std::move(body));
  pthread_t handle{};
  result = pthread_create(&handle, &attributes, run_body, payload.get());
  pthread_attr_destroy(&attributes);
  if (result != 0) {
    return core::make_error("RtThread::start: pthread_create with a " +
                            std::to_string(stack_bytes) +
                            "-byte stack failed: " + error_text(result) +
                            " (expected free memory for the stack and room under the "
                            "process's thread limit)");
  }
  static_cast<void>(payload.release());  // owned by run_body from here on
  RtThread thread(handle);
  if (!name.empty()) {
    const std::string terminated(name);
    // A failed rename is cosmetic (ERANGE is excluded above); the thread runs regardless.
    static_cast<void>(pthread_setname_np(handle, terminated.c_str()));
  }
  return thread;
}

RtThread::RtThread(RtThread&& other) noexcept
    : handle_(other.handle_), joinable_(std::exchange(other.joinable_, false)) {}

RtThread& RtThread::operator=(RtThread&& other) noexcept {
  if (this != &other) {
    join();
    handle_ = other.handle_;
    joinable_ = std::exchange(other.joinable_, false);
  }
  return *this;
}

RtThread::~RtThread() {
  join();
}

void RtThread::join() {
  if (!joinable_) return;
  pthread_join(handle_, nullptr);
  joinable_ = false;
}

}  // namespace trainer::loop
