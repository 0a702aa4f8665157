// The device file schema: [device], [digital], [[instrument]] with one sub-table per joint.
// Every key, unit, range and default here is documented in docs/config.md; keep them in step.
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>

#include "table_reader.hpp"
#include "trainer/config/device.hpp"
#include "value_text.hpp"

namespace trainer::config {

std::string_view to_string(JointId joint) noexcept {
  switch (joint) {
    case JointId::pitch: return "pitch";
    case JointId::yaw: return "yaw";
    case JointId::insertion: return "insertion";
    case JointId::roll: return "roll";
    case JointId::grip: return "grip";
  }
  return "unknown";
}

hal::JointScale joint_scale(const JointConfig& joint) noexcept {
  hal::JointScale scale;
  scale.kind = joint.kind;
  scale.counts_per_rev = joint.counts_per_rev;
  scale.gear_ratio = joint.gear_ratio;
  scale.capstan_radius_m = joint.capstan_radius_m;
  scale.torque_constant_nm_per_a = joint.torque_constant_nm_per_a;
  scale.current_limit_a = joint.current_limit_a;
  return scale;
}

namespace {

using detail::ErrorSink;
using detail::kNanosecondsPerMicrosecond;
using detail::IntRange;
using detail::RealRange;
using detail::TableReader;

constexpr std::array<std::string_view, 1> kBackends = {"sim"};
constexpr std::string_view kBackendNote =
    "socketcan, gpiod and usb backends are not implemented yet";

constexpr IntRange kPlantSubstepRangeUs{1, 1000};
constexpr std::int64_t kDefaultPlantSubstepUs = 100;

constexpr IntRange kBitRange{-1, 31};
constexpr int kNotWired = -1;

constexpr RealRange kTrocarComponentRangeM = RealRange::closed(-10.0, 10.0);
constexpr RealRange kShaftLengthRangeM = RealRange::left_open(0.0, 1.0);
constexpr RealRange kJawLengthRangeM = RealRange::left_open(0.0, 0.1);
// Unit vectors are orthogonal when |cos angle| is below this (after normalising both).
constexpr double kOrthogonalityTolerance = 1e-6;

constexpr IntRange kCountsPerRevRange{1, std::int64_t{1} << 24};
constexpr RealRange kGearRatioRange = RealRange::left_open(0.0, 1000.0);
constexpr RealRange kCapstanRadiusRangeM = RealRange::left_open(0.0, 0.1);
constexpr RealRange kTorqueConstantRange = RealRange::left_open(0.0, 10.0);
constexpr RealRange kCurrentLimitRangeA = RealRange::left_open(0.0, 100.0);
constexpr RealRange kRevoluteLimitRangeRad = RealRange::closed(-20.0, 20.0);
constexpr RealRange kPrismaticLimitRangeM = RealRange::closed(-1.0, 1.0);
constexpr RealRange kInertiaRange = RealRange::left_open(0.0, 100.0);
constexpr RealRange kHandStiffnessRange = RealRange::closed(0.0, 1e6);
constexpr RealRange kHandDampingRange = RealRange::closed(0.0, 1e4);

// Simulated-plant defaults: a small laparoscopic handle and a relaxed hand.
constexpr double kDefaultInertiaKgM2 = 0.002;
constexpr double kDefaultMassKg = 0.15;
constexpr double kDefaultHandStiffnessNmPerRad = 5.0;
constexpr double kDefaultHandDampingNmsPerRad = 0.1;
constexpr double kDefaultHandStiffnessNPerM = 1500.0;
constexpr double kDefaultHandDampingNsPerM = 15.0;

// Key names and units differ between revolute and prismatic joints; the schema is the same.
struct JointKeys {
  std::string_view min_key;
  std::string_view max_key;
  std::string_view limit_unit;
  std::string_view inertia_key;
  std::string_view inertia_unit;
  double default_inertia;
  std::string_view stiffness_key;
  std::string_view stiffness_unit;
  double default_stiffness;
  std::string_view damping_key;
  std::string_view damping_unit;
  double default_damping;
  RealRange limit_range;
};

constexpr JointKeys kRevoluteKeys{
    .min_key = "min_rad",
    .max_key = "max_rad",
    .limit_unit = "radians",
    .inertia_key = "inertia_kg_m2",
    .inertia_unit = "kilogram square metres, reflected to the joint",
    .default_inertia = kDefaultInertiaKgM2,
    .stiffness_key = "hand_stiffness_nm_per_rad",
    .stiffness_unit = "newton-metres per radian",
    .default_stiffness = kDefaultHandStiffnessNmPerRad,
    .damping_key = "hand_damping_nms_per_rad",
    .damping_unit = "newton-metre-seconds per radian",
    .default_damping = kDefaultHandDampingNmsPerRad,
    .limit_range = kRevoluteLimitRangeRad,
};

constexpr JointKeys kPrismaticKeys{
    .min_key = "min_m",
    .max_key = "max_m",
    .limit_unit = "metres",
    .inertia_key = "mass_kg",
    .inertia_unit = "kilograms, reflected to the joint",
    .default_inertia = kDefaultMassKg,
    .stiffness_key = "hand_stiffness_n_per_m",
    .stiffness_unit = "newtons per metre",
    .default_stiffness = kDefaultHandStiffnessNPerM,
    .damping_key = "hand_damping_ns_per_m",
    .damping_unit = "newton-seconds per metre",
    .default_damping = kDefaultHandDampingNsPerM,
    .limit_range = kPrismaticLimitRangeM,
};

JointConfig read_joint(TableReader& table, hal::JointKind kind, ErrorSink& errors) {
  const bool prismatic = kind == hal::JointKind::prismatic;
  const JointKeys& keys = prismatic ? kPrismaticKeys : kRevoluteKeys;
  JointConfig joint;
  joint.kind = kind;
  joint.counts_per_rev = static_cast<std::int32_t>(
      table.required_int("counts_per_rev", kCountsPerRevRange,
                         "encoder counts per motor revolution, after quadrature"));
  joint.gear_ratio = table.required_double("gear_ratio", kGearRatioRange,
                                           "motor revolutions per joint revolution");
  if (prismatic) {
    joint.capstan_radius_m =
        table.required_double("capstan_radius_m", kCapstanRadiusRangeM, "metres");
  }
  joint.torque_constant_nm_per_a = table.required_double(
      "torque_constant_nm_per_a", kTorqueConstantRange, "newton-metres per ampere");
  joint.current_limit_a = table.required_double("current_limit_a", kCurrentLimitRangeA, "amperes");
  joint.min_position = table.required_double(keys.min_key, keys.limit_range, keys.limit_unit);
  joint.max_position = table.required_double(keys.max_key, keys.limit_range, keys.limit_unit);
  joint.inertia = table.optional_double(keys.inertia_key, keys.default_inertia, kInertiaRange,
                                        keys.inertia_unit);
  joint.hand_stiffness = table.optional_double(keys.stiffness_key, keys.default_stiffness,
                                               kHandStiffnessRange, keys.stiffness_unit);
  joint.hand_damping = table.optional_double(keys.damping_key, keys.default_damping,
                                             kHandDampingRange, keys.damping_unit);
  if (errors.ok() && joint.min_position >= joint.max_position) {
    table.fail_value(keys.max_key, " is not greater than " + std::string(keys.min_key) + " = " +
                                       detail::format_number(joint.min_position) + ": expected " +
                                       std::string(keys.min_key) + " < " +
                                       std::string(keys.max_key) + " (" +
                                       std::string(keys.limit_unit) + ")");
  }
  table.finish();
  return joint;
}

double dot(const Vec3& a, const Vec3& b) noexcept {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

std::string format_vec3(const Vec3& vector) {
  // Appended piece by piece: GCC 12 at -O3 raises a false -Wrestrict on "literal" + string.
  std::string text = "[";
  for (std::size_t i = 0; i < vector.size(); ++i) {
    if (i > 0) text += ", ";
    text += detail::format_number(vector[i]);
  }
  text += "]";
  return text;
}

InstrumentDeviceConfig read_instrument(TableReader& table, ErrorSink& errors) {
  InstrumentDeviceConfig instrument;
  instrument.name = table.required_name("name");
  instrument.trocar_position_m =
      table.required_vec3("trocar_position_m", kTrocarComponentRangeM, "metres, trainer frame");
  instrument.shaft_axis = table.required_direction("shaft_axis");
  instrument.up_axis = table.required_direction("up_axis");
  if (errors.ok()) {
    const double cosine = dot(instrument.shaft_axis, instrument.up_axis);
    if (std::fabs(cosine) > kOrthogonalityTolerance) {
      table.fail_value(
          "up_axis",
          " is not orthogonal to shaft_axis " + format_vec3(instrument.shaft_axis) +
              " (cosine of the angle between them = " + detail::format_significant(cosine) +
              "): expected orthogonal within " + detail::format_number(kOrthogonalityTolerance));
    } else {
      // Remove the residual (at most 1e-6) so kinematics gets an exactly orthonormal pair.
      Vec3& up = instrument.up_axis;
      for (std::size_t i = 0; i < 3; ++i) up[i] -= cosine * instrument.shaft_axis[i];
      const double length = std::sqrt(dot(up, up));
      for (double& component : up) component /= length;
    }
  }
  instrument.shaft_length_m = table.required_double("shaft_length_m", kShaftLengthRangeM,
                                                    "metres, trocar-side end to jaw hinge");
  instrument.jaw_length_m =
      table.required_double("jaw_length_m", kJawLengthRangeM, "metres, jaw hinge to jaw tip");
  for (std::size_t i = 0; i < kJointCount; ++i) {
    const auto joint_id = static_cast<JointId>(i);
    const auto kind =
        joint_id == JointId::insertion ? hal::JointKind::prismatic : hal::JointKind::revolute;
    TableReader joint_table = table.required_table(to_string(joint_id));
    instrument.joints[i] = read_joint(joint_table, kind, errors);
  }
  table.finish();
  return instrument;
}

DigitalConfig read_digital(TableReader& table, ErrorSink& errors) {
  constexpr std::string_view kInputUnit = "bit of the digital input word, -1 = not wired";
  constexpr std::string_view kOutputUnit = "bit of the digital output word, -1 = not wired";
  DigitalConfig digital;
  digital.estop_input_bit =
      static_cast<int>(table.required_int("estop_input_bit", kBitRange, kInputUnit));
  digital.enable_input_bit =
      static_cast<int>(table.required_int("enable_input_bit", kBitRange, kInputUnit));
  digital.drive_enable_output_bit =
      static_cast<int>(table.required_int("drive_enable_output_bit", kBitRange, kOutputUnit));
  digital.fault_lamp_output_bit =
      static_cast<int>(table.required_int("fault_lamp_output_bit", kBitRange, kOutputUnit));
  // Inputs and outputs are separate words (HAL read_digital_inputs / write_digital_outputs),
  // so a bit must be unique only within its own word.
  if (errors.ok() && digital.enable_input_bit != kNotWired &&
      digital.enable_input_bit == digital.estop_input_bit) {
    table.fail_value("enable_input_bit",
                     " is already used by " + table.qualified("estop_input_bit") +
                         ": expected distinct input bits (-1 = not wired may repeat)");
  }
  if (errors.ok() && digital.fault_lamp_output_bit != kNotWired &&
      digital.fault_lamp_output_bit == digital.drive_enable_output_bit) {
    table.fail_value("fault_lamp_output_bit",
                     " is already used by " + table.qualified("drive_enable_output_bit") +
                         ": expected distinct output bits (-1 = not wired may repeat)");
  }
  table.finish();
  return digital;
}

DeviceConfig read_device(const detail::ParsedFile& parsed, ErrorSink& errors) {
  DeviceConfig config;
  config.source_path = parsed.file.absolute_path;
  TableReader root = detail::root_reader(parsed, errors);

  TableReader device = root.required_table("device");
  config.name = device.required_name("name");
  const auto backend = device.required_choice("backend", kBackends, kBackendNote);
  if (backend) config.backend = std::string(kBackends[*backend]);
  config.plant_substep_ns = device.optional_int("plant_substep_us", kDefaultPlantSubstepUs,
                                                kPlantSubstepRangeUs, "microseconds") *
                            kNanosecondsPerMicrosecond;
  device.finish();

  TableReader digital = root.required_table("digital");
  config.digital = read_digital(digital, errors);

  auto instruments = root.array_of_tables("instrument", 1, kMaxDeviceInstruments, "instruments");
  for (std::size_t i = 0; i < instruments.size(); ++i) {
    InstrumentDeviceConfig instrument = read_instrument(instruments[i], errors);
    for (std::size_t earlier = 0; errors.ok() && earlier < i; ++earlier) {
      if (config.instruments[earlier].name == instrument.name) {
        instruments[i].fail_value("name", " duplicates " + instruments[earlier].qualified("name") +
                                              ": expected unique instrument names");
      }
    }
    config.instruments.push_back(std::move(instrument));
  }
  root.finish();
  return config;
}

}  // namespace

core::Expected<DeviceConfig> load_device(const std::filesystem::path& file) {
  auto parsed = detail::parse_toml_file(file);
  if (!parsed) return std::move(parsed).error();
  ErrorSink errors;
  DeviceConfig config = read_device(*parsed, errors);
  if (!errors.ok()) return errors.error();
  return config;
}

}  // namespace trainer::config
