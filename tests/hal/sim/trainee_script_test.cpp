// TraineeScript: CSV parsing (valid files and every parse error with its file:line), the
// minimum-jerk interpolation (midpoint, zero velocity at keyframes, velocity = derivative of
// position), holding before/after the keyframes, the built-ins and the shipped wall_press.csv.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "sim_test_support.hpp"
#include "trainer/hal_sim/trainee_script.hpp"

namespace trainer::hal::sim {
namespace {

using test_support::write_temp_csv;

const std::vector<std::string> kTwoInstruments = {"left", "right"};

TraineeScript parse_or_fail(const std::string& text) {
  auto script = TraineeScript::parse_csv(text, "test.csv", kTwoInstruments);
  EXPECT_TRUE(script) << (script ? "" : script.error().message);
  return script ? std::move(script).value() : TraineeScript{};
}

std::string parse_error(const std::string& text) {
  auto script = TraineeScript::parse_csv(text, "bad.csv", kTwoInstruments);
  return script ? std::string("(parsed)") : script.error().message;
}

constexpr const char* kValidCsv =
    "# two instruments, interleaved rows\r\n"
    "time_s, instrument, pitch_rad, yaw_rad, insertion_m, roll_rad, grip_rad\r\n"
    "\r\n"
    "0.0,left,0,0,0.05,0,0.3\r\n"
    "0.5,right,0.1,0.1,0.06,0.2,0.4   # trailing comment\r\n"
    "2.0,left,0.2,-0.1,0.09,1.0,0.1\r\n"
    "   # indented comment\n"
    "4,left,0.2,-0.1,0.09,1.0,0.1\n";

TEST(TraineeScriptCsv, ParsesCommentsBlankLinesCrlfAndInterleavedInstruments) {
  const TraineeScript script = parse_or_fail(kValidCsv);
  EXPECT_EQ(script.instrument_count(), 2U);
  EXPECT_EQ(script.keyframe_count(), 4U);
  ASSERT_EQ(script.keyframes(0).size(), 3U);
  ASSERT_EQ(script.keyframes(1).size(), 1U);
  EXPECT_EQ(script.keyframes(2).size(), 0U);
  EXPECT_DOUBLE_EQ(script.keyframes(0)[1].time_s, 2.0);
  EXPECT_DOUBLE_EQ(script.keyframes(0)[1].pose[kRollJoint], 1.0);
  EXPECT_DOUBLE_EQ(script.keyframes(1)[0].pose[kGripJoint], 0.4);
  EXPECT_DOUBLE_EQ(script.duration_s(), 4.0);
}

TEST(TraineeScriptSample, MinimumJerkMidpointIsTheAverageAndKeyframesAreAtRest) {
  const TraineeScript script = parse_or_fail(kValidCsv);
  const Keyframe& from = script.keyframes(0)[0];
  const Keyframe& to = script.keyframes(0)[1];
  const PoseSample midpoint = script.sample(0, 1.0);
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_NEAR(midpoint.position[joint], 0.5 * (from.pose[joint] + to.pose[joint]), 1e-12)
        << kJointNames[joint];
    // Peak velocity of a minimum-jerk move is 1.875 · distance / duration, at the midpoint.
    EXPECT_NEAR(midpoint.velocity[joint], 1.875 * (to.pose[joint] - from.pose[joint]) / 2.0, 1e-12);
  }
  // At (and just around) every keyframe the velocity vanishes: s'(0) = s'(1) = 0.
  for (const double keyframe_s : {0.0, 2.0, 4.0}) {
    for (const double offset_s : {-1e-4, 0.0, 1e-4}) {
      const PoseSample sample = script.sample(0, keyframe_s + offset_s);
      for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
        // |v| <= 30 τ² |Δ| / T with τ = 1e-4 / 2: about 1e-8 for these moves.
        EXPECT_NEAR(sample.velocity[joint], 0.0, 1e-7)
            << "t = " << keyframe_s + offset_s << " joint " << kJointNames[joint];
      }
    }
  }
  // The quarter point of s(τ) is 10/64 − 15/256 + 6/1024 = 0.103515625.
  const PoseSample quarter = script.sample(0, 0.5);
  EXPECT_NEAR(quarter.position[kInsertionJoint], 0.05 + 0.103515625 * (0.09 - 0.05), 1e-12);
}

