// Tests for core::FixedVector / FixedVectorRef: capacity limits, element operations, copies
// that own their storage, capacity-free references, and no heap use.
#include "trainer/core/fixed_vector.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <cstdint>

#include "trainer/core/alloc_counter.hpp"

namespace trainer::core {
namespace {

struct Sample {
  int id = -1;
  float force_n = 0.0f;
};

// Takes the capacity-free base, so one non-template function serves every N.
int fill_with_sequence(FixedVectorRef<int>& vector, int first) {
  int pushed = 0;
  while (vector.push_back(first + pushed)) ++pushed;
  return pushed;
}

int sum(const FixedVectorRef<int>& vector) {
  int total = 0;
  for (int value : vector) total += value;
  return total;
}

TEST(FixedVector, StartsEmptyWithItsCapacity) {
  FixedVector<int, 5> vector;
  EXPECT_TRUE(vector.empty());
  EXPECT_FALSE(vector.full());
  EXPECT_EQ(vector.size(), 0u);
  EXPECT_EQ(vector.capacity(), 5u);
  EXPECT_EQ((FixedVector<int, 5>::kCapacity), 5u);
  EXPECT_EQ(vector.begin(), vector.end());
  EXPECT_TRUE(vector.span().empty());
}

TEST(FixedVector, PushToCapacityThenRefusesAndKeepsContents) {
  FixedVector<int, 4> vector;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(vector.push_back(10 * i)) << "push " << i;
    EXPECT_EQ(vector.size(), static_cast<std::size_t>(i + 1));
  }
  EXPECT_TRUE(vector.full());
  EXPECT_FALSE(vector.push_back(99));
  EXPECT_FALSE(vector.emplace_back(98));
  EXPECT_EQ(vector.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) EXPECT_EQ(vector[i], static_cast<int>(10 * i));
  EXPECT_EQ(vector.back(), 30);
}

TEST(FixedVector, EmplaceBackConstructsFromArguments) {
  FixedVector<Sample, 2> samples;
  ASSERT_TRUE(samples.emplace_back(7, 1.5f));
  ASSERT_TRUE(samples.emplace_back());
  EXPECT_FALSE(samples.emplace_back(9, 2.0f));
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_EQ(samples[0].id, 7);
  EXPECT_EQ(samples[0].force_n, 1.5f);
  EXPECT_EQ(samples[1].id, -1);  // default member initialiser
  EXPECT_EQ(samples[1].force_n, 0.0f);
}

TEST(FixedVector, PopBackRemovesLastAndIsHarmlessWhenEmpty) {
  FixedVector<int, 3> vector;
  ASSERT_TRUE(vector.push_back(1));
  ASSERT_TRUE(vector.push_back(2));
  vector.pop_back();
  EXPECT_EQ(vector.size(), 1u);
  EXPECT_EQ(vector.back(), 1);
  vector.pop_back();
  EXPECT_TRUE(vector.empty());
  vector.pop_back();  // empty: must not underflow the size
  EXPECT_TRUE(vector.empty());
  EXPECT_EQ(vector.size(), 0u);
  // Capacity is fully usable again after popping.
  EXPECT_EQ(fill_with_sequence(vector, 0), 3);
}

TEST(FixedVector, ResizeGrowsWithDefaultsShrinksAndRefusesBeyondCapacity) {
  FixedVector<Sample, 4> samples;
  ASSERT_TRUE(samples.push_back(Sample{1, 1.0f}));
  ASSERT_TRUE(samples.resize(3));
  ASSERT_EQ(samples.size(), 3u);
  EXPECT_EQ(samples[0].id, 1);
  EXPECT_EQ(samples[1].id, -1);
  EXPECT_EQ(samples[2].id, -1);

  EXPECT_FALSE(samples.resize(5));
  EXPECT_EQ(samples.size(), 3u);  // unchanged on failure
  EXPECT_EQ(samples[0].id, 1);

  ASSERT_TRUE(samples.resize(1));
  EXPECT_EQ(samples.size(), 1u);
  EXPECT_EQ(samples[0].id, 1);

  // Growing again must default-construct, not resurrect what was there before the shrink.
  samples[0].id = 5;
  ASSERT_TRUE(samples.push_back(Sample{2, 2.0f}));
  ASSERT_TRUE(samples.resize(1));
  ASSERT_TRUE(samples.resize(2));
  EXPECT_EQ(samples[1].id, -1);
  EXPECT_EQ(samples[1].force_n, 0.0f);

  ASSERT_TRUE(samples.resize(4));
  EXPECT_TRUE(samples.full());
  ASSERT_TRUE(samples.resize(0));
  EXPECT_TRUE(samples.empty());
}

TEST(FixedVector, ClearEmptiesAndIterationCoversSize) {
  FixedVector<int, 8> vector;
  EXPECT_EQ(fill_with_sequence(vector, 1), 8);
  EXPECT_EQ(sum(vector), 36);
  EXPECT_EQ(vector.end() - vector.begin(), 8);
  EXPECT_EQ(vector.span().size(), 8u);
  EXPECT_EQ(vector.span().data(), vector.data());
  vector.clear();
  EXPECT_TRUE(vector.empty());
  EXPECT_EQ(sum(vector), 0);
}

TEST(FixedVector, CopyConstructionOwnsSeparateStorage) {
  FixedVector<int, 4> original;
  ASSERT_TRUE(original.push_back(1));
  ASSERT_TRUE(original.push_back(2));

  FixedVector<int, 4> copy(original);
  ASSERT_EQ(copy.size(), 2u);
  EXPECT_EQ(copy.capacity(), 4u);
  EXPECT_NE(copy.data(), original.data());
  EXPECT_EQ(copy[0], 1);
  EXPECT_EQ(copy[1], 2);

  copy[0] = 100;
  ASSERT_TRUE(copy.push_back(3));
  EXPECT_EQ(original[0], 1);
  EXPECT_EQ(original.size(), 2u);
  EXPECT_EQ(copy.size(), 3u);

  original[1] = 200;
  EXPECT_EQ(copy[1], 2);
}

TEST(FixedVector, CopyAssignmentOwnsSeparateStorage) {
  FixedVector<int, 4> original;
  ASSERT_TRUE(original.push_back(5));
  ASSERT_TRUE(original.push_back(6));
  FixedVector<int, 4> target;
  ASSERT_TRUE(target.push_back(9));
  ASSERT_TRUE(target.push_back(9));
  ASSERT_TRUE(target.push_back(9));
  int* const target_storage = target.data();

  target = original;
  EXPECT_EQ(target.data(), target_storage);  // still its own inline storage
  ASSERT_EQ(target.size(), 2u);              // shrinks to the source's size
  EXPECT_EQ(target[0], 5);
  EXPECT_EQ(target[1], 6);

  target[0] = 50;
  EXPECT_EQ(original[0], 5);

  // Self-assignment keeps the contents.
  FixedVector<int, 4>& alias = target;
  target = alias;
  ASSERT_EQ(target.size(), 2u);
  EXPECT_EQ(target[0], 50);
}

TEST(FixedVector, MovedVectorIsAnIndependentCopy) {
  FixedVector<int, 3> original;
  ASSERT_TRUE(original.push_back(4));
  FixedVector<int, 3> moved(std::move(original));
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0], 4);
  EXPECT_NE(moved.data(), original.data());  // NOLINT(bugprone-use-after-move): copy semantics
}

