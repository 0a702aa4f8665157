// The tool-force safety chain as the reference scenes configure it (8 N, 4000 N/s), for tests
// that pass a model's tool force through it cycle by cycle and check what the tool would feel:
// finite, within max_force_n, rising by at most max_force_rate_n_per_s × dt per cycle.
// Used by the stability tests (docs/stability.md).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

#include <Eigen/Core>

#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::test {

struct SafetyChainProbe {
  safety::SafetySupervisor supervisor{limits(), 1};
  Eigen::Vector3f last_n = Eigen::Vector3f::Zero();
  float peak_n = 0.0F;
  float worst_rise_n = 0.0F;  // largest |F| increase in one cycle
  std::uint64_t cycle = 0;

  SafetyChainProbe() {
    supervisor.request_reset();
    EXPECT_TRUE(supervisor.evaluate_inputs({}, 0));
  }
  static safety::SafetyLimits limits() {
    safety::SafetyLimits result;
    result.max_force_n = 8.0F;
    result.max_force_rate_n_per_s = 4000.0F;
    return result;
  }
  // The force the tool would feel for `requested_n` in a cycle of `dt_s`.
  Eigen::Vector3f pass(const Eigen::Vector3f& requested_n, float dt_s) {
    const Eigen::Vector3f force = supervisor.limit_force(0, requested_n, dt_s, ++cycle);
    EXPECT_TRUE(force.allFinite());
    peak_n = std::max(peak_n, force.norm());
    worst_rise_n = std::max(worst_rise_n, force.norm() - last_n.norm());
    last_n = force;
    return force;
  }
  void expect_within_limits(float dt_s) const {
    EXPECT_TRUE(supervisor.armed());
    EXPECT_LE(peak_n, limits().max_force_n * (1.0F + 1e-6F));
    EXPECT_LE(worst_rise_n, limits().max_force_rate_n_per_s * dt_s * (1.0F + 1e-5F));
  }
};

}  // namespace trainer::test