TEST(TraineeScriptSample, VelocityIsTheDerivativeOfPosition) {
  const TraineeScript script = parse_or_fail(kValidCsv);
  constexpr double kStepS = 1e-6;
  for (double time_s = 0.05; time_s < 2.0; time_s += 0.1) {
    const PoseSample before = script.sample(0, time_s - kStepS);
    const PoseSample after = script.sample(0, time_s + kStepS);
    const PoseSample here = script.sample(0, time_s);
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      const double central_difference =
          (after.position[joint] - before.position[joint]) / (2.0 * kStepS);
      EXPECT_NEAR(here.velocity[joint], central_difference, 1e-6) << "t = " << time_s;
    }
  }
}

TEST(TraineeScriptSample, HoldsTheFirstPoseBeforeAndTheLastAfter) {
  const TraineeScript script = parse_or_fail(kValidCsv);
  // "right" starts at 0.5 s: before that it holds its first keyframe, after it holds it too.
  for (const double time_s : {0.0, 0.25, 0.5, 3.0, 100.0}) {
    const PoseSample sample = script.sample(1, time_s);
    EXPECT_EQ(sample.position, script.keyframes(1)[0].pose) << time_s;
    EXPECT_EQ(sample.velocity, (JointPose{})) << time_s;
  }
  EXPECT_EQ(script.sample(0, 4.0).position, script.keyframes(0)[2].pose);
  EXPECT_EQ(script.sample(0, 1e9).position, script.keyframes(0)[2].pose);
  EXPECT_EQ(script.sample(0, -5.0).position, script.keyframes(0)[0].pose);
  EXPECT_EQ(script.sample(7, 1.0).position, kNeutralPose) << "out-of-range instrument";
}

TEST(TraineeScriptSample, InstrumentWithoutKeyframesHoldsTheNeutralPose) {
  const TraineeScript script = parse_or_fail(
      "time_s,instrument,pitch_rad,yaw_rad,insertion_m,roll_rad,grip_rad\n"
      "0,left,0.1,0.1,0.1,0.1,0.1\n"
      "1,left,0.2,0.2,0.2,0.2,0.2\n");
  ASSERT_EQ(script.keyframes(1).size(), 1U);
  EXPECT_EQ(script.sample(1, 0.5).position, kNeutralPose);
  EXPECT_DOUBLE_EQ(script.duration_s(), 1.0);
}

TEST(TraineeScriptCsv, EachParseErrorNamesFileLineAndProblem) {
  const std::string header = "time_s,instrument,pitch_rad,yaw_rad,insertion_m,roll_rad,grip_rad\n";
  struct Case {
    std::string text;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {header + "0,left,0,0,0.05,zero,0.3\n",
       "bad.csv:2: column roll_rad: 'zero' is not a number"},
      {header + "0,left,0,0,0.05x,0,0.3\n",
       "bad.csv:2: column insertion_m: '0.05x' is not a number"},
      {header + "0,left,0,,0.05,0,0.3\n", "bad.csv:2: column yaw_rad: '' is not a number"},
      {header + "# comment\n0,left,0,0,0.05,0\n",
       "bad.csv:3: expected 7 comma-separated columns"},
      {header + "0,left,0,0,0.05,0,0.3,9\n", "got 8"},
      {header + "0,middle,0,0,0.05,0,0.3\n",
       "bad.csv:2: unknown instrument 'middle'; the device has 'left', 'right'"},
      {header + "0,left,0,0,0.05,0,0.3\n1,right,0,0,0.05,0,0.3\n1,left,0,0,0.05,0,0.3\n"
                "1,left,0,0,0.05,0,0.3\n",
       "bad.csv:5: time_s 1 for instrument 'left' is not after its previous keyframe (time_s 1 "
       "at line 4)"},
      {header + "2,left,0,0,0.05,0,0.3\n1.5,left,0,0,0.05,0,0.3\n",
       "bad.csv:3: time_s 1.5 for instrument 'left' is not after its previous keyframe"},
      {header + "0,left,nan,0,0.05,0,0.3\n", "bad.csv:2: column pitch_rad: 'nan' is not finite"},
      {header + "0,left,0,0,0.05,0,inf\n", "bad.csv:2: column grip_rad: 'inf' is not finite"},
      {header + "1e999,left,0,0,0.05,0,0.3\n", "bad.csv:2: column time_s: '1e999'"},
      {header + "-1,left,0,0,0.05,0,0.3\n", "bad.csv:2: time_s -1 is negative"},
      {"# only a comment\n\n", "bad.csv: no header line"},
      {"\ntime_s,instrument,pitch,yaw,insertion,roll,grip\n",
       "bad.csv:2: expected the header line 'time_s,instrument,pitch_rad"},
      {"0,left,0,0,0.05,0,0.3\n", "bad.csv:1: expected the header line"},
      {header + "# nothing else\n", "bad.csv: no keyframes after the header"},
  };
  for (const Case& test_case : cases) {
    const std::string message = parse_error(test_case.text);
    EXPECT_NE(message.find(test_case.expected), std::string::npos)
        << "expected '" << test_case.expected << "' in '" << message << "'";
  }
}

