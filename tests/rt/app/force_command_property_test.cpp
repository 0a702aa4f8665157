// Property test of the force command, fast layer (issue 6): over at least 10^6 random and
// hostile (state, input) cases, what the forces phase of the haptic cycle hands to the HAL is
// finite, within each actuator's effort limit from the device file, and zero unless the safety
// chain is armed; the chain's own limits hold and no fault is lost.
//
// A case is one instrument in one cycle, through the real code of the cycle's forces phase:
// the supervisor's input evaluation (e-stop, drive fault, enable switch, explicit resets), its
// encoder-jump and non-finite checks of the joint positions (as the kinematics stage
// calls them), the instrument's forward kinematics and command_instrument (Jᵀ of every point
// force, finite check, magnitude clamp, slew limit, passivity observer, the device's effort
// limits) — the function the forces stage (stages/force_stage.cpp) calls. Cases come in episodes: a
// fresh supervisor for the two instruments of config/devices/sim.toml, with the wall scene's safety
// limits or random ones in their configured ranges, run for 1..200 cycles. Inputs: joint
// positions walking inside and outside the mechanism's range, encoder jumps, teleports, NaN/Inf;
// tip and point forces from zero to 1e30 N (cancelling pairs, jaw squeezes, points off their
// segment), NaN/Inf/subnormal values, random joint rates and loop periods, input conditions,
// resets and faults raised at random. Each case is checked at once; the first failure prints
// the seed, the episode, the case and how to replay it (TRAINER_PROPERTY_EPISODE).
//
// Oracles (independent of the code under test where they can be):
//  - every effort finite and |effort| <= the joint's max_effort (current limit × torque constant
//    × gear [/ capstan radius]); efforts and force exactly zero whenever not armed;
//  - |force| <= safety.max_force_n; a rise or turn of the force by at most
//    max_force_rate_n_per_s × dt; the passivity energy within its bound while armed;
//  - the insertion effort renders the reported force: for any point on the rigid instrument
//    ∂x/∂d = d̂, so τ_insertion = d̂·F_total whatever the points;
//  - no input (tip or point force, point, joint position, tip velocity) is non-finite while
//    the chain stays armed, and a non-finite force, point or joint position latches non_finite;
//    a joint step faster than the configured speed latches encoder_jump; e-stop, drive fault
//    and enable release latch theirs;
//  - a latched fault stays latched (and counted) until an explicit reset with clear inputs
//    arms, which happens exactly then (never after shutdown).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>

