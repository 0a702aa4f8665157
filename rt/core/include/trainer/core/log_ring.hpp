// Lock-free log ring: the RT thread records a static format string and up to four numeric
// arguments (no formatting, no heap); a non-RT thread drains and formats them. The ring is
// single-producer / single-consumer. When it is full a record is dropped and counted, never
// blocked on. Faults are latched in the safety state, not only logged, so a dropped record
// never loses a fault.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>

namespace trainer::core {

enum class LogLevel : std::uint8_t { debug, info, warning, error };
const char* to_string(LogLevel level) noexcept;

struct LogArg {
  enum class Kind : std::uint8_t { none, signed_integer, unsigned_integer, floating, text };
  Kind kind = Kind::none;
  union {
    std::int64_t i;
    std::uint64_t u;
    double f;
    const char* s;  // must be a static literal
  };
  LogArg() noexcept : i(0) {}
};

struct LogRecord {
  std::int64_t time_ns = 0;
  const char* format = "";  // static literal with "{}" placeholders
  LogLevel level = LogLevel::info;
  std::uint8_t arg_count = 0;
  LogArg args[4];
};

// Formats a record's "{}" placeholders with its arguments (non-RT: returns a std::string).
std::string format_log_record(const LogRecord& record);

class LogRing {
 public:
  static constexpr std::size_t kCapacity = 1024;  // power of two
  static_assert((kCapacity & (kCapacity - 1)) == 0);

  template <class... Args>
  bool write(std::int64_t time_ns, LogLevel level, const char* format, Args... args) noexcept {
    static_assert(sizeof...(Args) <= 4, "at most four log arguments");
    LogRecord record;
    record.time_ns = time_ns;
    record.level = level;
    record.format = format;
    record.arg_count = static_cast<std::uint8_t>(sizeof...(Args));
    std::size_t index = 0;
    (set_arg(record.args[index++], args), ...);
    return push(record);
  }

  bool push(const LogRecord& record) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    if (head - tail == kCapacity) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    records_[head & (kCapacity - 1)] = record;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  // Consumer side: pops one record; false when empty.
  bool pop(LogRecord& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t head = head_.load(std::memory_order_acquire);
    if (tail == head) return false;
    out = records_[tail & (kCapacity - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  template <class A>
  static void set_arg(LogArg& arg, A value) noexcept {
    if constexpr (std::is_same_v<A, const char*> || std::is_same_v<A, char*>) {
      arg.kind = LogArg::Kind::text;
      arg.s = value;
    } else if constexpr (std::is_floating_point_v<A>) {
      arg.kind = LogArg::Kind::floating;
      arg.f = static_cast<double>(value);
    } else if constexpr (std::is_enum_v<A>) {
      arg.kind = LogArg::Kind::signed_integer;
      arg.i = static_cast<std::int64_t>(value);
    } else if constexpr (std::is_signed_v<A>) {
      arg.kind = LogArg::Kind::signed_integer;
      arg.i = static_cast<std::int64_t>(value);
    } else {
      static_assert(std::is_unsigned_v<A>, "log arguments: numbers, enums or static strings");
      arg.kind = LogArg::Kind::unsigned_integer;
      arg.u = static_cast<std::uint64_t>(value);
    }
  }

  LogRecord records_[kCapacity];
  alignas(64) std::atomic<std::size_t> head_{0};  // written by the producer
  alignas(64) std::atomic<std::size_t> tail_{0};  // written by the consumer
  alignas(64) std::atomic<std::uint64_t> dropped_{0};  // producer-only writes: own line
};

}  // namespace trainer::core
