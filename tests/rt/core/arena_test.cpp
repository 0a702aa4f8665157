// Tests for core::Arena: alignment (64 and larger), value initialisation, accounting,
// exhaustion and sealing errors, move semantics, and refusal of impossible sizes.
#include "trainer/core/arena.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <string>
#include <utility>

namespace trainer::core {
namespace {

bool is_aligned(const void* pointer, std::size_t alignment) {
  return reinterpret_cast<std::uintptr_t>(pointer) % alignment == 0;
}

struct WithDefaults {
  int count = 7;
  float gain = 2.5f;
  std::uint8_t flag = 1;
};

struct alignas(128) Aligned128 {
  float value;
};

struct alignas(4096) PageAligned {
  std::uint8_t bytes[16];
};

TEST(Arena, ZeroCapacityIsAnError) {
  auto arena = Arena::create(0);
  ASSERT_FALSE(arena);
  EXPECT_NE(arena.error().message.find("capacity"), std::string::npos) << arena.error().message;
}

TEST(Arena, CapacityIsRoundedUpToTheAlignment) {
  auto arena = Arena::create(100);
  ASSERT_TRUE(arena) << arena.error().message;
  EXPECT_EQ(arena->capacity_bytes(), 128u);
  EXPECT_EQ(arena->used_bytes(), 0u);
  EXPECT_FALSE(arena->sealed());
}

TEST(Arena, ImpossibleCapacityIsAnErrorNotAnEmptyArena) {
  // Rounding SIZE_MAX - 10 up to 64 wraps around; the request can never be satisfied and must
  // be refused rather than yield an arena whose capacity differs from what was asked.
  auto arena = Arena::create(std::numeric_limits<std::size_t>::max() - 10);
  ASSERT_FALSE(arena) << "got an arena of capacity " << arena->capacity_bytes();
}

TEST(Arena, ArraysAreAlignedToTheCacheLineAndUsedBytesGrow) {
  auto arena = Arena::create(4096);
  ASSERT_TRUE(arena) << arena.error().message;
  std::size_t previous_used = 0;
  for (std::size_t count : {1u, 3u, 17u, 5u}) {
    auto bytes = arena->allocate_array<std::uint8_t>(count, "odd-sized bytes");
    ASSERT_TRUE(bytes) << bytes.error().message;
    EXPECT_EQ(bytes->size(), count);
    EXPECT_TRUE(is_aligned(bytes->data(), Arena::kAlignment));
    EXPECT_GE(arena->used_bytes(), previous_used + count);
    EXPECT_LE(arena->used_bytes(), arena->capacity_bytes());
    previous_used = arena->used_bytes();
  }
  auto floats = arena->allocate_array<float>(10, "floats");
  ASSERT_TRUE(floats) << floats.error().message;
  EXPECT_TRUE(is_aligned(floats->data(), Arena::kAlignment));
  EXPECT_GE(arena->used_bytes(), previous_used + 10 * sizeof(float));
}

TEST(Arena, SpansDoNotOverlap) {
  auto arena = Arena::create(1024);
  ASSERT_TRUE(arena) << arena.error().message;
  auto first = arena->allocate_array<std::uint32_t>(20, "first");
  auto second = arena->allocate_array<std::uint32_t>(20, "second");
  ASSERT_TRUE(first && second);
  for (auto& value : *first) value = 0xAAAAAAAAu;
  for (auto& value : *second) value = 0x55555555u;
  for (auto value : *first) EXPECT_EQ(value, 0xAAAAAAAAu);
  EXPECT_GE(reinterpret_cast<std::uintptr_t>(second->data()),
            reinterpret_cast<std::uintptr_t>(first->data() + first->size()));
}

TEST(Arena, AlignsToTypesStricterThanTheCacheLine) {
  // Several arenas, each with a byte already taken, so the next offset is never a multiple of
  // the stricter alignment by accident of the block's own address.
  for (std::size_t capacity : {20000u, 65536u, 300000u, 1048576u}) {
    SCOPED_TRACE("capacity " + std::to_string(capacity));
    auto arena = Arena::create(capacity);
    ASSERT_TRUE(arena) << arena.error().message;
    ASSERT_TRUE(arena->allocate_array<std::uint8_t>(1, "padding"));

    auto wide = arena->allocate_array<Aligned128>(2, "128-aligned");
    ASSERT_TRUE(wide) << wide.error().message;
    EXPECT_TRUE(is_aligned(wide->data(), alignof(Aligned128)))
        << "address " << static_cast<const void*>(wide->data());

    auto page = arena->create_object<PageAligned>("page-aligned object");
    ASSERT_TRUE(page) << page.error().message;
    EXPECT_TRUE(is_aligned(*page, alignof(PageAligned)))
        << "address " << static_cast<const void*>(*page);

    auto raw = arena->allocate_bytes(8, 4096, "raw page-aligned bytes");
    ASSERT_TRUE(raw) << raw.error().message;
    EXPECT_TRUE(is_aligned(*raw, 4096)) << "address " << *raw;
  }
}

TEST(Arena, ArraysAndObjectsAreValueInitialised) {
  auto arena = Arena::create(4096);
  ASSERT_TRUE(arena) << arena.error().message;
  auto records = arena->allocate_array<WithDefaults>(5, "records");
  ASSERT_TRUE(records) << records.error().message;
  for (const WithDefaults& record : *records) {
    EXPECT_EQ(record.count, 7);
    EXPECT_EQ(record.gain, 2.5f);
    EXPECT_EQ(record.flag, 1);
  }
  auto numbers = arena->allocate_array<double>(16, "numbers");
  ASSERT_TRUE(numbers);
  for (double value : *numbers) EXPECT_EQ(value, 0.0);

  auto object = arena->create_object<WithDefaults>("object with arguments", 3, 0.5f);
  ASSERT_TRUE(object) << object.error().message;
  EXPECT_EQ((*object)->count, 3);
  EXPECT_EQ((*object)->gain, 0.5f);
  EXPECT_EQ((*object)->flag, 1);
  EXPECT_TRUE(is_aligned(*object, Arena::kAlignment));
}

TEST(Arena, ExhaustionNamesTheRequestTheBytesAndHowToRaiseIt) {
  auto arena = Arena::create(256);
  ASSERT_TRUE(arena) << arena.error().message;
  ASSERT_TRUE(arena->allocate_array<std::uint8_t>(100, "first block"));
  const std::size_t used_before = arena->used_bytes();

  // The next request starts at offset 128, so 128 of 256 bytes remain.
  auto too_big = arena->allocate_array<std::uint8_t>(200, "duct mode matrix");
  ASSERT_FALSE(too_big);
  const std::string& message = too_big.error().message;
  EXPECT_NE(message.find("duct mode matrix"), std::string::npos) << message;
  EXPECT_NE(message.find("200"), std::string::npos) << message;  // requested bytes
  EXPECT_NE(message.find("128"), std::string::npos) << message;  // bytes remaining
  EXPECT_NE(message.find("256"), std::string::npos) << message;  // capacity
  EXPECT_NE(message.find("raise"), std::string::npos) << message;
  EXPECT_NE(message.find("arena_kib"), std::string::npos) << message;
  EXPECT_EQ(arena->used_bytes(), used_before);  // a failed request takes nothing

  // What still fits is still handed out, up to the last byte.
  auto fits = arena->allocate_array<std::uint8_t>(128, "remaining");
  ASSERT_TRUE(fits) << fits.error().message;
  EXPECT_EQ(arena->used_bytes(), arena->capacity_bytes());
}

TEST(Arena, ExactlyFullThenOneMoreByteFails) {
  auto arena = Arena::create(128);
  ASSERT_TRUE(arena);
  ASSERT_TRUE(arena->allocate_array<std::uint8_t>(128, "all of it"));
  EXPECT_EQ(arena->used_bytes(), arena->capacity_bytes());
  EXPECT_FALSE(arena->allocate_array<std::uint8_t>(1, "one more"));
}

// count * sizeof(T) wraps around to 24 bytes; the arena must refuse the request with an Error
// naming it (setup path: no exception may escape) and take nothing. Run in a child process:
// a wrapped size makes the value-initialisation write far past the block (a crash, heap
// corruption or std::bad_array_new_length depending on the build), which must not take the
// other tests down with it.
TEST(ArenaDeathTest, ArrayByteCountOverflowIsRefusedWithAnError) {
  EXPECT_EXIT(
      {
        auto arena = Arena::create(4096);
        // Read through a volatile so the compiler cannot see the constant and fold the loop.
        volatile std::size_t opaque_count =
            std::numeric_limits<std::size_t>::max() / sizeof(std::uint64_t) + 4;
        int exit_code = 3;
        try {
          auto result = arena->allocate_array<std::uint64_t>(opaque_count, "overflowing array");
          if (result) {
            std::fprintf(stderr, "accepted: span of %zu elements\n", result->size());
            exit_code = 1;
          } else if (result.error().message.find("overflowing array") == std::string::npos ||
                     arena->used_bytes() != 0) {
            std::fprintf(stderr, "refused, but message '%s', used_bytes %zu\n",
                         result.error().message.c_str(), arena->used_bytes());
            exit_code = 2;
          } else {
            std::fprintf(stderr, "refused\n");
            exit_code = 0;
          }
        } catch (const std::exception& exception) {
          std::fprintf(stderr, "threw %s\n", exception.what());
        }
        std::_Exit(exit_code);
      },
      ::testing::ExitedWithCode(0), "refused");
}

TEST(Arena, NonPowerOfTwoAlignmentIsRefused) {
  auto arena = Arena::create(256);
  ASSERT_TRUE(arena);
  auto result = arena->allocate_bytes(8, 48, "odd alignment");
  ASSERT_FALSE(result);
  EXPECT_NE(result.error().message.find("odd alignment"), std::string::npos);
  EXPECT_FALSE(arena->allocate_bytes(8, 0, "zero alignment"));
  EXPECT_EQ(arena->used_bytes(), 0u);
}

TEST(Arena, SealRefusesEveryRequestAndCountsThem) {
  auto arena = Arena::create(1024);
  ASSERT_TRUE(arena);
  auto before_seal = arena->allocate_array<float>(4, "before seal");
  ASSERT_TRUE(before_seal);
  const std::size_t used = arena->used_bytes();

  arena->seal();
  EXPECT_TRUE(arena->sealed());
  EXPECT_EQ(arena->refused_after_seal(), 0u);

  auto array = arena->allocate_array<float>(1, "late array");
  ASSERT_FALSE(array);
  EXPECT_NE(array.error().message.find("late array"), std::string::npos) << array.error().message;
  EXPECT_NE(array.error().message.find("sealed"), std::string::npos) << array.error().message;
  EXPECT_FALSE(arena->create_object<WithDefaults>("late object"));
  EXPECT_FALSE(arena->allocate_bytes(1, 64, "late bytes"));
  EXPECT_EQ(arena->refused_after_seal(), 3u);
  EXPECT_EQ(arena->used_bytes(), used);

  // Memory handed out before sealing stays usable.
  (*before_seal)[3] = 1.25f;
  EXPECT_EQ((*before_seal)[3], 1.25f);
}

TEST(Arena, MoveConstructionTransfersTheBlock) {
  auto created = Arena::create(512);
  ASSERT_TRUE(created);
  Arena& source = *created;
  auto first = source.allocate_array<int>(4, "first");
  ASSERT_TRUE(first);
  (*first)[0] = 42;
  const std::size_t used = source.used_bytes();

  Arena moved(std::move(source));
  EXPECT_EQ(moved.capacity_bytes(), 512u);
  EXPECT_EQ(moved.used_bytes(), used);
  EXPECT_EQ((*first)[0], 42);  // spans stay valid: the block itself did not move
  auto second = moved.allocate_array<int>(4, "second");
  ASSERT_TRUE(second);
  EXPECT_GE(reinterpret_cast<std::uintptr_t>(second->data()),
            reinterpret_cast<std::uintptr_t>(first->data() + first->size()));

  EXPECT_EQ(source.capacity_bytes(), 0u);  // NOLINT(bugprone-use-after-move): defined state
  EXPECT_EQ(source.used_bytes(), 0u);
  EXPECT_FALSE(source.allocate_array<int>(1, "from moved-from arena"));
}

TEST(Arena, MoveAssignmentTransfersTheBlockAndKeepsSealState) {
  auto a = Arena::create(256);
  auto b = Arena::create(1024);
  ASSERT_TRUE(a && b);
  ASSERT_TRUE(b->allocate_array<std::uint8_t>(100, "payload"));
  const std::size_t used = b->used_bytes();
  b->seal();
  EXPECT_FALSE(b->allocate_bytes(1, 64, "refused"));

  *a = std::move(*b);
  EXPECT_EQ(a->capacity_bytes(), 1024u);
  EXPECT_EQ(a->used_bytes(), used);
  EXPECT_TRUE(a->sealed());
  EXPECT_EQ(a->refused_after_seal(), 1u);
  EXPECT_EQ(b->capacity_bytes(), 0u);  // NOLINT(bugprone-use-after-move)

  // Self-move leaves the arena intact.
  Arena& self = *a;
  *a = std::move(self);
  EXPECT_EQ(a->capacity_bytes(), 1024u);
}

}  // namespace
}  // namespace trainer::core
