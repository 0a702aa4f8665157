// LatestValue (the triple buffer between the libusb event thread and the RT thread): a
// consumer never sees a torn value or an older one than it saw before, the newest value always
// arrives, and overwritten values are reported. Run under TSan (ctest --preset tsan).
#include "trainer/hal_libusb/latest_value.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

namespace trainer::hal::libusb {
namespace {

struct Payload {
  std::uint64_t stamp = 0;
  std::array<std::uint64_t, 15> copies{};  // all equal to stamp when not torn
};

TEST(LatestValue, SingleThreadTakesNewestAndReportsOverwrites) {
  LatestValue<int> value;
  EXPECT_FALSE(value.take());
  value.back() = 1;
  EXPECT_FALSE(value.publish());
  value.back() = 2;
  EXPECT_TRUE(value.publish());  // 1 was never taken
  ASSERT_TRUE(value.take());
  EXPECT_EQ(value.front(), 2);
  EXPECT_FALSE(value.take());    // nothing newer
  EXPECT_EQ(value.front(), 2);   // front stays
  value.back() = 3;
  EXPECT_FALSE(value.publish());
  ASSERT_TRUE(value.take());
  EXPECT_EQ(value.front(), 3);
}

TEST(LatestValue, ConcurrentProducerConsumerNeverTornNeverOlder) {
  LatestValue<Payload> value;
  constexpr std::uint64_t kValues = 200'000;
  std::atomic<bool> done{false};
  std::uint64_t overwritten = 0;
  std::thread producer([&] {
    for (std::uint64_t i = 1; i <= kValues; ++i) {
      Payload& slot = value.back();
      slot.stamp = i;
      slot.copies.fill(i);
      if (value.publish()) ++overwritten;
    }
    done.store(true, std::memory_order_release);
  });
  std::uint64_t last = 0;
  std::uint64_t taken = 0;
  bool torn = false;
  bool backwards = false;
  for (;;) {
    const bool finished = done.load(std::memory_order_acquire);
    while (value.take()) {
      const Payload& p = value.front();
      for (std::uint64_t copy : p.copies) torn = torn || copy != p.stamp;
      backwards = backwards || p.stamp <= last;
      last = p.stamp;
      ++taken;
    }
    if (finished) break;
  }
  producer.join();
  EXPECT_FALSE(torn);
  EXPECT_FALSE(backwards);
  EXPECT_EQ(last, kValues);  // the newest value always arrives
  EXPECT_EQ(taken + overwritten, kValues);
}

}  // namespace
}  // namespace trainer::hal::libusb
