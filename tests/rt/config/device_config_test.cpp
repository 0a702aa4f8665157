// Tests of load_device: the repository's sim device file, defaults and conversions on a
// minimal file, and one specific message per kind of mistake (each asserted to name the file,
// the line, the key, the bad value and the expected range/unit).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "config_test_files.hpp"
#include "trainer/config/device.hpp"

namespace trainer::config {
namespace {

using testing::ConfigFileTest;
using testing::expect_contains;
using testing::line_of;
using testing::read_text;
using testing::replace_first;
using testing::repo_path;

std::string error_message(const core::Expected<DeviceConfig>& result) {
  EXPECT_FALSE(result.has_value()) << "expected the load to fail";
  return result.has_value() ? std::string{} : result.error().message;
}

// ---------------------------------------------------------------- the repository file

TEST(SimDeviceFile, LoadsWithSiValues) {
  const auto device = load_device(repo_path("config/devices/sim.toml"));
  ASSERT_TRUE(device.has_value()) << device.error().message;
  EXPECT_EQ(device->name, "sim-two-port");
  EXPECT_EQ(device->backend, "sim");
  EXPECT_TRUE(device->source_path.is_absolute());
  EXPECT_EQ(device->plant_substep_ns, 100'000);  // 100 us
  EXPECT_EQ(device->digital.estop_input_bit, 0);
  EXPECT_EQ(device->digital.enable_input_bit, 1);
  EXPECT_EQ(device->digital.drive_enable_output_bit, 0);
  EXPECT_EQ(device->digital.fault_lamp_output_bit, 1);

  ASSERT_EQ(device->instruments.size(), 2U);
  const auto& left = device->instruments[0];
  const auto& right = device->instruments[1];
  EXPECT_EQ(left.name, "left");
  EXPECT_EQ(right.name, "right");
  // Trocars about 10 cm apart, both shafts pointing down -z.
  EXPECT_NEAR(right.trocar_position_m[0] - left.trocar_position_m[0], 0.10, 1e-12);
  EXPECT_EQ(left.shaft_axis, (Vec3{0.0, 0.0, -1.0}));
  EXPECT_EQ(left.up_axis, (Vec3{0.0, 1.0, 0.0}));
  EXPECT_DOUBLE_EQ(left.shaft_length_m, 0.36);
  EXPECT_DOUBLE_EQ(left.jaw_length_m, 0.015);

  const auto& pitch = left.joints[index(JointId::pitch)];
  EXPECT_EQ(pitch.kind, hal::JointKind::revolute);
  EXPECT_EQ(pitch.counts_per_rev, 4096);
  EXPECT_DOUBLE_EQ(pitch.gear_ratio, 15.0);
  EXPECT_DOUBLE_EQ(pitch.capstan_radius_m, 0.0);
  EXPECT_DOUBLE_EQ(pitch.min_position, -0.6);
  EXPECT_DOUBLE_EQ(pitch.max_position, 0.6);
  EXPECT_DOUBLE_EQ(pitch.inertia, 0.002);
  EXPECT_DOUBLE_EQ(pitch.hand_stiffness, 5.0);

  const auto& insertion = left.joints[index(JointId::insertion)];
  EXPECT_EQ(insertion.kind, hal::JointKind::prismatic);
  EXPECT_DOUBLE_EQ(insertion.capstan_radius_m, 0.01);
  EXPECT_DOUBLE_EQ(insertion.inertia, 0.15);  // mass_kg
  EXPECT_DOUBLE_EQ(insertion.hand_stiffness, 1500.0);
  EXPECT_DOUBLE_EQ(insertion.max_position, 0.25);
  // Insertion effort per amp = Kt * gear / r = 0.025 * 10 / 0.01 = 25 N/A; at 2.5 A: 62.5 N.
  EXPECT_NEAR(joint_scale(insertion).max_effort(), 62.5, 1e-9);
  // Pitch: 0.03 N·m/A * 15 * 3 A = 1.35 N·m.
  EXPECT_NEAR(joint_scale(pitch).max_effort(), 1.35, 1e-12);
  for (std::size_t i = 0; i < kJointCount; ++i) {
    const auto& joint = left.joints[i];
    EXPECT_LT(joint.min_position, joint.max_position) << to_string(static_cast<JointId>(i));
    EXPECT_EQ(joint.kind, static_cast<JointId>(i) == JointId::insertion ? hal::JointKind::prismatic
                                                                        : hal::JointKind::revolute);
  }
}

// encoder_direction / motor_direction reach hal::JointScale: -1 negates counts <-> position
// both ways (a round trip through the sim plant is exact, so simulated benches do not change)
// and the motor sign a backend applies to effort <-> current.
TEST(JointScaleDirections, ReversedEncoderAndMotorFlipSigns) {
  JointConfig joint;
  joint.counts_per_rev = 4096;
  joint.gear_ratio = 15.0;
  joint.torque_constant_nm_per_a = 0.03;
  joint.current_limit_a = 3.0;
  const hal::JointScale normal = joint_scale(joint);
  joint.encoder_direction = -1;
  joint.motor_direction = -1;
  const hal::JointScale reversed = joint_scale(joint);
  EXPECT_EQ(reversed.encoder_direction, -1);
  EXPECT_EQ(normal.counts_from_position(0.1), -reversed.counts_from_position(0.1));
  EXPECT_DOUBLE_EQ(normal.position_from_counts(977), -reversed.position_from_counts(977));
  for (const double position : {-0.55, -0.1, 0.0, 0.123456, 0.6}) {
    EXPECT_EQ(reversed.position_from_counts(reversed.counts_from_position(position)),
              normal.position_from_counts(normal.counts_from_position(position)));
  }
  EXPECT_DOUBLE_EQ(normal.current_from_effort(0.45), 1.0);
  EXPECT_DOUBLE_EQ(reversed.current_from_effort(0.45), -1.0);
  EXPECT_DOUBLE_EQ(reversed.motor_sign(), -1.0);
  EXPECT_DOUBLE_EQ(reversed.max_effort(), normal.max_effort());  // limits stay positive
}

// ---------------------------------------------------------------- a minimal file

std::string joint_text(std::string_view instrument_joint, bool prismatic) {
  // Appended piece by piece: GCC 12 at -O3 raises a false -Wrestrict on "literal" + string.
  std::string text = "[";
  text += instrument_joint;
  text += "]\n";
  if (prismatic) {
    text +=
        "counts_per_rev = 2048\ngear_ratio = 12\ncapstan_radius_m = 0.02\n"
        "torque_constant_nm_per_a = 0.04\ncurrent_limit_a = 1.5\nmin_m = -0.01\nmax_m = 0.2\n";
  } else {
    text +=
        "counts_per_rev = 1000\ngear_ratio = 10\ntorque_constant_nm_per_a = 0.05\n"
        "current_limit_a = 2\nmin_rad = -1\nmax_rad = 1\n";
  }
  return text;
}

// Required keys only; integers where reals are expected; directions of non-unit length.
std::string instrument_text(std::string_view name, int trocar_x_cm) {
  std::string text = "[[instrument]]\nname = \"" + std::string(name) + "\"\ntrocar_position_m = [" +
                     std::to_string(trocar_x_cm) +
                     "e-2, 0, 0]\nshaft_axis = [0, 0, -2]\nup_axis = [0, 3, 0]\n"
                     "shaft_length_m = 0.3\njaw_length_m = 0.01\n";
  for (const std::string_view joint : {"pitch", "yaw", "insertion", "roll", "grip"}) {
    text += joint_text("instrument." + std::string(joint), joint == "insertion");
  }
  return text;
}

constexpr std::string_view kMinimalHeader =
    "[device]\nname = \"bench\"\nbackend = \"sim\"\n\n"
    "[digital]\nestop_input_bit = -1\nenable_input_bit = -1\ndrive_enable_output_bit = -1\n"
    "fault_lamp_output_bit = 31\n\n";

using DeviceFileTest = ConfigFileTest;

TEST_F(DeviceFileTest, MinimalFileGetsDocumentedDefaultsAndConversions) {
  const auto path = write("bench.toml", std::string(kMinimalHeader) + instrument_text("only", 3));
  const auto device = load_device(path);
  ASSERT_TRUE(device.has_value()) << device.error().message;
  EXPECT_EQ(device->plant_substep_ns, 100'000);  // default plant_substep_us = 100
  EXPECT_EQ(device->digital.estop_input_bit, -1);
  EXPECT_EQ(device->digital.fault_lamp_output_bit, 31);
  ASSERT_EQ(device->instruments.size(), 1U);
  const auto& instrument = device->instruments[0];
  EXPECT_DOUBLE_EQ(instrument.trocar_position_m[0], 0.03);
  // Directions are normalised.
  EXPECT_EQ(instrument.shaft_axis, (Vec3{0.0, 0.0, -1.0}));
  EXPECT_EQ(instrument.up_axis, (Vec3{0.0, 1.0, 0.0}));
  // Integers accepted for reals.
  const auto& pitch = instrument.joints[index(JointId::pitch)];
  EXPECT_EQ(pitch.encoder_direction, 1);  // default: wired as designed
  EXPECT_EQ(pitch.motor_direction, 1);
  EXPECT_DOUBLE_EQ(pitch.gear_ratio, 10.0);
  EXPECT_DOUBLE_EQ(pitch.current_limit_a, 2.0);
  EXPECT_DOUBLE_EQ(pitch.min_position, -1.0);
  // Simulated-plant defaults (docs/config.md).
  EXPECT_DOUBLE_EQ(pitch.inertia, 0.002);
  EXPECT_DOUBLE_EQ(pitch.hand_stiffness, 5.0);
  EXPECT_DOUBLE_EQ(pitch.hand_damping, 0.1);
  const auto& insertion = instrument.joints[index(JointId::insertion)];
  EXPECT_EQ(insertion.counts_per_rev, 2048);
  EXPECT_DOUBLE_EQ(insertion.capstan_radius_m, 0.02);
  EXPECT_DOUBLE_EQ(insertion.min_position, -0.01);
  EXPECT_DOUBLE_EQ(insertion.inertia, 0.15);
  EXPECT_DOUBLE_EQ(insertion.hand_stiffness, 1500.0);
  EXPECT_DOUBLE_EQ(insertion.hand_damping, 15.0);
}

TEST_F(DeviceFileTest, BoundaryValuesAreAccepted) {
  std::string text = std::string(kMinimalHeader) + instrument_text("only", 0);
  text = replace_first(text, "counts_per_rev = 1000", "counts_per_rev = 16777216").text;
  text = replace_first(text, "gear_ratio = 10", "gear_ratio = 1000").text;
  text = replace_first(text, "name = \"bench\"", "name = \"bench\"\nplant_substep_us = 1").text;
  text = replace_first(text, "max_rad = 1", "max_rad = 20").text;
  const auto device = load_device(write("bench.toml", text));
  ASSERT_TRUE(device.has_value()) << device.error().message;
  EXPECT_EQ(device->plant_substep_ns, 1000);
  const auto& pitch = device->instruments[0].joints[index(JointId::pitch)];
  EXPECT_EQ(pitch.counts_per_rev, 16777216);
  EXPECT_DOUBLE_EQ(pitch.gear_ratio, 1000.0);
  EXPECT_DOUBLE_EQ(pitch.max_position, 20.0);
}

TEST_F(DeviceFileTest, NearlyOrthogonalUpAxisIsAcceptedAndMadeExactlyOrthogonal) {
  std::string text = std::string(kMinimalHeader) + instrument_text("only", 0);
  text = replace_first(text, "up_axis = [0, 3, 0]", "up_axis = [0, 1, 5e-7]").text;
  const auto device = load_device(write("bench.toml", text));
  ASSERT_TRUE(device.has_value()) << device.error().message;
  const Vec3& shaft = device->instruments[0].shaft_axis;
  const Vec3& up = device->instruments[0].up_axis;
  const double dot = shaft[0] * up[0] + shaft[1] * up[1] + shaft[2] * up[2];
  const double length = std::sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2]);
  EXPECT_NEAR(dot, 0.0, 1e-15);
  EXPECT_NEAR(length, 1.0, 1e-15);
}

TEST_F(DeviceFileTest, FourInstrumentsAreAcceptedAndFiveAreTooMany) {
  std::string four = std::string(kMinimalHeader);
  for (int i = 0; i < 4; ++i) four += instrument_text("tool" + std::to_string(i), i);
  const auto accepted = load_device(write("four.toml", four));
  ASSERT_TRUE(accepted.has_value()) << accepted.error().message;
  EXPECT_EQ(accepted->instruments.size(), 4U);
  EXPECT_EQ(accepted->instruments[3].name, "tool3");

  const std::string five = four + instrument_text("tool4", 4);
  const auto path = write("five.toml", five);
  const std::string message = error_message(load_device(path));
  const int fifth_line = line_of(five, "name = \"tool4\"") - 1;  // its [[instrument]] header
  EXPECT_EQ(message, path.string() + ":" + std::to_string(fifth_line) +
                         ": instrument[4]: too many instruments (5): expected 1 to 4 instruments");
}

TEST_F(DeviceFileTest, NoInstrumentIsAMissingKey) {
  const auto path = write("none.toml", kMinimalHeader);
  EXPECT_EQ(error_message(load_device(path)),
            path.string() +
                ": missing required key 'instrument' (array of tables [[instrument]], 1 to 4 "
                "instruments)");
}

TEST_F(DeviceFileTest, MissingTableIsNamed) {
  const std::string text =
      "[device]\nname = \"bench\"\nbackend = \"sim\"\n\n" + instrument_text("only", 0);
  const auto path = write("bench.toml", text);
  EXPECT_EQ(error_message(load_device(path)),
            path.string() + ": missing required key 'digital' (table [digital])");
}

TEST_F(DeviceFileTest, MissingRequiredKeyNamesKeyTypeAndUnit) {
  const std::string text = read_text(repo_path("config/devices/sim.toml"));
  const auto edited = replace_first(
      text,
      "counts_per_rev = 4096              # integer [1, 16777216], per motor revolution "
      "after quadrature\n",
      "");
  const auto path = write("sim.toml", edited.text);
  EXPECT_EQ(error_message(load_device(path)),
            path.string() +
                ": missing required key 'instrument[0].pitch.counts_per_rev' (integer, encoder "
                "counts per motor revolution, after quadrature)");
}

TEST_F(DeviceFileTest, MissingFileIsReportedWithResolvedPath) {
  const auto path = root_ / "absent.toml";
  EXPECT_EQ(error_message(load_device(path)),
            path.string() + ": file not found (resolved to " + path.string() + ")");
}

TEST_F(DeviceFileTest, MissingJointTableIsNamed) {
  std::string text = std::string(kMinimalHeader) + instrument_text("only", 0);
  text = replace_first(text, "[instrument.roll]", "[instrument.rol]").text;
  const auto path = write("bench.toml", text);
  // The misspelt table is the specific error (the missing roll table is its consequence).
  const std::string message = error_message(load_device(path));
  expect_contains(message, path.string() + ":" + std::to_string(line_of(text, "[instrument.rol]")) +
                               ": unknown key 'instrument[0].rol' (known: name, ");
  expect_contains(message, "did you mean 'roll'?");
}

// ---------------------------------------------------------------- one edit, one message

struct DeviceErrorCase {
  const char* name;
  const char* from;  // first occurrence in config/devices/sim.toml is replaced
  const char* to;
  const char* expected;  // the message after "<file>:<line>: "
  int line_offset = 0;   // the reported line relative to the edited one
};

std::ostream& operator<<(std::ostream& stream, const DeviceErrorCase& error_case) {
  return stream << error_case.name;
}

class DeviceErrorTest : public ConfigFileTest,
                        public ::testing::WithParamInterface<DeviceErrorCase> {};

TEST_P(DeviceErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const DeviceErrorCase& error_case = GetParam();
  const std::string text = read_text(repo_path("config/devices/sim.toml"));
  const auto edited = replace_first(text, error_case.from, error_case.to);
  const auto path = write("devices/sim.toml", edited.text);
  const std::string message = error_message(load_device(path));
  const std::string location =
      path.string() + ":" + std::to_string(edited.line + error_case.line_offset) + ": ";
  expect_contains(message, location + error_case.expected);
}

const DeviceErrorCase kDeviceErrorCases[] = {
    {"syntax_error", "gear_ratio = 15.0", "gear_ratio = = 15.0", "syntax error: "},
    {"range_exclusive_lower", "gear_ratio = 15.0", "gear_ratio = 0",
     "instrument[0].pitch.gear_ratio = 0 is out of range: expected more than 0 and at most "
     "1000 (motor revolutions per joint revolution)"},
    {"range_upper", "gear_ratio = 15.0", "gear_ratio = 1000.5",
     "instrument[0].pitch.gear_ratio = 1000.5 is out of range: expected more than 0 and at "
     "most 1000 (motor revolutions per joint revolution)"},
    {"nan", "gear_ratio = 15.0", "gear_ratio = nan",
     "instrument[0].pitch.gear_ratio = nan is not a finite number: expected more than 0 and at "
     "most 1000 (motor revolutions per joint revolution)"},
    {"negative_infinity", "gear_ratio = 15.0", "gear_ratio = -inf",
     "instrument[0].pitch.gear_ratio = -inf is not a finite number: expected more than 0"},
    {"string_for_number", "gear_ratio = 15.0", "gear_ratio = \"fast\"",
     "instrument[0].pitch.gear_ratio = \"fast\" has type string: expected number (motor "
     "revolutions per joint revolution)"},
    {"float_for_integer", "counts_per_rev = 4096", "counts_per_rev = 4096.0",
     "instrument[0].pitch.counts_per_rev = 4096.0 has type float: expected integer (encoder "
     "counts per motor revolution, after quadrature)"},
    {"integer_range_lower", "counts_per_rev = 4096", "counts_per_rev = 0",
     "instrument[0].pitch.counts_per_rev = 0 is out of range: expected 1 to 16777216 (encoder "
     "counts per motor revolution, after quadrature)"},
    {"integer_range_upper", "counts_per_rev = 4096", "counts_per_rev = 16777217",
     "instrument[0].pitch.counts_per_rev = 16777217 is out of range: expected 1 to 16777216"},
    {"substep_lower", "plant_substep_us = 100", "plant_substep_us = 0",
     "device.plant_substep_us = 0 is out of range: expected 1 to 1000 (microseconds)"},
    {"substep_upper", "plant_substep_us = 100", "plant_substep_us = 1001",
     "device.plant_substep_us = 1001 is out of range: expected 1 to 1000 (microseconds)"},
    {"unknown_backend", "backend = \"sim\"", "backend = \"socketcan\"",
     "device.backend = \"socketcan\": expected one of: sim, canopen, usb (GPIO lines combine "
     "with any of them through [device] digital_io = \"gpio\")"},
    {"device_name", "name = \"sim-two-port\"", "name = \"sim two port\"",
     "device.name = \"sim two port\": expected a name of 1 to 32 characters from A-Z, a-z, "
     "0-9, '_' and '-'"},
    {"bit_upper", "estop_input_bit = 0", "estop_input_bit = 32",
     "digital.estop_input_bit = 32 is out of range: expected -1 to 31 (bit of the digital "
     "input word, -1 = not wired)"},
    {"bit_lower", "drive_enable_output_bit = 0", "drive_enable_output_bit = -2",
     "digital.drive_enable_output_bit = -2 is out of range: expected -1 to 31 (bit of the "
     "digital output word, -1 = not wired)"},
    {"duplicate_input_bit", "enable_input_bit = 1", "enable_input_bit = 0",
     "digital.enable_input_bit = 0 is already used by digital.estop_input_bit: expected "
     "distinct input bits"},
    {"duplicate_output_bit", "fault_lamp_output_bit = 1", "fault_lamp_output_bit = 0",
     "digital.fault_lamp_output_bit = 0 is already used by digital.drive_enable_output_bit: "
     "expected distinct output bits"},
    {"vector_component_nan", "trocar_position_m = [-0.05, 0.0, 0.0]",
     "trocar_position_m = [nan, 0.0, 0.0]",
     "instrument[0].trocar_position_m[0] = nan is not a finite number: expected -10 to 10 "
     "(metres, trainer frame)"},
    {"vector_component_range", "trocar_position_m = [-0.05, 0.0, 0.0]",
     "trocar_position_m = [-0.05, 0.0, 11]",
     "instrument[0].trocar_position_m[2] = 11 is out of range: expected -10 to 10 (metres, "
     "trainer frame)"},
    {"vector_length", "trocar_position_m = [-0.05, 0.0, 0.0]", "trocar_position_m = [-0.05, 0.0]",
     "instrument[0].trocar_position_m = [-0.05, 0.0] has 2 elements: expected an array of 3 "
     "numbers (metres, trainer frame)"},
    {"vector_type", "trocar_position_m = [-0.05, 0.0, 0.0]", "trocar_position_m = 0.1",
     "instrument[0].trocar_position_m = 0.1 has type float: expected an array of 3 numbers"},
    {"zero_direction", "shaft_axis = [0.0, 0.0, -1.0]", "shaft_axis = [0, 0, 0]",
     "instrument[0].shaft_axis = [0, 0, 0] is a zero vector: expected a direction of length at "
     "least 1e-09 (it is normalised on load)"},
    {"non_orthogonal_up_axis", "up_axis = [0.0, 1.0, 0.0]", "up_axis = [0.0, 1.0, 0.1]",
     "instrument[0].up_axis = [0.0, 1.0, 0.1] is not orthogonal to shaft_axis [0, 0, -1] "
     "(cosine of the angle between them = -0.0995): expected orthogonal within 1e-06"},
    {"duplicate_instrument_name", "name = \"right\"", "name = \"left\"",
     "instrument[1].name = \"left\" duplicates instrument[0].name: expected unique instrument "
     "names"},
    {"bad_instrument_name", "name = \"left\"", "name = \"\"",
     "instrument[0].name = \"\": expected a name of 1 to 32 characters"},
    {"shaft_length_upper", "shaft_length_m = 0.36", "shaft_length_m = 1.5",
     "instrument[0].shaft_length_m = 1.5 is out of range: expected more than 0 and at most 1 "
     "(metres, trocar-side end to jaw hinge)"},
    {"jaw_length_upper", "jaw_length_m = 0.015", "jaw_length_m = 0.2",
     "instrument[0].jaw_length_m = 0.2 is out of range: expected more than 0 and at most 0.1 "
     "(metres, jaw hinge to jaw tip)"},
    {"revolute_min_not_below_max", "min_rad = -0.6", "min_rad = 0.6",
     "instrument[0].pitch.max_rad = 0.6 is not greater than min_rad = 0.6: expected min_rad < "
     "max_rad (radians)",
     1},
    {"prismatic_min_above_max", "min_m = 0.0", "min_m = 0.3",
     "instrument[0].insertion.max_m = 0.25 is not greater than min_m = 0.3: expected min_m < "
     "max_m (metres)",
     1},
    {"revolute_limit_range", "max_rad = 0.6", "max_rad = 25",
     "instrument[0].pitch.max_rad = 25 is out of range: expected -20 to 20 (radians)"},
    {"hand_stiffness_negative", "hand_stiffness_nm_per_rad = 5.0", "hand_stiffness_nm_per_rad = -1",
     "instrument[0].pitch.hand_stiffness_nm_per_rad = -1 is out of range: expected 0 to "
     "1000000 (newton-metres per radian)"},
    {"mass_zero", "mass_kg = 0.15", "mass_kg = 0.0",
     "instrument[0].insertion.mass_kg = 0.0 is out of range: expected more than 0 and at most "
     "100 (kilograms, reflected to the joint)"},
    {"capstan_radius_range", "capstan_radius_m = 0.01", "capstan_radius_m = 0.5",
     "instrument[0].insertion.capstan_radius_m = 0.5 is out of range: expected more than 0 and "
     "at most 0.1 (metres)"},
    {"typo_in_key", "current_limit_a = 3.0", "current_limt_a = 3.0",
     "unknown key 'instrument[0].pitch.current_limt_a' (known: counts_per_rev, gear_ratio, "
     "torque_constant_nm_per_a, current_limit_a, min_rad, max_rad, inertia_kg_m2, "
     "hand_stiffness_nm_per_rad, hand_damping_nms_per_rad, encoder_direction, motor_direction); "
     "did you mean 'current_limit_a'?"},
    {"encoder_direction_zero", "hand_damping_nms_per_rad = 0.1",
     "hand_damping_nms_per_rad = 0.1\nencoder_direction = 0",
     "instrument[0].pitch.encoder_direction = 0: expected 1 or -1 (+1 as designed, -1 when the "
     "encoder counts down for a positive joint motion)",
     1},
    {"motor_direction_range", "hand_damping_nms_per_rad = 0.1",
     "hand_damping_nms_per_rad = 0.1\nmotor_direction = 2",
     "instrument[0].pitch.motor_direction = 2 is out of range: expected -1 to 1 (+1 as designed, "
     "-1 when a positive motor torque turns the joint negative)",
     1},
    {"prismatic_key_on_revolute_joint", "gear_ratio = 15.0",
     "gear_ratio = 15.0\ncapstan_radius_m = 0.01",
     "unknown key 'instrument[0].pitch.capstan_radius_m' (known: ", 1},
    {"unknown_table", "[digital]", "[digital]\n[digitals]\nx = 1",
     "unknown key 'digitals' (known: device, digital, telemetry, instrument); did you mean 'digital'?", 1},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, DeviceErrorTest, ::testing::ValuesIn(kDeviceErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// With its header gone, the [digital] keys land in [device]: the first of them is the specific
// error, not the consequence that [digital] is missing.
TEST_F(DeviceFileTest, KeysInTheWrongTableAreUnknownThere) {
  const std::string text = read_text(repo_path("config/devices/sim.toml"));
  const auto edited = replace_first(text, "[digital]", "");
  const auto path = write("sim.toml", edited.text);
  const std::string message = error_message(load_device(path));
  expect_contains(message, path.string() + ":" +
                               std::to_string(line_of(edited.text, "estop_input_bit")) +
                               ": unknown key 'device.estop_input_bit' (known: name, backend, "
                               "plant_substep_us, digital_io)");
}

// ---------------------------------------------------------------- backend "canopen"

TEST(CanopenDeviceFile, LoadsTheBusAndEveryJointsDrive) {
  const auto device = load_device(repo_path("config/devices/canopen_vcan.toml"));
  ASSERT_TRUE(device.has_value()) << device.error().message;
  EXPECT_EQ(device->backend, "canopen");
  const CanopenConfig& bus = device->canopen;
  EXPECT_EQ(bus.interface, "vcan0");
  EXPECT_EQ(bus.bitrate, 0U);  // vcan: a virtual bus
  EXPECT_EQ(bus.sync_period_ns, 0);  // SYNC every loop period
  EXPECT_EQ(bus.master_node_id, 127);
  EXPECT_EQ(bus.master_heartbeat_ns, 10'000'000);
  EXPECT_EQ(bus.drive_heartbeat_consumer_ns, 30'000'000);
  EXPECT_EQ(bus.drive_heartbeat_ns, 10'000'000);
  EXPECT_EQ(bus.drive_heartbeat_timeout_ns, 30'000'000);
  EXPECT_EQ(bus.rpdo_timeout_ns, 10'000'000);
  EXPECT_EQ(bus.abort_connection, AbortConnectionOption::quick_stop);
  EXPECT_EQ(bus.sdo_timeout_ns, 100'000'000);
  EXPECT_EQ(bus.boot_timeout_ns, 3'000'000'000);
  EXPECT_EQ(bus.digital_inputs_node, 1);
  EXPECT_EQ(bus.digital_outputs_node, 1);
  ASSERT_EQ(device->instruments.size(), 2U);
  // Nodes 1..10 in file order; the hexadecimal identity as written.
  std::uint8_t expected_node = 1;
  for (const auto& instrument : device->instruments) {
    for (const auto& joint : instrument.joints) {
      EXPECT_EQ(joint.canopen.node_id, expected_node++);
      EXPECT_EQ(joint.canopen.vendor_id, 0x00545252U);
      EXPECT_EQ(joint.canopen.product_code, 0x402U);
      EXPECT_FALSE(joint.canopen.revision.has_value());
      EXPECT_GT(joint.canopen.motor_rated_torque_nm, 0.0);
    }
  }
  // The mechanism is sim.toml's, so simdrive's plant is the simulated bench's.
  const auto sim = load_device(repo_path("config/devices/sim.toml"));
  ASSERT_TRUE(sim.has_value());
  EXPECT_DOUBLE_EQ(device->instruments[1].joints[2].gear_ratio,
                   sim->instruments[1].joints[2].gear_ratio);
  EXPECT_EQ(sim->instruments[0].joints[0].canopen.node_id, 0);  // sim: no drives
}

struct CanopenErrorCase {
  const char* name;
  const char* from;  // first occurrence in config/devices/canopen_vcan.toml is replaced
  const char* to;
  const char* expected;
};

std::ostream& operator<<(std::ostream& stream, const CanopenErrorCase& error_case) {
  return stream << error_case.name;
}

class CanopenErrorTest : public ConfigFileTest,
                         public ::testing::WithParamInterface<CanopenErrorCase> {};

TEST_P(CanopenErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const CanopenErrorCase& error_case = GetParam();
  const std::string text = read_text(repo_path("config/devices/canopen_vcan.toml"));
  const auto edited = replace_first(text, error_case.from, error_case.to);
  const auto path = write("devices/can.toml", edited.text);
  const std::string message = error_message(load_device(path));
  expect_contains(message, path.string() + ":" + std::to_string(edited.line) + ": " +
                               error_case.expected);
}

const CanopenErrorCase kCanopenErrorCases[] = {
    {"node_id_zero", "node_id = 1 ", "node_id = 0 ",
     "instrument[0].pitch.node_id = 0 is out of range: expected 1 to 127 (CANopen node id)"},
    {"node_id_duplicate", "node_id = 2", "node_id = 1",
     "instrument[0].yaw.node_id = 1 is already used by instrument[0].pitch.node_id: expected a "
     "node id unique on the bus"},
    {"node_id_is_the_masters", "node_id = 10", "node_id = 127",
     "instrument[1].grip.node_id = 127 is already used by canopen.master_node_id"},
    {"vendor_id_too_large", "vendor_id = 0x00545252", "vendor_id = 0x100000000",
     "instrument[0].pitch.vendor_id = 4294967296 is out of range: expected 0 to 4294967295"},
    {"rated_torque_zero", "motor_rated_torque_nm = 0.060", "motor_rated_torque_nm = 0",
     "instrument[0].pitch.motor_rated_torque_nm = 0 is out of range: expected more than 0"},
    {"interface_too_long", "interface = \"vcan0\"", "interface = \"can_interface_16\"",
     "canopen.interface = \"can_interface_16\": expected 1..15 characters"},
    {"sync_too_fast", "sync_period_us = 0 ", "sync_period_us = 50 ",
     "canopen.sync_period_us = 50: expected 0 (SYNC every loop period) or 100 to 100000"},
    {"sync_too_slow", "sync_period_us = 0 ", "sync_period_us = 100001 ",
     "canopen.sync_period_us = 100001 is out of range: expected 0 to 100000"},
    {"consumer_shorter_than_two_master_beats", "drive_heartbeat_consumer_ms = 30",
     "drive_heartbeat_consumer_ms = 15",
     "canopen.drive_heartbeat_consumer_ms = 15: expected at least twice master_heartbeat_ms = "
     "10"},
    {"master_consumer_too_short", "drive_heartbeat_timeout_ms = 30",
     "drive_heartbeat_timeout_ms = 19",
     "canopen.drive_heartbeat_timeout_ms = 19: expected at least twice drive_heartbeat_ms = 10"},
    {"abort_option_unknown", "abort_connection = \"quick_stop\"",
     "abort_connection = \"ignore\"",
     "canopen.abort_connection = \"ignore\": expected one of: fault_signal, disable_voltage, "
     "quick_stop"},
    {"digital_node_not_a_drive", "digital_inputs_node = 1", "digital_inputs_node = 42",
     "canopen.digital_inputs_node = 42: expected -1 or the node_id of one of the joints' "
     "drives"},
    {"bitrate_below_real_buses", "bitrate = 0 ", "bitrate = 5000 ",
     "canopen.bitrate = 5000: expected 0 (a virtual bus, no load limit) or 10000 to 1000000"},
    {"unknown_canopen_key", "bitrate = 0 ", "bitrat = 0 ",
     "unknown key 'canopen.bitrat'"},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, CanopenErrorTest, ::testing::ValuesIn(kCanopenErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(DeviceFileTest, AnRpdoDeadlineShorterThanTwoSyncsIsRefusedAtItsLine) {
  const std::string text = read_text(repo_path("config/devices/canopen_vcan.toml"));
  const auto edited = replace_first(text, "sync_period_us = 0 ", "sync_period_us = 6000 ");
  const auto path = write("can.toml", edited.text);
  expect_contains(error_message(load_device(path)),
                  path.string() + ":" + std::to_string(line_of(edited.text, "rpdo_timeout_ms")) +
                      ": canopen.rpdo_timeout_ms = 10: expected at least two SYNC periods "
                      "(sync_period_us = 6000)");
}

TEST_F(DeviceFileTest, CanopenWithoutItsTableIsAMissingTable) {
  const std::string text = read_text(repo_path("config/devices/canopen_vcan.toml"));
  std::string edited = text;
  const auto begin = edited.find("[canopen]");
  const auto end = edited.find("[digital]");
  edited.erase(begin, end - begin);
  const std::string message = error_message(load_device(write("can.toml", edited)));
  expect_contains(message, "[canopen]");
}

TEST_F(DeviceFileTest, ACanopenTableInASimFileIsUnknown) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const std::string message =
      error_message(load_device(write("sim.toml", sim + "\n[canopen]\ninterface = \"can0\"\n")));
  expect_contains(message, "unknown key 'canopen'");
}

TEST_F(DeviceFileTest, CanopenJointKeysInASimFileAreUnknown) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const auto edited = replace_first(sim, "counts_per_rev = 4096", "node_id = 1\ncounts_per_rev = 4096");
  const std::string message = error_message(load_device(write("sim.toml", edited.text)));
  expect_contains(message, "unknown key 'instrument[0].pitch.node_id'");
}

}  // namespace
}  // namespace trainer::config

// ---------------------------------------------------------------- backend "usb"

namespace trainer::config {
namespace {

TEST(UsbDeviceFile, LoadsTheUsbTableAndTheSimMechanism) {
  const auto device = load_device(repo_path("config/devices/usb_benchvm.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->backend, "usb");
  const UsbConfig& usb = device->usb;
  EXPECT_EQ(usb.vendor_id, 0x1209);
  EXPECT_EQ(usb.product_id, 0x0001);
  EXPECT_EQ(usb.serial, "usbgadget-0001");
  EXPECT_EQ(usb.protocol_version, 1);
  ASSERT_TRUE(usb.min_firmware_version.has_value());
  EXPECT_EQ(*usb.min_firmware_version, 0x0100);
  EXPECT_EQ(usb.watchdog_ms, 100);
  EXPECT_EQ(usb.stale_limit_cycles, 5U);
  EXPECT_EQ(usb.control_timeout_ns, 100'000'000);
  EXPECT_EQ(usb.start_timeout_ns, 2'000'000'000);
  EXPECT_EQ(usb.stop_timeout_ns, 100'000'000);
  EXPECT_EQ(usb.event_poll_ns, 10'000'000);
  // The mechanism is sim.toml's, joint for joint.
  const auto sim = load_device(repo_path("config/devices/sim.toml"));
  ASSERT_TRUE(sim);
  ASSERT_EQ(device->instruments.size(), sim->instruments.size());
  for (std::size_t i = 0; i < sim->instruments.size(); ++i) {
    for (std::size_t j = 0; j < kJointCount; ++j) {
      const JointConfig& a = device->instruments[i].joints[j];
      const JointConfig& b = sim->instruments[i].joints[j];
      EXPECT_EQ(a.counts_per_rev, b.counts_per_rev);
      EXPECT_EQ(a.gear_ratio, b.gear_ratio);
      EXPECT_EQ(a.current_limit_a, b.current_limit_a);
      EXPECT_EQ(a.inertia, b.inertia);
    }
  }
}

struct UsbErrorCase {
  const char* name;
  const char* from;  // first occurrence in config/devices/usb_benchvm.toml is replaced
  const char* to;
  const char* expected;
};

std::ostream& operator<<(std::ostream& stream, const UsbErrorCase& error_case) {
  return stream << error_case.name;
}

class UsbErrorTest : public ConfigFileTest, public ::testing::WithParamInterface<UsbErrorCase> {};

TEST_P(UsbErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const UsbErrorCase& error_case = GetParam();
  const std::string text = read_text(repo_path("config/devices/usb_benchvm.toml"));
  const auto edited = replace_first(text, error_case.from, error_case.to);
  const auto path = write("devices/usb.toml", edited.text);
  const std::string message = error_message(load_device(path));
  expect_contains(message, path.string() + ":" + std::to_string(edited.line) + ": " +
                               error_case.expected);
}

const UsbErrorCase kUsbErrorCases[] = {
    {"vendor_id_too_large", "vendor_id = 0x1209", "vendor_id = 0x10000",
     "usb.vendor_id = 65536 is out of range: expected 0 to 65535 (USB vendor id (idVendor))"},
    {"product_id_negative", "product_id = 0x0001", "product_id = -1",
     "usb.product_id = -1 is out of range: expected 0 to 65535"},
    {"serial_not_a_string", "serial = \"usbgadget-0001\"", "serial = 1",
     "usb.serial"},
    {"serial_too_long", "serial = \"usbgadget-0001\"",
     "serial = \"0123456789012345678901234567890123456789012345678901234567890123456789"
     "0123456789012345678901234567890123456789012345678901234567\"",
     "usb.serial = \"0123456789012345678901234567890123456789012345678901234567890123456789"
     "0123456789012345678901234567890123456789012345678901234567\": expected at most 126 "
     "characters (a USB string descriptor)"},
    {"protocol_version_unknown", "protocol_version = 1 ", "protocol_version = 2 ",
     "usb.protocol_version = 2 is out of range: expected 1 to 1 (the protocol version this "
     "build speaks)"},
    {"watchdog_too_short", "watchdog_ms = 100", "watchdog_ms = 1",
     "usb.watchdog_ms = 1 is out of range: expected 2 to 1000 (milliseconds, the device's "
     "watchdog)"},
    {"stale_limit_zero", "stale_limit_cycles = 5", "stale_limit_cycles = 0",
     "usb.stale_limit_cycles = 0 is out of range: expected 1 to 1000"},
    {"control_timeout_zero", "control_timeout_ms = 100", "control_timeout_ms = 0",
     "usb.control_timeout_ms = 0 is out of range: expected 1 to 10000 (milliseconds)"},
    {"start_timeout_too_long", "start_timeout_ms = 2000", "start_timeout_ms = 60001",
     "usb.start_timeout_ms = 60001 is out of range: expected 1 to 60000"},
    {"event_poll_too_short", "event_poll_us = 10000", "event_poll_us = 10",
     "usb.event_poll_us = 10 is out of range: expected 50 to 100000 (microseconds)"},
    {"firmware_too_large", "min_firmware_version = 0x0100", "min_firmware_version = 0x10000",
     "usb.min_firmware_version = 65536 is out of range: expected 0 to 65535"},
    {"unknown_usb_key", "watchdog_ms = 100", "watchdog = 100",
     "unknown key 'usb.watchdog'"},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, UsbErrorTest, ::testing::ValuesIn(kUsbErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(DeviceFileTest, UsbWithoutItsTableIsAMissingTable) {
  std::string text = read_text(repo_path("config/devices/usb_benchvm.toml"));
  const auto begin = text.find("[usb]");
  const auto end = text.find("[digital]");
  text.erase(begin, end - begin);
  expect_contains(error_message(load_device(write("usb.toml", text))), "[usb]");
}

TEST_F(DeviceFileTest, AUsbTableInASimFileIsUnknown) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const std::string message =
      error_message(load_device(write("sim.toml", sim + "\n[usb]\nserial = \"x\"\n")));
  expect_contains(message, "unknown key 'usb'");
}

TEST_F(DeviceFileTest, UsbCarriesAtMostSixteenChannelsSoThreeInstruments) {
  const std::string text = read_text(repo_path("config/devices/usb_benchvm.toml"));
  const auto first = text.find("[[instrument]]");
  const auto second = text.find("[[instrument]]", first + 1);
  const std::string one = text.substr(first, second - first);
  std::string four = text;
  for (int copy = 0; copy < 2; ++copy) {
    std::string extra = one;
    const std::string from = "name = \"left\"";
    extra.replace(extra.find(from), from.size(), "name = \"extra" + std::to_string(copy) + "\"");
    four += "\n" + extra;
  }
  const auto path = write("usb4.toml", four);
  const std::string message = error_message(load_device(path));
  expect_contains(message, "instrument[3].name = \"extra1\" is instrument 4: backend \"usb\" "
                           "carries one channel per joint and at most 16 channels: expected at "
                           "most 3 instruments");
}

// ---------------------------------------------------------------- [telemetry]

TEST(TelemetryDeviceKeys, AbsentTableMeansNoStream) {
  const auto device = load_device(repo_path("config/devices/sim.toml"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_FALSE(device->telemetry.enabled);
}

TEST_F(DeviceFileTest, TelemetryTableLoadsWithItsDefaults) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const auto device = load_device(
      write("sim.toml", sim + "\n[telemetry]\naddress = \"192.168.7.20\"\nport = 47800\n"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_TRUE(device->telemetry.enabled);
  EXPECT_EQ(device->telemetry.address, "192.168.7.20");
  EXPECT_EQ(device->telemetry.port, 47800);
  EXPECT_EQ(device->telemetry.rate_hz, 60U);
  EXPECT_EQ(device->telemetry.source_port, 0);
  const auto v6 = load_device(write(
      "sim6.toml", sim + "\n[telemetry]\naddress = \"fd00::20\"\nport = 9\nrate_hz = 120\n"));
  ASSERT_TRUE(v6) << v6.error().message;
  EXPECT_EQ(v6->telemetry.address, "fd00::20");
  EXPECT_EQ(v6->telemetry.rate_hz, 120U);
}

TEST_F(DeviceFileTest, ADisabledTelemetryTableNeedsNoDestination) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const auto device = load_device(write("sim.toml", sim + "\n[telemetry]\nenabled = false\n"));
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_FALSE(device->telemetry.enabled);
}

struct TelemetryErrorCase {
  const char* name;
  const char* table;     // appended to config/devices/sim.toml after "[telemetry]"
  const char* key_line;  // the line the message must name (its text)
  const char* expected;
};

std::ostream& operator<<(std::ostream& stream, const TelemetryErrorCase& error_case) {
  return stream << error_case.name;
}

class TelemetryErrorTest : public ConfigFileTest,
                           public ::testing::WithParamInterface<TelemetryErrorCase> {};

TEST_P(TelemetryErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const TelemetryErrorCase& error_case = GetParam();
  const std::string text = read_text(repo_path("config/devices/sim.toml")) + "\n[telemetry]\n" +
                           error_case.table;
  const auto path = write("devices/sim.toml", text);
  const std::string message = error_message(load_device(path));
  expect_contains(message, path.string() + ":" + std::to_string(line_of(text, error_case.key_line)) +
                               ": " + error_case.expected);
}

const TelemetryErrorCase kTelemetryErrorCases[] = {
    {"rate_too_low", "address = \"127.0.0.1\"\nport = 47800\nrate_hz = 10\n", "rate_hz = 10",
     "telemetry.rate_hz = 10 is out of range: expected 30 to 120 (frames per second)"},
    {"rate_too_high", "address = \"127.0.0.1\"\nport = 47800\nrate_hz = 1000\n", "rate_hz = 1000",
     "telemetry.rate_hz = 1000 is out of range: expected 30 to 120"},
    {"port_zero", "address = \"127.0.0.1\"\nport = 0\n", "port = 0",
     "telemetry.port = 0 is out of range: expected 1 to 65535 (UDP port)"},
    {"port_too_large", "address = \"127.0.0.1\"\nport = 70000\n", "port = 70000",
     "telemetry.port = 70000 is out of range: expected 1 to 65535"},
    {"host_name", "address = \"viewer.local\"\nport = 47800\n", "address = \"viewer.local\"",
     "telemetry.address = \"viewer.local\": expected a numeric IPv4 (192.168.1.20) or IPv6 "
     "(fd00::20) address; host names are not looked up"},
    {"address_and_port_written_together", "address = \"127.0.0.1:47800\"\nport = 47800\n",
     "address = \"127.0.0.1:47800\"", "telemetry.address = \"127.0.0.1:47800\": expected a numeric"},
    {"source_port_too_large", "address = \"127.0.0.1\"\nport = 47800\nsource_port = 65536\n",
     "source_port = 65536",
     "telemetry.source_port = 65536 is out of range: expected 0 to 65535 (local UDP port, 0 = any)"},
    {"unknown_key", "address = \"127.0.0.1\"\nport = 47800\nrate = 60\n", "rate = 60",
     "unknown key 'telemetry.rate'"},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, TelemetryErrorTest, ::testing::ValuesIn(kTelemetryErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

TEST_F(DeviceFileTest, AnEnabledTelemetryTableNeedsItsDestination) {
  const std::string sim = read_text(repo_path("config/devices/sim.toml"));
  const std::string message = error_message(load_device(write("sim.toml", sim + "\n[telemetry]\nport = 47800\n")));
  expect_contains(message, "telemetry.address");
}

}  // namespace
}  // namespace trainer::config
