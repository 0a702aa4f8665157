// A synthetic frame source for checking a graphics host without an appliance (viewer --source
// test-pattern): the scene at rest except the first modes of each modal model swinging at
// 1 Hz (amplitude a few millimetres at the surface), the instruments' pitch sweeping, the
// catheter's particles at rest. Its frames say so (sequence from 1, cycle = frame × period).
// Not a measurement of anything: the real stream comes from the trainer (udp source).
#pragma once

#include <chrono>

#include "frame_source.hpp"
#include "scene_assets.hpp"

namespace trainer::viewer {

class TestPatternSource final : public FrameSource {
 public:
  TestPatternSource(const SceneAssets& assets, double rate_hz);
  core::Expected<bool> next(SceneFrame& frame, std::chrono::milliseconds timeout) override;
  std::string describe() const override;
  std::string stats_json() const override;

 private:
  const SceneAssets& assets_;
  std::chrono::nanoseconds period_;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point next_due_;
  std::uint64_t count_ = 0;
};

}  // namespace trainer::viewer