TEST(TraineeScriptCsv, MoreThanTheKeyframeCapacityIsRefused) {
  std::string text = std::string(kCsvHeader) + "\n";
  for (std::size_t row = 0; row <= kMaxKeyframes; ++row) {
    text += std::to_string(row) + ".0," + (row % 2 == 0 ? "left" : "right") +
            ",0,0,0.05,0,0.3\n";
  }
  const std::string message = parse_error(text);
  EXPECT_NE(message.find("bad.csv:" + std::to_string(kMaxKeyframes + 2) +
                         ": too many keyframes: a script holds at most 4096"),
            std::string::npos)
      << message;
  // Exactly at capacity is fine.
  text.resize(text.rfind(std::to_string(kMaxKeyframes) + ".0,"));
  EXPECT_EQ(parse_error(text), "(parsed)");
}

TEST(TraineeScriptLoad, ReadsFilesAndRefusesMissingOnesAndUnknownBuiltins) {
  const std::string path = write_temp_csv("valid", kValidCsv);
  auto script = TraineeScript::load(path, kTwoInstruments);
  ASSERT_TRUE(script) << script.error().message;
  EXPECT_EQ(script->keyframe_count(), 4U);

  const std::string bad_path = write_temp_csv("bad", "time_s\n");
  auto bad = TraineeScript::load(bad_path, kTwoInstruments);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find(bad_path + ":1: expected the header line"), std::string::npos)
      << bad.error().message;

  auto missing = TraineeScript::load("/no/such/trajectory.csv", kTwoInstruments);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find(
                "cannot open trajectory file '/no/such/trajectory.csv': No such file"),
            std::string::npos)
      << missing.error().message;

  auto unknown = TraineeScript::load("builtin:dance", kTwoInstruments);
  ASSERT_FALSE(unknown);
  EXPECT_NE(unknown.error().message.find("unknown built-in script 'builtin:dance'"),
            std::string::npos);
  EXPECT_FALSE(TraineeScript::load("", kTwoInstruments));
}

TEST(TraineeScriptBuiltin, HoldIsTheNeutralPoseForever) {
  auto script = TraineeScript::load("builtin:hold", kTwoInstruments);
  ASSERT_TRUE(script);
  EXPECT_EQ(script->duration_s(), 0.0);
  for (std::size_t instrument = 0; instrument < 2; ++instrument) {
    for (const double time_s : {0.0, 1.0, 1000.0}) {
      EXPECT_EQ(script->sample(instrument, time_s).position, kNeutralPose);
    }
  }
  EXPECT_EQ(kNeutralPose, (JointPose{0.0, 0.0, 0.05, 0.0, 0.3}));
}

