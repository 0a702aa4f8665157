#include "trainer/core/status.hpp"

namespace trainer::core {

const char* to_string(StatusCode code) noexcept {
  switch (code) {
    case StatusCode::ok: return "ok";
    case StatusCode::io_error: return "io_error";
    case StatusCode::timeout: return "timeout";
    case StatusCode::invalid_argument: return "invalid_argument";
    case StatusCode::capacity_exceeded: return "capacity_exceeded";
    case StatusCode::not_ready: return "not_ready";
    case StatusCode::fault: return "fault";
    case StatusCode::numeric_error: return "numeric_error";
  }
  return "unknown";
}

}  // namespace trainer::core
