// The scripted trainee: keyframed joint targets per instrument that the simulated hand follows.
// Between two keyframes of an instrument the target moves along a minimum-jerk profile
// s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (Flash & Hogan 1985), so target velocity and acceleration are zero
// at every keyframe; before an instrument's first keyframe it holds the first pose, after its
// last it holds the last. An instrument the script never mentions holds the neutral pose.
//
// Loading (CSV parsing, file I/O, the built-ins) is setup path and returns core::Expected
// errors that name file:line; sample() is RT path (noexcept, no heap).
//
// Trajectory CSV format:
//   # comment lines and blank lines are ignored anywhere; a '#' also starts a trailing comment
//   time_s,instrument,pitch_rad,yaw_rad,insertion_m,roll_rad,grip_rad      <- header, required
//   0.0,left,0,0,0.05,0,0.3
// `instrument` is an instrument name from the device parameters; times are seconds from the
// start of the script (>= 0) and strictly increasing per instrument (rows of different
// instruments may interleave). At most kMaxKeyframes rows per script.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/core/expected.hpp"
#include "trainer/hal_sim/sim_params.hpp"

namespace trainer::hal::sim {

inline constexpr std::size_t kMaxKeyframes = 4096;

// Joint targets of one instrument in channel order: pitch rad, yaw rad, insertion m, roll rad,
// grip rad (or their rates per second when used as a velocity).
using JointPose = std::array<double, kJointsPerInstrument>;

// pitch 0, yaw 0, insertion 0.05 m, roll 0, grip 0.3 rad: shaft 5 cm in, jaws slightly open.
inline constexpr JointPose kNeutralPose = {0.0, 0.0, 0.05, 0.0, 0.3};

inline constexpr std::string_view kHoldScript = "builtin:hold";
inline constexpr std::string_view kSweepScript = "builtin:sweep";
inline constexpr std::string_view kCsvHeader =
    "time_s,instrument,pitch_rad,yaw_rad,insertion_m,roll_rad,grip_rad";

struct Keyframe {
  double time_s = 0.0;
  std::size_t instrument = 0;
  JointPose pose{};
};

struct PoseSample {
  JointPose position{};
  JointPose velocity{};  // rad/s and m/s
};

class TraineeScript {
 public:
  // Empty script for zero instruments (what a default-constructed SimDevice holds).
  TraineeScript() = default;

  // Dispatches on `spec`: "builtin:hold", "builtin:sweep", any other "builtin:..." is refused,
  // anything else is a CSV path. `instrument_names` fixes the instrument indices.
  static core::Expected<TraineeScript> load(std::string_view spec,
                                            std::span<const std::string> instrument_names);
  static core::Expected<TraineeScript> load_csv_file(const std::string& path,
                                                     std::span<const std::string> instrument_names);
  // `source_name` prefixes every error message ("<source_name>:<line>: ...").
  static core::Expected<TraineeScript> parse_csv(std::string_view text, std::string_view source_name,
                                                 std::span<const std::string> instrument_names);
  // Keyframes in any instrument order; per instrument they must be in strictly increasing time.
  static core::Expected<TraineeScript> from_keyframes(std::span<const Keyframe> keyframes,
                                                      std::size_t instrument_count,
                                                      std::string_view source_name);

  // Every instrument holds kNeutralPose forever (duration 0).
  static TraineeScript builtin_hold(std::size_t instrument_count);
  // A gentle 10 s motion of every joint about the neutral pose, identical for every
  // instrument: keyframes every 2.5 s at neutral, +A, neutral, -A, neutral with
  // A = (0.2 rad, 0.2 rad, 0.02 m, 0.5 rad, 0.2 rad). Meant for tests and demos; the device's
  // joint stops clip it if they are narrower.
  static TraineeScript builtin_sweep(std::size_t instrument_count);

  std::size_t instrument_count() const noexcept { return instrument_count_; }
  std::size_t keyframe_count() const noexcept { return keyframes_.size(); }
  // Time of the last keyframe over all instruments, seconds.
  double duration_s() const noexcept { return duration_s_; }
  // The keyframes of one instrument, in time order (empty span for an out-of-range index).
  std::span<const Keyframe> keyframes(std::size_t instrument) const noexcept;

  // Target pose and velocity of `instrument` at `time_s` (RT path). Out-of-range instrument:
  // the neutral pose at rest.
  PoseSample sample(std::size_t instrument, double time_s) const noexcept;

 private:
  std::size_t instrument_count_ = 0;
  // Sorted by (instrument, time); instrument i owns [begin_[i], begin_[i + 1]). Sized once at
  // load (setup path) and never grown after.
  std::vector<Keyframe> keyframes_;
  std::array<std::size_t, kMaxInstruments + 1> begin_{};
  double duration_s_ = 0.0;
};

}  // namespace trainer::hal::sim
