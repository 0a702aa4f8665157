// Status codes for the real-time path: a trivially copyable value that RT functions return
// instead of throwing. The detail string must be a static literal (no ownership, no heap).
#pragma once

#include <cstdint>

namespace trainer::core {

enum class StatusCode : std::uint8_t {
  ok = 0,
  io_error,           // a transport failed (read/write/timeout)
  timeout,            // a reply did not come in time
  invalid_argument,   // caller passed something out of range
  capacity_exceeded,  // a fixed capacity would be exceeded
  not_ready,          // lifecycle state does not allow the call
  fault,              // a latched fault prevents the action
  numeric_error,      // non-finite or out-of-range number produced
};

const char* to_string(StatusCode code) noexcept;

class [[nodiscard]] Status {
 public:
  constexpr Status() noexcept = default;
  constexpr Status(StatusCode code, const char* detail) noexcept : code_(code), detail_(detail) {}

  static constexpr Status ok() noexcept { return {}; }
  constexpr bool is_ok() const noexcept { return code_ == StatusCode::ok; }
  constexpr explicit operator bool() const noexcept { return is_ok(); }
  constexpr StatusCode code() const noexcept { return code_; }
  // Static literal describing the failure; "" when ok.
  constexpr const char* detail() const noexcept { return detail_; }

 private:
  StatusCode code_ = StatusCode::ok;
  const char* detail_ = "";
};

}  // namespace trainer::core
