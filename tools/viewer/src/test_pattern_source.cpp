#include "test_pattern_source.hpp"

#include <cmath>
#include <numbers>
#include <string>
#include <thread>

#include "view_frame.hpp"  // realtime_now_ns

namespace trainer::viewer {

TestPatternSource::TestPatternSource(const SceneAssets& assets, double rate_hz)
    : assets_(assets),
      period_(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      start_(std::chrono::steady_clock::now()),
      next_due_(start_) {}

core::Expected<bool> TestPatternSource::next(SceneFrame& frame, std::chrono::milliseconds timeout) {
  const auto now = std::chrono::steady_clock::now();
  if (next_due_ > now + timeout) {
    std::this_thread::sleep_for(timeout);
    return false;
  }
  std::this_thread::sleep_until(next_due_);
  next_due_ += period_;
  ++count_;
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double phase = 2.0 * std::numbers::pi * t;
  frame.sequence = count_;
  // The haptic cycle this instant would be, so the page's session time runs at wall speed.
  frame.cycle =
      assets_.period_s() > 0.0 ? static_cast<std::uint64_t>(t / assets_.period_s()) : count_;
  frame.times.cycle_ns = realtime_now_ns();
  frame.times.sent_ns = frame.times.cycle_ns;
  frame.times.received_ns = frame.times.cycle_ns;
  frame.latched_faults = 0;
  frame.models.assign(assets_.models().size(), ModelState{});
  for (std::size_t i = 0; i < assets_.models().size(); ++i) {
    const ModelAssets& m = assets_.models()[i];
    ModelState& state = frame.models[i];
    if (m.kind == config::ModelKind::modal_shell) {
      state.modal_coordinates.assign(m.mode_count, 0.0F);
      // q = amplitude / ω scale: the first modes' displacement of a few mm for the duct.
      for (std::size_t k = 0; k < std::min<std::size_t>(3, m.mode_count); ++k) {
        state.modal_coordinates[k] =
            static_cast<float>(2e-4 * std::sin(phase + static_cast<double>(k)));
      }
    } else if (m.kind == config::ModelKind::catheter) {
      for (std::size_t p = 0; p < m.node_count; ++p) {
        state.particles_m.push_back(
            {m.rest_positions[3 * p], m.rest_positions[3 * p + 1], m.rest_positions[3 * p + 2]});
      }
    }
  }
  frame.instruments.assign(assets_.instruments().size(), InstrumentState{});
  frame.contacts.clear();
  for (std::size_t i = 0; i < frame.instruments.size(); ++i) {
    const kinematics::JointVector joints{static_cast<float>(0.1 * std::sin(phase)), 0.0F, 0.1F,
                                         0.0F, static_cast<float>(0.3 + 0.3 * std::sin(phase))};
    const kinematics::InstrumentPose pose = assets_.instruments()[i].kinematics.forward(joints);
    InstrumentState& instrument = frame.instruments[i];
    auto put = [](std::array<float, 3>& to, const kinematics::Vec3& from) {
      to = {from.x(), from.y(), from.z()};
    };
    put(instrument.shaft_start_m, pose.shaft_start_m);
    put(instrument.hinge_m, pose.hinge_m);
    put(instrument.jaw_tips_m[0], pose.jaw_tips_m[0]);
    put(instrument.jaw_tips_m[1], pose.jaw_tips_m[1]);
  }
  return true;
}

std::string TestPatternSource::describe() const {
  return "test pattern (synthetic, no appliance)";
}

std::string TestPatternSource::stats_json() const {
  return "{\"source\":\"test-pattern\",\"frames\":" + std::to_string(count_) + "}";
}

}  // namespace trainer::viewer
