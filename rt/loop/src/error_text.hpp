// The text of an errno value, thread-safe (GNU strerror_r returns a pointer to the message,
// maybe not into the buffer). Private to rt/loop.
#pragma once

#include <cstring>
#include <string>

namespace trainer::loop::detail {

inline std::string error_text(int error_number) {
  char buffer[256];
  return strerror_r(error_number, buffer, sizeof buffer);
}

}  // namespace trainer::loop::detail
