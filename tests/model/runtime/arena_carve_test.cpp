// The broad phases' setup refusals when their arena is too small (arena_carve.hpp, shared by
// the bucket grid and the triangle BVH): an error naming the structure, "arena exhausted" and
// the array that did not fit, and nothing half-built returned.
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace trainer::model {
namespace {

TEST(ArenaCarve, ABucketGridTooBigForItsArenaNamesTheGridAndTheArray) {
  auto arena = core::Arena::create(4096);
  ASSERT_TRUE(arena);
  // The bucket starts (4097 uint32) alone need more than the 4 KiB arena.
  auto grid = BucketGrid::create({16, 16, 0.001F, 4096, 64}, arena.value());
  ASSERT_FALSE(grid);
  const std::string& message = grid.error().message;
  EXPECT_EQ(message.rfind("bucket grid: arena exhausted: ", 0), 0U) << message;
  EXPECT_NE(message.find("bucket starts"), std::string::npos) << message;
}

TEST(ArenaCarve, ATriangleBvhTooBigForItsArenaNamesTheBvhAndTheArray) {
  // 2,000 separate triangles: their order array (8 kB) does not fit in 4 KiB.
  const std::uint32_t count = 2000;
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
  for (std::uint32_t t = 0; t < count; ++t) {
    const float x = 0.001F * static_cast<float>(t);
    positions.insert(positions.end(), {x, 0.0F, 0.0F, x, 0.001F, 0.0F, x, 0.0F, 0.001F});
    triangles.insert(triangles.end(), {3 * t, 3 * t + 1, 3 * t + 2});
  }
  auto arena = core::Arena::create(4096);
  ASSERT_TRUE(arena);
  auto bvh = TriangleBvh::create(positions, triangles, arena.value());
  ASSERT_FALSE(bvh);
  const std::string& message = bvh.error().message;
  EXPECT_EQ(message.rfind("triangle bvh: arena exhausted: ", 0), 0U) << message;
  EXPECT_NE(message.find("bvh triangle order"), std::string::npos) << message;
}

}  // namespace
}  // namespace trainer::model