TEST(FixedVector, CopiesInsideAContainerStayValidAfterTheContainerIsCopied) {
  // A struct of vectors copied as a whole (what a snapshot does): every member must point at
  // its own copy's storage, or a later write through the copy would corrupt the original.
  struct Holder {
    FixedVector<int, 2> first;
    FixedVector<int, 3> second;
  };
  Holder original;
  ASSERT_TRUE(original.first.push_back(1));
  ASSERT_TRUE(original.second.push_back(2));
  Holder copy = original;
  copy.first[0] = 10;
  copy.second[0] = 20;
  EXPECT_EQ(original.first[0], 1);
  EXPECT_EQ(original.second[0], 2);
  EXPECT_EQ(copy.first.data(), &copy.first[0]);
  EXPECT_NE(copy.first.data(), original.first.data());
  EXPECT_NE(copy.second.data(), original.second.data());
}

TEST(FixedVectorRef, OneFunctionServesDifferentCapacities) {
  FixedVector<int, 2> small;
  FixedVector<int, 7> large;
  EXPECT_EQ(fill_with_sequence(small, 1), 2);
  EXPECT_EQ(fill_with_sequence(large, 1), 7);
  EXPECT_EQ(sum(small), 3);
  EXPECT_EQ(sum(large), 28);

  FixedVectorRef<int>& reference = large;
  EXPECT_EQ(reference.capacity(), 7u);
  EXPECT_TRUE(reference.full());
  reference.pop_back();
  EXPECT_EQ(large.size(), 6u);  // the reference views the same vector
  ASSERT_TRUE(reference.push_back(-7));
  EXPECT_EQ(large.back(), -7);
}

TEST(FixedVector, FillingAndClearingNeverAllocates) {
  ASSERT_TRUE(alloc::hooks_installed());
  FixedVector<Sample, 64> samples;
  FixedVector<int, 16> integers;
  const std::uint64_t before = alloc::counted_allocations();
  alloc::begin_counting_this_thread();
  bool all_pushed = true;
  for (int round = 0; round < 10; ++round) {
    for (int i = 0; i < 64; ++i) all_pushed = samples.emplace_back(i, 0.5f) && all_pushed;
    all_pushed = !samples.push_back(Sample{}) && all_pushed;  // full: refused
    all_pushed = samples.resize(10) && all_pushed;
    samples.pop_back();
    samples.clear();
    fill_with_sequence(integers, round);
    FixedVector<int, 16> copy = integers;
    integers.clear();
    integers = copy;
    integers.clear();
  }
  alloc::end_counting_this_thread();
  EXPECT_TRUE(all_pushed);
  EXPECT_EQ(alloc::counted_allocations() - before, 0u);
}

}  // namespace
}  // namespace trainer::core
