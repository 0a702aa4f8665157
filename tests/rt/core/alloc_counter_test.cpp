// Tests for the allocation counter and its hooks (core::alloc, trainer::alloc_hooks): every
// heap entry point is counted on a counting thread, nothing is counted on other threads.
#include "trainer/core/alloc_counter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

namespace trainer::core {
namespace {

// Storing a pointer in a volatile global makes it escape, so the compiler cannot elide the
// allocation that produced it (new/delete and malloc/free pairs may otherwise be removed).
void* volatile g_escape = nullptr;
void escape(void* pointer) {
  g_escape = pointer;
}

// Counts allocations made by `body` on this thread while counting is on.
template <class Body>
std::uint64_t count_while_counting(Body body) {
  const std::uint64_t before = alloc::counted_allocations();
  alloc::begin_counting_this_thread();
  body();
  alloc::end_counting_this_thread();
  return alloc::counted_allocations() - before;
}

// Counts allocations made by `body` on this thread with counting off.
template <class Body>
std::uint64_t count_without_counting(Body body) {
  const std::uint64_t before = alloc::counted_allocations();
  body();
  return alloc::counted_allocations() - before;
}

void allocate_new_int() {
  int* value = new int(5);
  escape(value);
  delete value;
}

void grow_vector() {
  std::vector<int> values;
  for (int i = 0; i < 100; ++i) values.push_back(i);
  escape(values.data());
}

void build_long_string() {
  std::string text(200, 'x');  // far beyond any small-string buffer
  escape(text.data());
}

void call_malloc() {
  void* pointer = std::malloc(48);
  escape(pointer);
  std::free(pointer);
}

void call_calloc() {
  void* pointer = std::calloc(6, 8);
  escape(pointer);
  std::free(pointer);
}

void call_realloc() {
  // realloc(nullptr, n) allocates; growing an existing block may allocate again.
  void* pointer = std::realloc(nullptr, 16);
  escape(pointer);
  pointer = std::realloc(pointer, 4096);
  escape(pointer);
  std::free(pointer);
}

void call_aligned_alloc() {
  void* pointer = std::aligned_alloc(64, 128);
  escape(pointer);
  std::free(pointer);
}

void call_posix_memalign() {
  void* pointer = nullptr;
  if (posix_memalign(&pointer, 64, 100) == 0) escape(pointer);
  std::free(pointer);
}

TEST(AllocCounter, HooksAreLinkedIntoTheTestProgram) {
  EXPECT_TRUE(alloc::hooks_installed());
}

TEST(AllocCounter, OperatorNewIsCountedWhileCounting) {
  EXPECT_GE(count_while_counting(allocate_new_int), 1u);
  EXPECT_GE(count_while_counting(grow_vector), 1u);
  EXPECT_GE(count_while_counting(build_long_string), 1u);
  // Array and aligned forms go through their own replacement functions.
  EXPECT_GE(count_while_counting([] {
              int* values = new int[10]();
              escape(values);
              delete[] values;
            }),
            1u);
  struct alignas(128) Wide {
    float values[4];
  };
  EXPECT_GE(count_while_counting([] {
              Wide* wide = new Wide{};
              escape(wide);
              delete wide;
            }),
            1u);
}

TEST(AllocCounter, EachAllocationCountsOnce) {
  // 50 separate `new int` calls: exactly 50 counts. operator new forwards to glibc's own
  // entry point (or the sanitizer's malloc), never re-entering a counted function.
  const std::uint64_t counted = count_while_counting([] {
    for (int i = 0; i < 50; ++i) allocate_new_int();
  });
  EXPECT_EQ(counted, 50u);
}

TEST(AllocCounter, MallocFamilyIsCountedWhenHooked) {
  if (!alloc::malloc_family_counted()) {
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, only operator new is counted";
  }
  EXPECT_GE(count_while_counting(call_malloc), 1u);
  EXPECT_GE(count_while_counting(call_calloc), 1u);
  EXPECT_GE(count_while_counting(call_realloc), 1u);
  EXPECT_GE(count_while_counting(call_aligned_alloc), 1u);
  EXPECT_GE(count_while_counting(call_posix_memalign), 1u);
}

TEST(AllocCounter, NothingIsCountedWithoutBeginCounting) {
  EXPECT_EQ(count_without_counting(allocate_new_int), 0u);
  EXPECT_EQ(count_without_counting(grow_vector), 0u);
  EXPECT_EQ(count_without_counting(build_long_string), 0u);
  EXPECT_EQ(count_without_counting(call_malloc), 0u);
  EXPECT_EQ(count_without_counting(call_calloc), 0u);
  EXPECT_EQ(count_without_counting(call_realloc), 0u);
  EXPECT_EQ(count_without_counting(call_aligned_alloc), 0u);
  EXPECT_EQ(count_without_counting(call_posix_memalign), 0u);
}

TEST(AllocCounter, EndCountingStopsCounting) {
  alloc::begin_counting_this_thread();
  alloc::end_counting_this_thread();
  EXPECT_EQ(count_without_counting(allocate_new_int), 0u);
}

TEST(AllocCounter, InvalidPosixMemalignIsRefused) {
  if (!alloc::malloc_family_counted()) GTEST_SKIP() << "sanitizer build: malloc not replaced";
  void* pointer = nullptr;
  EXPECT_NE(posix_memalign(&pointer, 48, 64), 0);  // not a power of two
  EXPECT_NE(posix_memalign(&pointer, 2, 64), 0);   // smaller than a pointer
  EXPECT_EQ(pointer, nullptr);
}

// Another thread allocates while only this thread counts: none of its allocations show up.
// The helper thread is started, and told to go, without this thread allocating while counting.
TEST(AllocCounter, OtherThreadsAreNotCounted) {
  std::atomic<int> phase{0};  // 0: wait, 1: allocate, 2: done
  std::thread other([&phase] {
    while (phase.load(std::memory_order_acquire) != 1) std::this_thread::yield();
    for (int i = 0; i < 200; ++i) {
      allocate_new_int();
      call_malloc();
    }
    grow_vector();
    phase.store(2, std::memory_order_release);
  });

  const std::uint64_t counted = count_while_counting([&phase] {
    phase.store(1, std::memory_order_release);
    while (phase.load(std::memory_order_acquire) != 2) std::this_thread::yield();
  });
  other.join();
  EXPECT_EQ(counted, 0u);
}

// The converse: a counting helper thread's allocations are counted even though this thread
// does not count.
TEST(AllocCounter, ACountingThreadIsCountedFromAnyThread) {
  std::uint64_t counted_inside = 0;
  std::thread other([&counted_inside] {
    counted_inside = count_while_counting([] {
      for (int i = 0; i < 20; ++i) allocate_new_int();
    });
  });
  other.join();
  EXPECT_GE(counted_inside, 20u);
}

}  // namespace
}  // namespace trainer::core