#include "property_support.hpp"
#include "trainer/app/force_command.hpp"
#include "trainer/app/instrument_geometry.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/kinematics/trocar_kinematics.hpp"
#include "trainer/model/segment_contact.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {
namespace {

using Vec3 = Eigen::Vector3f;
using kinematics::JointVector;
using kinematics::kJointCount;

#if defined(TRAINER_SANITIZER_BUILD)
constexpr std::uint64_t kDefaultCases = 200'000;  // ASan+UBSan: memory and UB, not the count
#else
constexpr std::uint64_t kDefaultCases = 1'000'000;
#endif
constexpr std::uint64_t kForceCommandSeed = 0x5EED'F0CE'0006ULL;
constexpr std::size_t kInstruments = 2;
// HapticApp's per-instrument capacity of shaft/jaw forces (walls and catheters).
constexpr std::size_t kMaxPointForces = 2 * model::ForcepsCatheterContact::kMaxToolForces +
                                        4 * model::SegmentSurfaceContact::kMaxSegments;
constexpr double kPeriodS = 1e-3;

// One instrument of the device file, as HapticApp::create builds it, with the limits the
// oracles use (double, straight from the configuration).
struct InstrumentModel {
  kinematics::TrocarKinematics kinematics;
  JointVector effort_limits{};                   // what command_instrument is given (float)
  std::array<double, kJointCount> max_effort{};  // the oracle's limit (double)
  std::array<bool, kJointCount> prismatic{};
  std::array<double, kJointCount> min_position{};
  std::array<double, kJointCount> max_position{};
  double shaft_length_m = 0.0;
  double jaw_length_m = 0.0;
};

InstrumentModel instrument_model(const config::InstrumentDeviceConfig& device) {
  InstrumentModel model;
  model.kinematics = kinematics::TrocarKinematics(trocar_geometry(device));
  model.shaft_length_m = device.shaft_length_m;
  model.jaw_length_m = device.jaw_length_m;
  for (std::size_t j = 0; j < kJointCount; ++j) {
    const config::JointConfig& joint = device.joints[j];
    model.max_effort[j] = config::joint_scale(joint).max_effort();
    model.effort_limits[j] = effort_limit(config::joint_scale(joint));
    model.prismatic[j] = joint.kind == hal::JointKind::prismatic;
    model.min_position[j] = joint.min_position;
    model.max_position[j] = joint.max_position;
  }
  return model;
}

// Everything one case used and produced: printed when it fails.
struct Case {
  std::uint64_t episode = 0;
  std::uint64_t cycle = 0;
  std::size_t instrument = 0;
  bool hostile_episode = false;
  float dt_s = 0.0F;
  JointVector previous{};
  JointVector joints{};
  JointVector joint_rates{};
  Vec3 tip_force = Vec3::Zero();
  Vec3 tip_velocity = Vec3::Zero();
  std::array<model::ToolForce, kMaxPointForces> points{};
  std::size_t point_count = 0;
  std::uint32_t latched_before = 0;
  std::uint32_t latched_after = 0;
  Vec3 previous_force = Vec3::Zero();
  ForceCommand command;
};

std::string describe(const Case& c, const safety::SafetyLimits& limits, std::uint64_t seed) {
  std::ostringstream text;
  text.precision(9);
  const auto vec = [&](const Vec3& v) { text << property::vec_text(v); };
  text << "episode " << c.episode << " cycle " << c.cycle << " instrument " << c.instrument
       << (c.hostile_episode ? " (hostile episode)" : "") << "\n  limits: max_force_n "
       << limits.max_force_n << ", max_force_rate_n_per_s " << limits.max_force_rate_n_per_s
       << ", speeds " << limits.max_joint_speed_rad_per_s << " rad/s "
       << limits.max_insertion_speed_m_per_s << " m/s, passivity "
       << limits.passivity_energy_bound_j << " J, require_enable " << limits.require_enable_input
       << "\n  dt_s " << c.dt_s << "\n  joints (previous -> now, rate):";
  for (std::size_t j = 0; j < kJointCount; ++j) {
    text << " " << c.previous[j] << "->" << c.joints[j] << " (" << c.joint_rates[j] << ")";
  }
  text << "\n  tip force ";
  vec(c.tip_force);
  text << ", tip velocity ";
  vec(c.tip_velocity);
  text << "\n  point forces (" << c.point_count << "):";
  for (std::size_t k = 0; k < c.point_count && k < 12; ++k) {
    text << " {segment " << static_cast<int>(c.points[k].segment) << " at " << c.points[k].along_m
         << " m ";
    vec(c.points[k].force_n);
    text << "}";
  }
  text << "\n  latched before " << c.latched_before << ", after " << c.latched_after
       << "; previous force ";
  vec(c.previous_force);
  text << "\n  commanded force ";
  vec(c.command.force_n);
  text << ", efforts";
  for (const float effort : c.command.efforts) text << " " << effort;
  text << "\n  replay: TRAINER_PROPERTY_SEED=" << seed << " TRAINER_PROPERTY_EPISODE=" << c.episode
       << " force_property_test --gtest_filter=ForceCommandProperty.*";
  return text.str();
}

bool finite(const Vec3& v) {
  return v.allFinite();
}

// A force of a random kind: mostly zero or in the felt range, sometimes far beyond it, and in
// hostile episodes sometimes with a NaN, Inf, FLT_MAX or subnormal component.
Vec3 random_force(property::Random& random, double felt_n, double hostile_probability) {
  const double pick = random.unit();
  Vec3 force = Vec3::Zero();
  if (pick < 0.25) {
    force.setZero();
  } else if (pick < 0.72) {
    force = random.unit_vector() * static_cast<float>(random.log_uniform(1e-4, 2.0 * felt_n));
  } else if (pick < 0.92) {
    force = random.unit_vector() * static_cast<float>(random.log_uniform(2.0 * felt_n, 1e4));
  } else {
    force = random.unit_vector() * static_cast<float>(random.log_uniform(1e4, 1e30));
  }
  if (random.chance(hostile_probability))
    force[static_cast<Eigen::Index>(random.index(3))] = random.hostile();
  return force;
}

class ForceCommandProperty : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scene = config::load_scene(property::kRepo / "config/scenes/wall.toml");
    ASSERT_TRUE(scene) << scene.error().message;
    ASSERT_GE(scene->device.instruments.size(), kInstruments);
    for (std::size_t i = 0; i < kInstruments; ++i) {
      instruments_[i] = instrument_model(scene->device.instruments[i]);
    }
    const config::SafetyConfig& safety = scene->safety;
    scene_limits_.max_force_n = static_cast<float>(safety.max_force_n);
    scene_limits_.max_force_rate_n_per_s = static_cast<float>(safety.max_force_rate_n_per_s);
    scene_limits_.max_joint_speed_rad_per_s = static_cast<float>(safety.max_joint_speed_rad_per_s);
    scene_limits_.max_insertion_speed_m_per_s =
        static_cast<float>(safety.max_insertion_speed_m_per_s);
    scene_limits_.passivity_energy_bound_j = static_cast<float>(safety.passivity_energy_bound_j);
    scene_limits_.require_enable_input = safety.require_enable_input;
  }

  std::array<InstrumentModel, kInstruments> instruments_;
  safety::SafetyLimits scene_limits_;
};

