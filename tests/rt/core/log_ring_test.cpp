// Single-threaded tests for core::LogRing and format_log_record (the concurrent
// producer/consumer test is in log_ring_concurrency_test.cpp).
#include "trainer/core/log_ring.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <memory>
#include <string>

#include "trainer/core/alloc_counter.hpp"

namespace trainer::core {
namespace {

enum class Joint : std::uint8_t { pitch = 2, yaw = 3 };

LogRecord record_with(const char* format) {
  LogRecord record;
  record.format = format;
  return record;
}

TEST(LogLevel, Names) {
  EXPECT_STREQ(to_string(LogLevel::debug), "debug");
  EXPECT_STREQ(to_string(LogLevel::info), "info");
  EXPECT_STREQ(to_string(LogLevel::warning), "warning");
  EXPECT_STREQ(to_string(LogLevel::error), "error");
}

TEST(LogRing, EmptyRingPopsNothing) {
  auto ring = std::make_unique<LogRing>();
  LogRecord record;
  EXPECT_FALSE(ring->pop(record));
  EXPECT_EQ(ring->dropped(), 0u);
}

TEST(LogRing, WriteThenPopPreservesOrderAndFields) {
  auto ring = std::make_unique<LogRing>();
  ASSERT_TRUE(ring->write(100, LogLevel::info, "armed"));
  ASSERT_TRUE(ring->write(200, LogLevel::warning, "overrun {} ns", std::int64_t{1500}));
  ASSERT_TRUE(ring->write(300, LogLevel::error, "joint {} fault {}", 2u, "stuck encoder"));

  LogRecord record;
  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.time_ns, 100);
  EXPECT_EQ(record.level, LogLevel::info);
  EXPECT_STREQ(record.format, "armed");
  EXPECT_EQ(record.arg_count, 0);
  EXPECT_EQ(format_log_record(record), "armed");

  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.time_ns, 200);
  EXPECT_EQ(record.level, LogLevel::warning);
  ASSERT_EQ(record.arg_count, 1);
  EXPECT_EQ(record.args[0].kind, LogArg::Kind::signed_integer);
  EXPECT_EQ(record.args[0].i, 1500);
  EXPECT_EQ(format_log_record(record), "overrun 1500 ns");

  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.time_ns, 300);
  EXPECT_EQ(record.level, LogLevel::error);
  ASSERT_EQ(record.arg_count, 2);
  EXPECT_EQ(record.args[0].kind, LogArg::Kind::unsigned_integer);
  EXPECT_EQ(record.args[1].kind, LogArg::Kind::text);
  EXPECT_EQ(format_log_record(record), "joint 2 fault stuck encoder");

  EXPECT_FALSE(ring->pop(record));
}

TEST(LogRing, ArgumentKindsAreClassifiedAndFormatted) {
  auto ring = std::make_unique<LogRing>();
  char mutable_text[] = "mutable";
  ASSERT_TRUE(ring->write(0, LogLevel::debug, "{}|{}|{}|{}", -42,
                          std::uint64_t{18446744073709551615u}, 0.25f, Joint::yaw));
  ASSERT_TRUE(ring->write(0, LogLevel::debug, "{}|{}|{}|{}", std::int64_t{-9223372036854775807 - 1},
                          static_cast<std::int16_t>(-7), 1.5e-7, static_cast<char*>(mutable_text)));
  ASSERT_TRUE(ring->write(0, LogLevel::debug, "{} {}", true, static_cast<std::uint8_t>(200)));

  LogRecord record;
  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.args[0].kind, LogArg::Kind::signed_integer);
  EXPECT_EQ(record.args[1].kind, LogArg::Kind::unsigned_integer);
  EXPECT_EQ(record.args[2].kind, LogArg::Kind::floating);
  EXPECT_EQ(record.args[3].kind, LogArg::Kind::signed_integer);  // enums log their value
  EXPECT_EQ(format_log_record(record), "-42|18446744073709551615|0.25|3");

  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.args[2].kind, LogArg::Kind::floating);
  EXPECT_EQ(record.args[3].kind, LogArg::Kind::text);
  EXPECT_EQ(format_log_record(record), "-9223372036854775808|-7|1.5e-07|mutable");

  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(format_log_record(record), "1 200");
}

TEST(FormatLogRecord, EachKindDirectly) {
  LogRecord record = record_with("[{}] [{}] [{}] [{}]");
  record.arg_count = 4;
  record.args[0].kind = LogArg::Kind::floating;
  record.args[0].f = 1234567.0;  // %.6g switches to exponent form
  record.args[1].kind = LogArg::Kind::floating;
  record.args[1].f = -0.5;
  record.args[2].kind = LogArg::Kind::text;
  record.args[2].s = nullptr;
  record.args[3].kind = LogArg::Kind::unsigned_integer;
  record.args[3].u = 0;
  EXPECT_EQ(format_log_record(record), "[1.23457e+06] [-0.5] [(null)] [0]");
}

