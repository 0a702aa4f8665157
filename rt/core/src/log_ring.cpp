#include "trainer/core/log_ring.hpp"

#include <cstdio>

namespace trainer::core {

const char* to_string(LogLevel level) noexcept {
  switch (level) {
    case LogLevel::debug: return "debug";
    case LogLevel::info: return "info";
    case LogLevel::warning: return "warning";
    case LogLevel::error: return "error";
  }
  return "unknown";
}

namespace {
void append_arg(std::string& out, const LogArg& arg) {
  char buffer[64];
  switch (arg.kind) {
    case LogArg::Kind::none: return;
    case LogArg::Kind::signed_integer:
      std::snprintf(buffer, sizeof buffer, "%lld", static_cast<long long>(arg.i));
      break;
    case LogArg::Kind::unsigned_integer:
      std::snprintf(buffer, sizeof buffer, "%llu", static_cast<unsigned long long>(arg.u));
      break;
    case LogArg::Kind::floating: std::snprintf(buffer, sizeof buffer, "%.6g", arg.f); break;
    case LogArg::Kind::text: out += (arg.s != nullptr ? arg.s : "(null)"); return;
  }
  out += buffer;
}
}  // namespace

std::string format_log_record(const LogRecord& record) {
  std::string out;
  std::size_t next_arg = 0;
  const char* format = record.format != nullptr ? record.format : "";
  for (const char* p = format; *p != '\0'; ++p) {
    if (p[0] == '{' && p[1] == '}') {
      if (next_arg < record.arg_count) {
        append_arg(out, record.args[next_arg]);
      } else {
        out += "{?}";
      }
      ++next_arg;
      ++p;
    } else {
      out += *p;
    }
  }
  return out;
}

}  // namespace trainer::core
