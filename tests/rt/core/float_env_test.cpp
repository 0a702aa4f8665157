// FlushDenormalsScope: subnormals flushed inside the scope (inputs and results), the thread's
// own mode restored after it, nested scopes restore their outer mode.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "trainer/core/float_env.hpp"

namespace {

using trainer::core::FlushDenormalsScope;

// Through volatile so the compiler cannot fold the arithmetic at compile time.
float multiply(float a, float b) {
  volatile float x = a;
  volatile float y = b;
  return x * y;
}

constexpr float kSubnormal = std::numeric_limits<float>::denorm_min() * 1000.0F;
constexpr float kSmallestNormal = std::numeric_limits<float>::min();

#if defined(__x86_64__) || defined(__i386__) || defined(__aarch64__)
TEST(FlushDenormalsScope, FlushesSubnormalInputsAndResultsInsideAndRestoresAfter) {
  ASSERT_FALSE(FlushDenormalsScope::active()) << "the test thread starts in IEEE mode";
  ASSERT_EQ(std::fpclassify(kSubnormal), FP_SUBNORMAL);
  EXPECT_EQ(std::fpclassify(multiply(kSubnormal, 1.0F)), FP_SUBNORMAL);
  EXPECT_EQ(std::fpclassify(multiply(kSmallestNormal, 0.25F)), FP_SUBNORMAL);
  {
    const FlushDenormalsScope flush;
    EXPECT_TRUE(FlushDenormalsScope::active());
    EXPECT_EQ(multiply(kSmallestNormal, 0.25F), 0.0F) << "a subnormal result is flushed";
    EXPECT_EQ(multiply(kSubnormal, 1.0e30F), 0.0F) << "a subnormal input counts as zero";
    EXPECT_EQ(multiply(kSmallestNormal, 2.0F), 2.0F * kSmallestNormal) << "normals unchanged";
    {
      const FlushDenormalsScope nested;
      EXPECT_TRUE(FlushDenormalsScope::active());
    }
    EXPECT_TRUE(FlushDenormalsScope::active()) << "the inner scope restored the outer mode";
  }
  EXPECT_FALSE(FlushDenormalsScope::active());
  EXPECT_EQ(std::fpclassify(multiply(kSmallestNormal, 0.25F)), FP_SUBNORMAL);
}
#else
TEST(FlushDenormalsScope, IsANoOpWithoutTheControlBits) {
  const FlushDenormalsScope flush;
  EXPECT_FALSE(FlushDenormalsScope::active());
}
#endif

}  // namespace
