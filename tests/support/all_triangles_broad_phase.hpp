// Shared by the collision tests: the reference broad phase, every triangle in id order; a
// conservative broad phase must return every triangle of it that is within reach.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>

#include "trainer/model/broad_phase.hpp"

namespace trainer::model::test_support {

class AllTriangles final : public TriangleBroadPhase {
 public:
  explicit AllTriangles(std::size_t count) : count_(count) {}
  core::Status query(const Aabb&, std::span<std::uint32_t> out, std::size_t& count) noexcept override {
    count = std::min(out.size(), count_);
    for (std::size_t t = 0; t < count; ++t) out[t] = static_cast<std::uint32_t>(t);
    return core::Status::ok();
  }

 private:
  std::size_t count_;
};

}  // namespace trainer::model::test_support