// What the run covered, so a generator that stopped reaching the interesting states fails
// instead of passing emptily.
struct Coverage {
  std::uint64_t cases = 0;
  std::uint64_t armed_cases = 0;           // armed after the case
  std::uint64_t pushing_cases = 0;         // armed with a non-zero effort
  std::uint64_t effort_limited_cases = 0;  // armed with some |effort| >= 99.9 % of its limit
  std::uint64_t non_finite_cases = 0;      // some input non-finite
  std::uint64_t outside_range_cases = 0;   // armed with a joint outside its range
  std::uint64_t episodes = 0;
  std::uint64_t arms = 0;
  std::array<std::uint64_t, safety::kFaultKinds> raised{};
};

TEST_F(ForceCommandProperty, CommandIsFiniteWithinLimitsAndZeroUnlessArmed) {
  const std::uint64_t seed = property::seed_for("ForceCommandProperty", kForceCommandSeed);
  const std::uint64_t case_budget =
      property::env_u64("TRAINER_PROPERTY_CASES").value_or(kDefaultCases);
  const std::optional<std::uint64_t> only_episode = property::env_u64("TRAINER_PROPERTY_EPISODE");
  Coverage coverage;
  std::string failure;
  Case current;
  safety::SafetyLimits limits;
  const auto started = std::chrono::steady_clock::now();

  for (std::uint64_t episode = only_episode.value_or(0);
       failure.empty() && (only_episode ? episode == *only_episode : coverage.cases < case_budget);
       ++episode) {
    std::uint64_t episode_state = seed ^ (episode * 0xD1B54A32D192ED03ULL);
    property::Random random(property::splitmix64(episode_state));
    ++coverage.episodes;

    // The episode's style: the scene's limits or random ones in the configured ranges
    // (docs/config.md [safety]); hostile episodes put non-finite values in the inputs.
    limits = scene_limits_;
    if (random.chance(0.5)) {
      limits.max_force_n = static_cast<float>(random.log_uniform(0.05, 100.0));
      limits.max_force_rate_n_per_s = static_cast<float>(random.log_uniform(10.0, 1e7));
      limits.max_joint_speed_rad_per_s = static_cast<float>(random.log_uniform(0.5, 1e4));
      limits.max_insertion_speed_m_per_s = static_cast<float>(random.log_uniform(0.05, 100.0));
      limits.passivity_energy_bound_j =
          random.chance(0.2) ? 0.0F : static_cast<float>(random.log_uniform(1e-3, 100.0));
      limits.require_enable_input = random.chance(0.3);
    }
    const bool hostile = random.chance(0.5);
    const double hostile_probability = hostile ? 0.01 : 0.0;
    const auto cycles = static_cast<std::uint64_t>(1 + random.index(200));
    safety::SafetySupervisor supervisor(limits, kInstruments);

    std::array<JointVector, kInstruments> positions{};
    for (std::size_t i = 0; i < kInstruments; ++i) {
      for (std::size_t j = 0; j < kJointCount; ++j) {
        const double span = instruments_[i].max_position[j] - instruments_[i].min_position[j];
        positions[i][j] = random.chance(0.8)
                              ? random.uniform_float(instruments_[i].min_position[j],
                                                     instruments_[i].max_position[j])
                              : random.uniform_float(instruments_[i].min_position[j] - span,
                                                     instruments_[i].max_position[j] + span);
      }
    }
    std::array<Vec3, kInstruments> previous_force{};
    for (Vec3& force : previous_force) force.setZero();
    safety::InputConditions inputs;
    bool reset_next = true;         // the trainer's explicit reset at start
    std::uint64_t raise_total = 0;  // fault raises seen so far: any new one zeroes the slew memory

    const auto total_raises = [&] {
      std::uint64_t total = 0;
      for (const std::uint64_t count : supervisor.fault_counts()) total += count;
      return total;
    };
    const auto fail = [&](const std::string& what) {
      if (failure.empty()) failure = what + "\n" + describe(current, limits, seed);
    };

    for (std::uint64_t cycle = 0; cycle < cycles && failure.empty(); ++cycle) {
      current = Case{};
      current.episode = episode;
      current.cycle = cycle;
      current.hostile_episode = hostile;
      const double dt_pick = random.unit();
      const double dt_s = dt_pick < 0.8    ? kPeriodS
                          : dt_pick < 0.95 ? random.uniform(kPeriodS, 50.0 * kPeriodS)
                                           : random.log_uniform(1e-6, kPeriodS);
      current.dt_s = static_cast<float>(dt_s);

      // Input conditions toggle now and then; resets come often while faulted.
      if (random.chance(inputs.estop_active ? 0.3 : 0.01))
        inputs.estop_active = !inputs.estop_active;
      if (random.chance(inputs.drive_fault ? 0.3 : 0.01)) inputs.drive_fault = !inputs.drive_fault;
      if (random.chance(inputs.enable_held ? 0.01 : 0.3)) inputs.enable_held = !inputs.enable_held;
      const bool reset = reset_next || random.chance(supervisor.armed() ? 0.005 : 0.25);
      reset_next = false;
      const std::uint32_t latched_before_inputs = supervisor.latched_faults();
      const bool armed_before_inputs = supervisor.armed();
      const std::uint32_t arms_before = supervisor.arm_count();
      if (reset) supervisor.request_reset();
      supervisor.evaluate_inputs(inputs, cycle);
      const std::uint32_t latched = supervisor.latched_faults();
      const bool inputs_clear = !inputs.estop_active && !inputs.drive_fault &&
                                (!limits.require_enable_input || inputs.enable_held);
      const bool expect_arm = reset && inputs_clear &&
                              (latched_before_inputs & safety::bit(safety::Fault::shutdown)) == 0;
      current.latched_before = latched_before_inputs;
      current.latched_after = latched;
      if ((supervisor.arm_count() != arms_before) != expect_arm) {
        fail(std::string("reset ") + (expect_arm ? "not honoured" : "honoured") + " (requested " +
             std::to_string(reset) + ", inputs clear " + std::to_string(inputs_clear) + ")");
      }
      if (expect_arm ? latched != 0 : (latched & latched_before_inputs) != latched_before_inputs) {
        fail("latched faults lost without an explicit reset, or left after one");
      }
      if (inputs.estop_active && (latched & safety::bit(safety::Fault::estop)) == 0) {
        fail("e-stop active but not latched");
      }
      if (inputs.drive_fault && (latched & safety::bit(safety::Fault::drive_fault)) == 0) {
        fail("drive fault but not latched");
      }
      if (limits.require_enable_input && !inputs.enable_held && armed_before_inputs &&
          !inputs.estop_active && !inputs.drive_fault &&
          (latched & safety::bit(safety::Fault::enable_released)) == 0) {
        fail("enable switch released while armed but not latched");
      }
      if (supervisor.arm_count() != arms_before) {
        ++coverage.arms;
        for (Vec3& force : previous_force) force.setZero();
      }
      // A fault raised by something else in the cycle (overrun streak, lost device, shutdown).
      if (random.chance(0.002)) {
        const std::size_t kind = random.index(safety::kFaultKinds);
        if (kind != 9 || random.chance(0.1)) {
          supervisor.latch(static_cast<safety::Fault>(1U << kind), cycle);
          if ((supervisor.latched_faults() & (1U << kind)) == 0) fail("latch() did not latch");
        }
      }

      for (std::size_t i = 0; i < kInstruments && failure.empty(); ++i) {
        const InstrumentModel& model = instruments_[i];
        current.instrument = i;
        current.previous = positions[i];
        if (total_raises() != raise_total) {
          for (Vec3& force : previous_force) force.setZero();  // latch() zeroes the slew memory
          raise_total = total_raises();
        }
        current.previous_force = previous_force[i];
        current.latched_before = supervisor.latched_faults();

        // Joint positions: a hand's motion within the speed limits, or a jump, a teleport
        // inside or outside the range, or a hostile value on one joint.
        JointVector joints = positions[i];
        const double motion = random.unit();
        const std::size_t one = random.index(kJointCount);
        for (std::size_t j = 0; j < kJointCount; ++j) {
          const double speed = model.prismatic[j] ? limits.max_insertion_speed_m_per_s
                                                  : limits.max_joint_speed_rad_per_s;
          const double span = model.max_position[j] - model.min_position[j];
          if (motion < 0.86) {
            joints[j] += static_cast<float>(random.uniform(-0.95, 0.95) * speed * dt_s);
          } else if (motion < 0.90 && j == one) {
            joints[j] +=
                static_cast<float>(random.sign() * random.log_uniform(1.01, 1e3) * speed * dt_s);
          } else if (motion < 0.94) {
            joints[j] = random.uniform_float(model.min_position[j], model.max_position[j]);
          } else if (motion < 0.98) {
            joints[j] = random.uniform_float(model.min_position[j] - 3.0 * span,
                                             model.max_position[j] + 3.0 * span);
          } else if (j == one && hostile) {
            joints[j] = random.hostile();
          }
        }
        current.joints = joints;
        bool non_finite_position = false;
        bool expect_jump = false;
        bool jump_borderline = false;
        for (std::size_t j = 0; j < kJointCount; ++j) {
          const float speed = model.prismatic[j] ? limits.max_insertion_speed_m_per_s
                                                 : limits.max_joint_speed_rad_per_s;
          supervisor.check_joint_step(model.prismatic[j], positions[i][j], joints[j], current.dt_s,
                                      cycle);
          non_finite_position = non_finite_position || !std::isfinite(joints[j]);
          const double step =
              std::fabs(static_cast<double>(joints[j]) - static_cast<double>(positions[i][j]));
          const double allowed = static_cast<double>(speed) * static_cast<double>(current.dt_s);
          if (std::isfinite(step)) {
            expect_jump = expect_jump || step > allowed * (1.0 + 1e-5);
            jump_borderline = jump_borderline || std::fabs(step - allowed) <= allowed * 1e-5;
          }
        }
        positions[i] = joints;  // the app keeps the reading, as the kinematics stage does

        const kinematics::InstrumentPose pose = model.kinematics.forward(joints);
        for (std::size_t j = 0; j < kJointCount; ++j) {
          const double speed = model.prismatic[j] ? limits.max_insertion_speed_m_per_s
                                                  : limits.max_joint_speed_rad_per_s;
          current.joint_rates[j] = static_cast<float>(random.uniform(-2.0, 2.0) * speed);
        }
        current.tip_velocity = kinematics::TrocarKinematics::point_velocity(pose, pose.insertion_m,
                                                                            current.joint_rates);
        if (random.chance(hostile_probability)) {
          current.tip_velocity[static_cast<Eigen::Index>(random.index(3))] = random.hostile();
        }

        // Forces: the tip's, and points on the shaft and jaws (walls, catheters), with jaw
        // squeezes and huge cancelling pairs among them.
        const double felt_n = limits.max_force_n;
        current.tip_force = random_force(random, felt_n, hostile_probability);
        const double count_pick = random.unit();
        const std::size_t count = count_pick < 0.45   ? 0
                                  : count_pick < 0.85 ? 1 + random.index(6)
                                                      : 1 + random.index(kMaxPointForces);
        for (std::size_t k = 0; k < count; ++k) {
          model::ToolForce& point = current.points[k];
          point.segment = static_cast<model::ToolSegment>(random.index(3));
          const double length = point.segment == model::ToolSegment::shaft
                                    ? model.shaft_length_m - model.jaw_length_m
                                    : model.jaw_length_m;
          point.along_m = random.chance(0.9) ? random.uniform_float(0.0, length)
                                             : random.uniform_float(-1.0, 1.5);
          if (random.chance(hostile_probability)) point.along_m = random.hostile();
          point.force_n = random_force(random, 0.5 * felt_n, hostile_probability);
        }
        current.point_count = count;
        if (count + 2 <= kMaxPointForces && random.chance(0.15)) {
          // A jaw squeeze: equal and opposite across the jaws, off the total.
          const float along = random.uniform_float(0.0, model.jaw_length_m);
          const Vec3 squeeze =
              pose.opening_direction * static_cast<float>(random.log_uniform(1e-3, 100.0));
          current.points[current.point_count++] = {model::ToolSegment::jaw0, along, -squeeze};
          current.points[current.point_count++] = {model::ToolSegment::jaw1, along, squeeze};
        }
        if (current.point_count < kMaxPointForces && random.chance(0.04)) {
          // Huge and cancelling: a total near zero from parts beyond any limit.
          const Vec3 huge =
              random.unit_vector() * static_cast<float>(random.log_uniform(1e3, 1e30));
          current.tip_force = huge;
          current.points[current.point_count++] = {
              model::ToolSegment::shaft,
              random.uniform_float(0.0, model.shaft_length_m - model.jaw_length_m), -huge};
        }

        bool non_finite_force = !finite(current.tip_force);
        for (std::size_t k = 0; k < current.point_count; ++k) {
          non_finite_force = non_finite_force || !finite(current.points[k].force_n) ||
                             !std::isfinite(current.points[k].along_m);
        }
        const bool non_finite_any =
            non_finite_force || non_finite_position || !finite(current.tip_velocity);
        const InstrumentForces forces{
            current.tip_force,
            std::span<const model::ToolForce>(current.points.data(), current.point_count),
            current.tip_velocity};
        current.command = command_instrument(supervisor, i, model.kinematics, pose, forces,
                                             model.effort_limits, current.dt_s, cycle);
        const ForceCommand& command = current.command;
        current.latched_after = supervisor.latched_faults();
        ++coverage.cases;
        if (non_finite_any) ++coverage.non_finite_cases;

        // The command: finite, within every actuator's limit, zero unless armed.
        for (std::size_t j = 0; j < kJointCount; ++j) {
          const double effort = static_cast<double>(command.efforts[j]);
          if (!std::isfinite(effort)) fail("non-finite effort on joint " + std::to_string(j));
          if (!(std::fabs(effort) <= model.max_effort[j])) {
            fail("effort on joint " + std::to_string(j) + " beyond its limit " +
                 property::number_text(model.max_effort[j]));
          }
        }
        if (!finite(command.force_n)) fail("non-finite commanded force");
        const bool armed = supervisor.armed();
        if (!armed) {
          for (const float effort : command.efforts) {
            if (effort != 0.0F) fail("non-zero effort while not armed");
          }
          if (!command.force_n.isZero(0.0F)) fail("non-zero force while not armed");
        }
        // Faults: latched by what the inputs hold, never lost within a cycle.
        const std::uint32_t after = supervisor.latched_faults();
        if ((after & current.latched_before) != current.latched_before)
          fail("a latched fault cleared");
        if (non_finite_any && armed) fail("non-finite input, still armed");
        if ((non_finite_force || non_finite_position) &&
            (after & safety::bit(safety::Fault::non_finite)) == 0) {
          fail("non-finite force, point or joint position, non_finite not latched");
        }
        if (expect_jump && !jump_borderline &&
            (after & safety::bit(safety::Fault::encoder_jump)) == 0) {
          fail("joint step beyond the speed limit, encoder_jump not latched");
        }
        if (armed) {
          ++coverage.armed_cases;
          const float force_norm = command.force_n.norm();
          if (!(force_norm <= limits.max_force_n * (1.0F + 1e-5F)))
            fail("force beyond max_force_n");
          // Slew: a rise or a turn by at most rate × dt; a pure decrease is always allowed.
          const Vec3& last = previous_force[i];
          const bool decreasing = command.force_n.squaredNorm() <= last.squaredNorm() &&
                                  command.force_n.dot(last) >= 0.0F;
          const double max_step = static_cast<double>(limits.max_force_rate_n_per_s) * dt_s;
          if (!decreasing &&
              !(static_cast<double>((command.force_n - last).norm()) <=
                max_step * (1.0 + 1e-4) + 1e-5 * static_cast<double>(limits.max_force_n))) {
            fail("force changed faster than max_force_rate_n_per_s");
          }
          // The insertion effort renders the reported force (d̂·F for any point).
          double gross_n =
              static_cast<double>(current.tip_force.norm()) + 2.0 * static_cast<double>(force_norm);
          for (std::size_t k = 0; k < current.point_count; ++k) {
            gross_n += static_cast<double>(current.points[k].force_n.norm());
          }
          const double rendered = static_cast<double>(pose.direction.dot(command.force_n));
          if (!(std::fabs(static_cast<double>(command.efforts[kinematics::kInsertion]) -
                          rendered) <= 1e-5 * gross_n + 1e-6)) {
            fail("insertion effort does not render the commanded force (expected " +
                 property::number_text(rendered) + ")");
          }
          if (limits.passivity_energy_bound_j > 0.0F &&
              supervisor.delivered_energy_j(i) > limits.passivity_energy_bound_j) {
            fail("delivered energy beyond the passivity bound while armed");
          }
          bool pushing = false;
          bool at_limit = false;
          bool outside = false;
          for (std::size_t j = 0; j < kJointCount; ++j) {
            pushing = pushing || command.efforts[j] != 0.0F;
            at_limit = at_limit || std::fabs(static_cast<double>(command.efforts[j])) >=
                                       0.999 * model.max_effort[j];
            const double position = static_cast<double>(joints[j]);
            outside =
                outside || position < model.min_position[j] || position > model.max_position[j];
          }
          if (pushing) ++coverage.pushing_cases;
          if (at_limit) ++coverage.effort_limited_cases;
          if (outside) ++coverage.outside_range_cases;
          previous_force[i] = command.force_n;
        } else {
          previous_force[i].setZero();
        }
      }
    }
    for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
      coverage.raised[kind] += supervisor.fault_counts()[kind];
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  ASSERT_TRUE(failure.empty()) << failure;

  std::printf(
      "ForceCommandProperty: %llu cases in %llu episodes, %.2f s; armed %llu, pushing %llu, "
      "at an effort limit %llu, armed outside the joint range %llu, non-finite inputs %llu, "
      "arms %llu\n",
      static_cast<unsigned long long>(coverage.cases),
      static_cast<unsigned long long>(coverage.episodes), seconds,
      static_cast<unsigned long long>(coverage.armed_cases),
      static_cast<unsigned long long>(coverage.pushing_cases),
      static_cast<unsigned long long>(coverage.effort_limited_cases),
      static_cast<unsigned long long>(coverage.outside_range_cases),
      static_cast<unsigned long long>(coverage.non_finite_cases),
      static_cast<unsigned long long>(coverage.arms));
  std::printf("  faults raised:");
  for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
    std::printf(" %s %llu", safety::to_string(static_cast<safety::Fault>(1U << kind)),
                static_cast<unsigned long long>(coverage.raised[kind]));
  }
  std::printf("\n");
  if (only_episode) return;
  EXPECT_GE(coverage.cases, case_budget);
  // The generator reaches what the property is about (fractions of the cases, with margin
  // below what the default seed gives).
  EXPECT_GT(coverage.armed_cases, coverage.cases / 3);
  EXPECT_GT(coverage.pushing_cases, coverage.cases / 4);
  EXPECT_GT(coverage.effort_limited_cases, coverage.cases / 100);
  EXPECT_GT(coverage.outside_range_cases, coverage.cases / 100);
  EXPECT_GT(coverage.non_finite_cases, coverage.cases / 1000);
  for (const safety::Fault kind :
       {safety::Fault::non_finite, safety::Fault::encoder_jump, safety::Fault::estop,
        safety::Fault::drive_fault, safety::Fault::passivity, safety::Fault::enable_released}) {
    EXPECT_GT(coverage.raised[static_cast<std::size_t>(std::countr_zero(safety::bit(kind)))], 0U)
        << safety::to_string(kind);
  }
}

}  // namespace
}  // namespace trainer::app