TEST(FormatLogRecord, MissingArgumentsAreMarked) {
  LogRecord record = record_with("a={} b={} c={}");
  record.arg_count = 1;
  record.args[0].kind = LogArg::Kind::signed_integer;
  record.args[0].i = 5;
  EXPECT_EQ(format_log_record(record), "a=5 b={?} c={?}");

  // Arguments beyond the placeholders are ignored rather than appended.
  LogRecord extra = record_with("only {}");
  extra.arg_count = 2;
  extra.args[0].kind = LogArg::Kind::unsigned_integer;
  extra.args[0].u = 1;
  extra.args[1].kind = LogArg::Kind::unsigned_integer;
  extra.args[1].u = 2;
  EXPECT_EQ(format_log_record(extra), "only 1");
}

TEST(FormatLogRecord, TextWithoutPlaceholdersAndUnpairedBraces) {
  EXPECT_EQ(format_log_record(record_with("plain text")), "plain text");
  EXPECT_EQ(format_log_record(record_with("")), "");
  EXPECT_EQ(format_log_record(record_with(nullptr)), "");
  EXPECT_EQ(format_log_record(record_with("{ } } {")), "{ } } {");
  EXPECT_EQ(format_log_record(record_with("trailing {")), "trailing {");
  EXPECT_EQ(format_log_record(record_with("{}{}")), "{?}{?}");
}

TEST(LogRing, FullRingDropsAndCountsWithoutBlocking) {
  auto ring = std::make_unique<LogRing>();
  for (std::size_t i = 0; i < LogRing::kCapacity; ++i) {
    ASSERT_TRUE(ring->write(static_cast<std::int64_t>(i), LogLevel::info, "record {}", i)) << i;
  }
  EXPECT_EQ(ring->dropped(), 0u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_FALSE(ring->write(-1, LogLevel::error, "dropped {}", i));
  }
  EXPECT_EQ(ring->dropped(), 10u);

  // The records that made it in are intact and in order; dropped ones never appear.
  LogRecord record;
  for (std::size_t i = 0; i < LogRing::kCapacity; ++i) {
    ASSERT_TRUE(ring->pop(record));
    EXPECT_EQ(record.time_ns, static_cast<std::int64_t>(i));
    EXPECT_EQ(record.args[0].u, i);
  }
  EXPECT_FALSE(ring->pop(record));

  // Space freed by the consumer is usable again; the drop count is cumulative.
  ASSERT_TRUE(ring->write(7, LogLevel::info, "again"));
  EXPECT_EQ(ring->dropped(), 10u);
  ASSERT_TRUE(ring->pop(record));
  EXPECT_EQ(record.time_ns, 7);
}

TEST(LogRing, WrapsAroundManyTimes) {
  auto ring = std::make_unique<LogRing>();
  LogRecord record;
  std::uint64_t next_expected = 0;
  std::uint64_t next_written = 0;
  for (int burst = 0; burst < 50; ++burst) {
    const int count = 1 + (burst * 37) % 700;
    for (int i = 0; i < count; ++i) {
      ASSERT_TRUE(ring->write(0, LogLevel::debug, "{}", next_written));
      ++next_written;
    }
    while (ring->pop(record)) {
      ASSERT_EQ(record.args[0].u, next_expected);
      ++next_expected;
    }
  }
  EXPECT_EQ(next_expected, next_written);
  EXPECT_EQ(ring->dropped(), 0u);
}

TEST(LogRing, WritingAndDroppingNeverAllocate) {
  auto ring = std::make_unique<LogRing>();
  const std::uint64_t before = alloc::counted_allocations();
  alloc::begin_counting_this_thread();
  bool all_accepted = true;
  for (std::size_t i = 0; i < LogRing::kCapacity; ++i) {
    all_accepted =
        ring->write(1, LogLevel::info, "{} {} {} {}", i, -1, 2.0, "text") && all_accepted;
  }
  const bool overflow_refused = !ring->write(2, LogLevel::error, "full");
  LogRecord record;
  const bool popped = ring->pop(record);
  alloc::end_counting_this_thread();
  EXPECT_TRUE(all_accepted);
  EXPECT_TRUE(overflow_refused);
  EXPECT_TRUE(popped);
  EXPECT_EQ(alloc::counted_allocations() - before, 0u);
}

}  // namespace
}  // namespace trainer::core