TEST(TraineeScriptBuiltin, SweepMovesEveryJointGentlyForTenSeconds) {
  auto script = TraineeScript::load("builtin:sweep", kTwoInstruments);
  ASSERT_TRUE(script);
  EXPECT_DOUBLE_EQ(script->duration_s(), 10.0);
  JointPose lowest = kNeutralPose;
  JointPose highest = kNeutralPose;
  JointPose fastest{};
  for (double time_s = 0.0; time_s <= 10.0; time_s += 0.01) {
    const PoseSample sample = script->sample(1, time_s);
    EXPECT_EQ(sample.position, script->sample(0, time_s).position) << "instruments move alike";
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      lowest[joint] = std::min(lowest[joint], sample.position[joint]);
      highest[joint] = std::max(highest[joint], sample.position[joint]);
      fastest[joint] = std::max(fastest[joint], std::abs(sample.velocity[joint]));
    }
  }
  const JointPose amplitude = {0.2, 0.2, 0.02, 0.5, 0.2};
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    EXPECT_NEAR(highest[joint] - kNeutralPose[joint], amplitude[joint], 1e-9) << kJointNames[joint];
    EXPECT_NEAR(kNeutralPose[joint] - lowest[joint], amplitude[joint], 1e-9) << kJointNames[joint];
    EXPECT_NEAR(fastest[joint], 0.75 * amplitude[joint], 1e-3 * amplitude[joint]);
  }
  EXPECT_EQ(script->sample(0, 10.0).position, kNeutralPose) << "ends where it started";
}

TEST(TraineeScriptWallPress, ShippedFileParsesAndPressesPastTheWall) {
  const std::string path = std::string(TRAINER_SOURCE_DIR) + "/config/trajectories/wall_press.csv";
  auto script = TraineeScript::load(path, kTwoInstruments);
  ASSERT_TRUE(script) << script.error().message;
  const std::span<const Keyframe> left = script->keyframes(0);
  ASSERT_GE(left.size(), 4U);
  EXPECT_EQ(left.front().pose, kNeutralPose);
  EXPECT_EQ(left.front().time_s, 0.0);
  EXPECT_NEAR(script->duration_s(), 10.0, 0.5);
  EXPECT_EQ(script->sample(0, script->duration_s()).position[kInsertionJoint], 0.05);

  double deepest_m = 0.0;
  double reached_wall_s = -1.0;
  double pressed_from_s = -1.0;
  double pressed_until_s = -1.0;
  double yaw_low = 0.0;
  double yaw_high = 0.0;
  for (double time_s = 0.0; time_s <= 11.0; time_s += 0.001) {
    const JointPose pose = script->sample(0, time_s).position;
    deepest_m = std::max(deepest_m, pose[kInsertionJoint]);
    if (reached_wall_s < 0.0 && pose[kInsertionJoint] >= 0.09) reached_wall_s = time_s;
    if (pose[kInsertionJoint] >= 0.105 - 1e-9) {
      if (pressed_from_s < 0.0) pressed_from_s = time_s;
      pressed_until_s = time_s;
      yaw_low = std::min(yaw_low, pose[kYawJoint]);
      yaw_high = std::max(yaw_high, pose[kYawJoint]);
    } else {
      EXPECT_NEAR(pose[kYawJoint], 0.0, 1e-12) << "yaw only moves while pressed, t = " << time_s;
    }
  }
  EXPECT_NEAR(deepest_m, 0.105, 1e-12) << "15 mm past the wall at 0.09 m";
  EXPECT_GT(reached_wall_s, 3.0);
  EXPECT_LT(reached_wall_s, 6.0);
  EXPECT_NEAR(pressed_from_s, 6.0, 0.01);
  EXPECT_GT(pressed_until_s - pressed_from_s, 2.0) << "held 1 s, then slides while pressed";
  EXPECT_NEAR(yaw_low, -0.05, 1e-9);
  EXPECT_NEAR(yaw_high, 0.05, 1e-9);
  // "right" is not in the file: it holds the neutral pose.
  EXPECT_EQ(script->sample(1, 5.0).position, kNeutralPose);
}

}  // namespace
}  // namespace trainer::hal::sim
