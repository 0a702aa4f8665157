// Tests for core::Expected (setup-path results) and core::Status (RT-path results).
#include <gtest/gtest.h>

#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>

#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"

namespace trainer::core {
namespace {

Expected<int> parse_period_us(int value) {
  if (value < 50) {
    return make_error("loop.period_us = " + std::to_string(value) + ": expected >= 50");
  }
  return value;
}

Expected<void> check_positive(int value) {
  if (value <= 0) return make_error("value must be positive");
  return {};
}

TEST(Expected, HoldsAValue) {
  auto result = parse_period_us(1000);
  ASSERT_TRUE(result.has_value());
  EXPECT_TRUE(static_cast<bool>(result));
  EXPECT_EQ(result.value(), 1000);
  EXPECT_EQ(*result, 1000);
  *result = 500;
  EXPECT_EQ(result.value(), 500);
}

TEST(Expected, HoldsAnErrorWithItsMessage) {
  auto result = parse_period_us(5);
  ASSERT_FALSE(result.has_value());
  EXPECT_FALSE(static_cast<bool>(result));
  EXPECT_EQ(result.error().message, "loop.period_us = 5: expected >= 50");
}

TEST(Expected, ArrowReachesMembersAndRvalueValueMovesOut) {
  Expected<std::string> text(std::string("catheter"));
  EXPECT_EQ(text->size(), 8u);
  std::string taken = std::move(text).value();
  EXPECT_EQ(taken, "catheter");

  Expected<std::unique_ptr<int>> owner(std::make_unique<int>(3));
  ASSERT_TRUE(owner);
  std::unique_ptr<int> pointer = std::move(owner).value();
  ASSERT_NE(pointer, nullptr);
  EXPECT_EQ(*pointer, 3);

  const Expected<std::string> constant(std::string("duct"));
  EXPECT_EQ(constant->front(), 'd');
  EXPECT_EQ(*constant, "duct");
}

TEST(Expected, ErrorCanBeMovedOutAndForwarded) {
  auto failed = parse_period_us(1);
  Error error = std::move(failed).error();
  EXPECT_NE(error.message.find("period_us"), std::string::npos);

  // Forwarding an error to a result of another type (the pattern used across the setup path).
  auto forward = [](int value) -> Expected<double> {
    auto inner = parse_period_us(value);
    if (!inner) return std::move(inner).error();
    return inner.value() * 1e-6;
  };
  auto forwarded = forward(10);
  ASSERT_FALSE(forwarded);
  EXPECT_EQ(forwarded.error().message, "loop.period_us = 10: expected >= 50");
  auto converted = forward(2000);
  ASSERT_TRUE(converted);
  EXPECT_DOUBLE_EQ(*converted, 0.002);
}

TEST(Expected, VoidSpecialisation) {
  Expected<void> fine = check_positive(3);
  EXPECT_TRUE(fine.has_value());
  EXPECT_TRUE(static_cast<bool>(fine));

  Expected<void> failed = check_positive(0);
  ASSERT_FALSE(failed.has_value());
  EXPECT_EQ(failed.error().message, "value must be positive");
  Error moved = std::move(failed).error();
  EXPECT_EQ(moved.message, "value must be positive");
}

TEST(Expected, MakeErrorKeepsTheMessage) {
  const Error error = make_error("config/scenes/wall.toml:12: bad key");
  EXPECT_EQ(error.message, "config/scenes/wall.toml:12: bad key");
}

TEST(Status, DefaultIsOkWithEmptyDetail) {
  constexpr Status status;
  static_assert(status.is_ok());
  static_assert(Status::ok().code() == StatusCode::ok);
  EXPECT_TRUE(status.is_ok());
  EXPECT_TRUE(static_cast<bool>(status));
  EXPECT_EQ(status.code(), StatusCode::ok);
  ASSERT_NE(status.detail(), nullptr);
  EXPECT_STREQ(status.detail(), "");
}

TEST(Status, FailureCarriesCodeAndStaticDetail) {
  constexpr Status status(StatusCode::timeout, "drive reply late");
  static_assert(!status.is_ok());
  EXPECT_FALSE(static_cast<bool>(status));
  EXPECT_EQ(status.code(), StatusCode::timeout);
  EXPECT_STREQ(status.detail(), "drive reply late");
}

TEST(Status, IsTriviallyCopyableAndSmall) {
  // Returned by value every cycle: must stay a plain value type.
  static_assert(std::is_trivially_copyable_v<Status>);
  static_assert(std::is_nothrow_copy_constructible_v<Status>);
  EXPECT_LE(sizeof(Status), 2 * sizeof(void*));
}

TEST(Status, EveryCodeHasADistinctName) {
  const StatusCode codes[] = {StatusCode::ok,
                              StatusCode::io_error,
                              StatusCode::timeout,
                              StatusCode::invalid_argument,
                              StatusCode::capacity_exceeded,
                              StatusCode::not_ready,
                              StatusCode::fault,
                              StatusCode::numeric_error};
  const char* expected[] = {
      "ok",        "io_error", "timeout",      "invalid_argument", "capacity_exceeded",
      "not_ready", "fault",    "numeric_error"};
  for (std::size_t i = 0; i < std::size(codes); ++i) {
    EXPECT_STREQ(to_string(codes[i]), expected[i]);
  }
  EXPECT_STREQ(to_string(static_cast<StatusCode>(200)), "unknown");
}

}  // namespace
}  // namespace trainer::core
