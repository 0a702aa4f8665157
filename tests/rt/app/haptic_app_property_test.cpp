// Property test of the force command, full-cycle layer (issue 6): the whole haptic cycle —
// HapticApp in the real PeriodicLoop on a manual clock, the simulated bench behind the HAL
// interfaces — on the wall scene and on the reference cbd scene (duct + catheter + two
// forceps), for many cycles of random device inputs, injected faults and model states, with
// every command written to every actuator channel checked as it is written.
//
// What is random, cycle by cycle (seeded; property_support.hpp):
//  - the trainee's hand (the simulated plant's target): the scene's own script, then a new pose
//    every 0.1–1.5 s, anywhere in the joints' ranges, near the script's poses, or pressing up to
//    6 mm deeper than the script's deepest (write_random_trainee);
//  - the encoders: the sim's real readings, plus a slowly drifting offset per channel (the
//    armed controller then sees joints far outside the mechanism's range), glitches (a jump, a
//    teleport, a NaN/Inf/huge value marked valid, an invalid sample) and failed or
//    "deactivate" reads, through a decorator on the HAL's encoder interface;
//  - the bench's own faults (SimDevice): e-stop, drive faults, stuck encoders, failed reads,
//    late replies (overruns, then the loop's overrun-streak fault); unreadable digital inputs;
//    failed or "deactivate" actuator writes and faulted status reads;
//  - loop stalls (a step that takes 0.2–30 periods: overruns, long dt), explicit resets;
//  - the models (cbd): loads of up to 10^4 N (and non-finite ones) on random duct nodes, taken
//    by the duct as the catheter's wall reactions are, modal resets, catheter particles held at
//    random places (in and across the duct wall, at the tools), catheter resets.
//
// Checked on every write to the actuators (any caller: the cycle, the overrun fault, shutdown):
// every channel's effort finite and within its drive's limit from the device file, zero and
// disabled unless the safety chain is armed, enabled exactly when armed; channels of device
// instruments the scene does not use at zero. After every cycle: the telemetry reports the
// latched faults and the efforts written; a fault raised in the cycle (or by the loop between
// cycles) is latched and published at the end of that cycle, and logged when new; latched
// faults only clear when an explicit reset arms; the faults the injected causes imply are
// latched (e-stop, unreadable inputs, drive fault, lost device, non-finite or jumping encoder
// reading). The first failure stops the run and prints the seed and the cycle's events.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "catheter_images.hpp"
#include "model_spec.hpp"  // tools/modelc: a model definition → the modal builder's spec
#include "property_support.hpp"
#include "trainer/app/haptic_app.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/hal/joint_scale.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::app {

// Random model states through the models' own public calls (HapticApp's friend).
class HapticAppTestAccess {
 public:
  static std::size_t modal_count(const HapticApp& app) { return app.models_.modal_count; }
  static std::size_t modal_vertex_count(const HapticApp& app, std::size_t m) {
    return app.models_.modal[m].surface.vertex_count();
  }
  // A load on a node of modal model m, applied at its next step: the path the catheters' wall
  // reactions take. False when the model's pending loads are full.
  static bool add_modal_load(HapticApp& app, std::size_t m, std::uint32_t node,
                             const Eigen::Vector3f& force_n) {
    return app.models_.modal[m].add_catheter_load(node, force_n);
  }
  static void reset_modal(HapticApp& app, std::size_t m) { app.models_.modal[m].model->reset(); }
  static std::size_t catheter_count(const HapticApp& app) { return app.models_.catheter_count; }
  static model::Catheter& catheter(HapticApp& app, std::size_t c) {
    return *app.models_.catheters[c].catheter;
  }
};

namespace {

using Vec3 = Eigen::Vector3f;
using kinematics::kJointCount;

// Sanitizer builds run a tenth of the cycles (the cbd cycle is ~20x slower under ASan) and
// start the random trainee at once instead of after the scene's own 11 s script, so the few
// cycles still reach the duct and the catheter.
#if defined(TRAINER_SANITIZER_BUILD)
constexpr std::uint64_t kWallCycles = 40'000;
constexpr std::uint64_t kCbdCycles = 3'000;
constexpr bool kSceneScriptFirst = false;
constexpr bool kSanitizerBuild = true;
#else
constexpr std::uint64_t kWallCycles = 300'000;
constexpr std::uint64_t kCbdCycles = 30'000;
constexpr bool kSceneScriptFirst = true;
constexpr bool kSanitizerBuild = false;
#endif
constexpr std::uint64_t kCycleSeed = 0xCB0D'5EED'0006ULL;

// The encoders as the HAL gives them, then drifted, glitched or failed as the test asks.
class HostileEncoders final : public hal::EncoderInterface {
 public:
  enum class Glitch : std::uint8_t { none, jitter, jump, teleport, hostile_value, invalid };
  struct Plan {
    Glitch glitch = Glitch::none;
    std::size_t channel = 0;
    float value = 0.0F;  // jitter/jump offset, teleport position or hostile value
    hal::ReturnCode code = hal::ReturnCode::ok;  // forced on the read when not ok
  };

  explicit HostileEncoders(hal::EncoderInterface& inner) : inner_(inner) {}
  std::size_t encoder_count() const noexcept override { return inner_.encoder_count(); }

  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override {
    hal::ReturnCode code = inner_.read_encoders(out);
    for (std::size_t c = 0; c < out.size() && c < offset_.size(); ++c) {
      // The drift creeps toward its target slowly enough never to look like a jump.
      const float step = std::clamp(target_[c] - offset_[c], -rate_[c], rate_[c]);
      offset_[c] += step;
      out[c].position += offset_[c];
    }
    for (std::size_t c = 0; c < out.size() && c < forced.size(); ++c) {
      if (forced[c]) out[c].position = *forced[c];
      if (invalid[c]) out[c].valid = false;
    }
    switch (plan.glitch) {
      case Glitch::none: break;
      case Glitch::jitter:
      case Glitch::jump: out[plan.channel].position += plan.value; break;
      case Glitch::teleport:
      case Glitch::hostile_value: out[plan.channel].position = plan.value; break;
      case Glitch::invalid: out[plan.channel].valid = false; break;
    }
    if (plan.code != hal::ReturnCode::ok) code = plan.code;
    plan = Plan{};
    delivered.assign(out.begin(), out.end());
    delivered_code = code;
    ++reads;
    return code;
  }

  // Starts a drift of channel c toward `target` (joint units) at `rate` per read.
  void drift(std::size_t c, float target, float rate) {
    target_[c] = target;
    rate_[c] = rate;
  }
  float offset(std::size_t c) const { return offset_[c]; }

  Plan plan;  // this read only
  // Persistent, per channel: a reading replaced by a value, or marked invalid.
  std::array<std::optional<float>, hal::sim::kMaxChannels> forced{};
  std::array<bool, hal::sim::kMaxChannels> invalid{};
  std::vector<hal::EncoderSample> delivered;
  hal::ReturnCode delivered_code = hal::ReturnCode::ok;
  std::uint64_t reads = 0;

 private:
  hal::EncoderInterface& inner_;
  std::array<float, hal::sim::kMaxChannels> offset_{};
  std::array<float, hal::sim::kMaxChannels> target_{};
  std::array<float, hal::sim::kMaxChannels> rate_{};
};

class HostileDigitalInputs final : public hal::DigitalInputInterface {
 public:
  explicit HostileDigitalInputs(hal::DigitalInputInterface& inner) : inner_(inner) {}
  std::size_t digital_input_count() const noexcept override { return inner_.digital_input_count(); }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override {
    const hal::ReturnCode code = inner_.read_digital_inputs(levels);
    if (fail_next) {
      fail_next = false;
      failed = true;
      return hal::ReturnCode::error;
    }
    return code;
  }
  bool fail_next = false;
  bool failed = false;  // this cycle's read failed (reset by the test)

 private:
  hal::DigitalInputInterface& inner_;
};

// The property's checkpoint: every command on its way to the drives.
class CheckingActuators final : public hal::ActuatorInterface {
 public:
  CheckingActuators(hal::ActuatorInterface& inner, std::vector<double> max_effort,
                    std::vector<bool> used)
      : inner_(inner), max_effort_(std::move(max_effort)), used_(std::move(used)) {}
  std::size_t actuator_count() const noexcept override { return inner_.actuator_count(); }

  hal::ReturnCode write_actuators(
      std::span<const hal::ActuatorCommand> commands) noexcept override {
    ++writes;
    const bool armed = app != nullptr && app->safety().armed();
    bool pushing = false;
    for (std::size_t c = 0; c < commands.size(); ++c) {
      const hal::ActuatorCommand& command = commands[c];
      const double effort = static_cast<double>(command.effort);
      ++commands_checked;
      if (!std::isfinite(effort)) fail(c, command, "non-finite effort");
      if (c < max_effort_.size() && !(std::fabs(effort) <= max_effort_[c])) {
        fail(c, command,
             "effort beyond the drive's limit " + property::number_text(max_effort_[c]));
      }
      if (!armed && (effort != 0.0 || command.enable))
        fail(c, command, "not armed, yet not zero and disabled");
      if (command.enable != armed) fail(c, command, "enable differs from the safety chain's state");
      if (c < used_.size() && !used_[c] && effort != 0.0)
        fail(c, command, "effort on a channel the scene does not use");
      pushing = pushing || effort != 0.0;
      if (c < max_effort_.size() && std::fabs(effort) >= 0.999 * max_effort_[c]) ++at_limit;
      last[c] = command;
    }
    if (pushing) ++pushing_writes;
    const hal::ReturnCode code = inner_.write_actuators(commands);
    if (force_write_code != hal::ReturnCode::ok) {
      const hal::ReturnCode forced = force_write_code;
      force_write_code = hal::ReturnCode::ok;
      return forced;
    }
    return code;
  }
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override {
    const hal::ReturnCode code = inner_.read_actuator_status(out);
    if (fault_next_status) {
      fault_next_status = false;
      out[fault_channel].fault = true;
      return hal::ReturnCode::deactivate;
    }
    return code;
  }

  const HapticApp* app = nullptr;
  std::array<hal::ActuatorCommand, hal::sim::kMaxChannels> last{};
  hal::ReturnCode force_write_code = hal::ReturnCode::ok;
  bool fault_next_status = false;
  std::size_t fault_channel = 0;
  std::uint64_t writes = 0;
  std::uint64_t commands_checked = 0;
  std::uint64_t pushing_writes = 0;
  std::uint64_t at_limit = 0;
  std::string failure;

 private:
  void fail(std::size_t channel, const hal::ActuatorCommand& command, const std::string& what) {
    if (!failure.empty()) return;
    std::ostringstream text;
    text.precision(9);
    text << "write " << writes << ", channel " << channel << ": " << what << " (effort "
         << command.effort << ", enable " << command.enable << ", armed "
         << (app != nullptr && app->safety().armed()) << ", latched "
         << (app != nullptr ? app->safety().latched_faults() : 0U) << ")";
    failure = text.str();
  }

  hal::ActuatorInterface& inner_;
  std::vector<double> max_effort_;
  std::vector<bool> used_;
};

// A directory of this test program's own, removed at exit: the duct image and the random
// trainee scripts go there.
class TemporaryDirectory {
 public:
  static const std::filesystem::path& path() {
    static const TemporaryDirectory directory;
    return directory.path_;
  }
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;
  ~TemporaryDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }

 private:
  TemporaryDirectory()
      : path_(std::filesystem::temp_directory_path() /
              ("trainer_property_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  std::filesystem::path path_;
};

// The duct image the cbd scene names, built once per test program (about 0.5 s), so the test
// needs no `modelc build` run beforehand. Empty when the build failed (the message is printed).
std::filesystem::path build_duct_image() {
  const auto complain = [](const std::string& message) {
    std::fprintf(stderr, "duct image: %s\n", message.c_str());
    return std::filesystem::path{};
  };
  auto scene = config::load_scene(property::kRepo / "config/scenes/cbd.toml");
  if (!scene) return complain(scene.error().message);
  for (const config::SceneModelConfig& entry : scene->models) {
    if (entry.definition.kind != config::ModelKind::modal_shell) continue;
    auto spec = tools::modelc::modal_spec_from(entry.definition);
    if (!spec) return complain(spec.error().message);
    auto build = model::offline::build_modal_model(*spec);
    if (!build) return complain(build.error().message);
    const std::filesystem::path image = TemporaryDirectory::path() / "duct.img";
    if (auto written = model::offline::write_modal_image(*spec, *build, image); !written) {
      return complain(written.error().message);
    }
    return image;
  }
  return complain("config/scenes/cbd.toml names no modal model");
}

const std::filesystem::path& duct_image() {
  static const std::filesystem::path image = build_duct_image();
  return image;
}

// A random trainee for the whole run: the scene's own script first (its procedure, as
// written; not in sanitizer builds), then a new pose every 0.1–1.5 s per instrument (the hand
// sometimes snapping there in 0.1 s; longer in soak runs, the script holding 4096 keyframes): a
// quarter of them anywhere in the joints' ranges, 45 % within 2 % of the range from one of the
// instrument's scripted poses (where the contacts are), 30 % (and the first) at its deepest
// scripted pose pressed up to 6 mm deeper (into the wall or the duct). Written as a trajectory CSV
// the simulated device loads.
std::filesystem::path write_random_trainee(const config::SceneConfig& scene,
                                           property::Random& random, double duration_s,
                                           const std::string& name) {
  std::ifstream original(scene.trainee.script);
  std::vector<std::string> rows;
  std::vector<std::pair<std::string, std::array<double, kJointCount>>> poses;
  double last_time_s = 0.0;
  std::string line;
  while (std::getline(original, line)) {
    if (line.empty() || line.front() == '#' || line.starts_with("time_s")) continue;
    std::istringstream fields(line);
    std::string field;
    std::vector<std::string> parts;
    while (std::getline(fields, field, ',')) parts.push_back(field);
    if (parts.size() != 2 + kJointCount) continue;
    last_time_s = std::max(last_time_s, std::stod(parts[0]));
    std::array<double, kJointCount> pose{};
    for (std::size_t j = 0; j < kJointCount; ++j) pose[j] = std::stod(parts[2 + j]);
    poses.emplace_back(parts[1], pose);
    rows.push_back(line);
  }
  const std::filesystem::path path = TemporaryDirectory::path() / (name + "_trainee.csv");
  std::ofstream out(path);
  out << "time_s,instrument,pitch_rad,yaw_rad,insertion_m,roll_rad,grip_rad\n";
  if (kSceneScriptFirst) {
    for (const std::string& row : rows) out << row << '\n';
  } else {
    last_time_s = 0.0;
    rows.clear();
  }
  std::size_t keyframes = rows.size();
  // Keep within the script's keyframe capacity whatever the run length.
  const double mean_interval_s =
      std::max(0.8, duration_s * static_cast<double>(scene.instruments.size()) /
                        static_cast<double>(hal::sim::kMaxKeyframes - keyframes - 16));
  for (const config::SceneInstrumentConfig& instrument : scene.instruments) {
    const config::InstrumentDeviceConfig& device =
        scene.device.instruments[instrument.device_instrument];
    double time_s = last_time_s;
    std::vector<std::array<double, kJointCount>> mine;  // this instrument's scripted poses
    for (const auto& [who, pose] : poses) {
      if (who == device.name) mine.push_back(pose);
    }
    // Its deepest scripted pose: where it presses on something.
    const auto deepest =
        std::max_element(mine.begin(), mine.end(), [](const auto& a, const auto& b) {
          return a[kinematics::kInsertion] < b[kinematics::kInsertion];
        });
    bool first = true;
    while (time_s < duration_s + 1.0 && keyframes < hal::sim::kMaxKeyframes - 1) {
      time_s += random.chance(0.1) ? 0.1 : random.uniform(0.2, 2.0 * mean_interval_s - 0.2);
      std::array<double, kJointCount> pose{};
      // The first pose presses, so that even a short run (sanitizer builds) reaches contact.
      const double pick = first ? 0.5 : random.unit();
      first = false;
      const std::array<double, kJointCount>* anchor = nullptr;
      if (!mine.empty() && pick < 0.45) anchor = &mine[random.index(mine.size())];
      const bool press = !mine.empty() && pick >= 0.45 && pick < 0.75;
      for (std::size_t j = 0; j < kJointCount; ++j) {
        const config::JointConfig& joint = device.joints[j];
        const double span = joint.max_position - joint.min_position;
        double value = random.uniform(joint.min_position, joint.max_position);
        if (anchor != nullptr) {
          value = (*anchor)[j] + random.uniform(-0.02, 0.02) * span;
        } else if (press && j == kinematics::kInsertion) {
          value = (*deepest)[j] + random.uniform(-0.002, 0.006);  // up to 6 mm deeper
        } else if (press && j != kinematics::kGrip) {
          value = (*deepest)[j] + random.uniform(-0.01, 0.01) * span;
        }
        pose[j] = std::clamp(value, joint.min_position, joint.max_position);
      }
      out << time_s << ',' << device.name;
      for (const double value : pose) out << ',' << value;
      out << '\n';
      ++keyframes;
    }
  }
  return path;
}

struct RunCoverage {
  std::uint64_t cycles = 0;
  std::uint64_t armed_cycles = 0;
  std::uint64_t armed_outside_range_cycles = 0;
  std::uint64_t arms = 0;
  std::uint64_t glitches = 0;
  std::uint64_t model_perturbations = 0;
  std::uint64_t overrun_faults = 0;
  std::uint64_t contact_cycles = 0;           // instrument-cycles in contact (app statistics)
  std::uint64_t model_contact_cycles = 0;     // cycles a tool held a modal model's wall
  std::uint64_t catheter_contact_cycles = 0;  // instrument-cycles pushing a catheter
  std::uint64_t model_step_errors = 0;
  std::array<std::uint64_t, safety::kFaultKinds> raised{};
};

// One scene on the simulated bench in the real loop, every cycle randomised and checked.
class ScenePropertyRun final : public loop::CycleTask {
 public:
  // `drift_probability`: per cycle, that an encoder channel starts drifting.
  ScenePropertyRun(std::uint64_t seed, std::string name, double drift_probability)
      : random_(seed), seed_(seed), name_(std::move(name)), drift_probability_(drift_probability) {}

  void setup(const std::filesystem::path& scene_file, const std::filesystem::path& duct_image_path,
             std::uint64_t cycles) {
    auto scene = config::load_scene(scene_file);
    ASSERT_TRUE(scene) << scene.error().message;
    scene_ = std::move(*scene);
    scene_.trainee.script =
        write_random_trainee(
            scene_, random_,
            static_cast<double>(cycles * static_cast<std::uint64_t>(scene_.loop.period_ns)) * 1e-9,
            name_)
            .string();
    for (config::SceneModelConfig& entry : scene_.models) {
      if (entry.definition.kind == config::ModelKind::modal_shell) {
        ASSERT_FALSE(duct_image_path.empty()) << "the duct image could not be built";
        entry.definition.image_path = duct_image_path;
      }
    }
    device_ = std::make_unique<hal::sim::SimDevice>(clock_, sim_params_from(scene_));
    ASSERT_TRUE(device_->configure());
    ASSERT_TRUE(device_->activate());

    std::vector<double> max_effort;
    std::vector<bool> used(device_->actuator_count(), false);
    for (const config::InstrumentDeviceConfig& instrument : scene_.device.instruments) {
      for (std::size_t j = 0; j < kJointCount; ++j) {
        const config::JointConfig& joint = instrument.joints[j];
        max_effort.push_back(config::joint_scale(joint).max_effort());
        min_position_.push_back(joint.min_position);
        max_position_.push_back(joint.max_position);
        prismatic_.push_back(joint.kind == hal::JointKind::prismatic);
      }
    }
    for (const config::SceneInstrumentConfig& instrument : scene_.instruments) {
      first_channels_.push_back(instrument.device_instrument * kJointCount);
      for (std::size_t j = 0; j < kJointCount; ++j)
        used[instrument.device_instrument * kJointCount + j] = true;
    }
    encoders_ = std::make_unique<HostileEncoders>(*device_->encoders());
    inputs_ = std::make_unique<HostileDigitalInputs>(*device_->digital_inputs());
    actuators_ = std::make_unique<CheckingActuators>(*device_->actuators(), max_effort, used);

    auto arena = core::Arena::create(scene_.memory.arena_bytes);
    ASSERT_TRUE(arena) << arena.error().message;
    arena_ = std::make_unique<core::Arena>(std::move(*arena));
    auto app = HapticApp::create(
        scene_, {encoders_.get(), actuators_.get(), inputs_.get(), device_->digital_outputs()},
        *arena_, log_, telemetry_, clock_);
    ASSERT_TRUE(app) << app.error().message;
    app_ = std::move(*app);
    arena_->seal();
    actuators_->app = app_.get();
    held_.assign(scene_.instruments.size(), {});
    has_held_.assign(scene_.instruments.size(), false);
    catheter_hold_release_.assign(16, 0);
  }

  void run(std::uint64_t cycles) {
    const auto started = std::chrono::steady_clock::now();
    app_->request_reset();  // the trainer's explicit reset at start
    reset_requested_ = true;
    loop::PeriodicLoop periodic(
        clock_,
        loop::LoopSettings{scene_.loop.period_ns, scene_.loop.overrun_streak_limit, cycles});
    periodic.run(*this, stop_);
    app_->shutdown();
    check_write_failure("shutdown");
    for (std::size_t c = 0; c < device_->actuator_count() && failure_.empty(); ++c) {
      if (device_->applied_effort(c) != 0.0)
        failure_ = "effort applied after shutdown on channel " + std::to_string(c);
    }
    seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
      coverage_.raised[kind] = app_->safety().fault_counts()[kind];
    }
    coverage_.overrun_faults = periodic.stats().overrun_fault ? 1 : 0;
    for (std::size_t i = 0; i < scene_.instruments.size(); ++i) {
      coverage_.contact_cycles += app_->stats().instruments[i].contact_cycles;
      coverage_.catheter_contact_cycles += app_->stats().instruments[i].catheter_contact_cycles;
    }
    coverage_.model_step_errors = app_->stats().model_step_errors;
    for (std::size_t m = 0; m < HapticAppTestAccess::modal_count(*app_); ++m) {
      coverage_.model_contact_cycles += app_->stats().modal_models[m].tool_contact_cycles;
    }
  }

  core::Status run_cycle(const loop::CycleTiming& timing) noexcept override {
    if (!failure_.empty()) return core::Status::ok();
    events_.clear();
    const std::uint32_t published_before = published_;
    const std::uint32_t latched_before = app_->safety().latched_faults();
    const std::array<std::uint64_t, safety::kFaultKinds> counts_before =
        app_->safety().fault_counts();
    // Raised by the loop between the cycles (the overrun-streak fault).
    std::uint32_t between = 0;
    for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
      if (counts_before[kind] != counts_end_[kind]) between |= 1U << kind;
    }
    const std::uint32_t arms_before = app_->safety().arm_count();
    inject(timing);
    const bool reset_this_cycle = reset_requested_;
    reset_requested_ = false;
    inputs_->failed = false;
    const std::uint64_t reads_before = encoders_->reads;

    (void)app_->run_cycle(timing);

    ++coverage_.cycles;
    const safety::SafetySupervisor& safety = app_->safety();
    const std::uint32_t latched = safety.latched_faults();
    const bool armed_now = safety.armed();
    const bool armed_this_cycle = safety.arm_count() != arms_before;
    std::uint32_t raised = between;
    for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
      if (safety.fault_counts()[kind] != counts_before[kind]) raised |= 1U << kind;
    }
    counts_end_ = safety.fault_counts();
    check_write_failure("cycle");

    // The telemetry: this cycle's snapshot, the latched faults, the efforts written.
    if (!telemetry_.update()) fail(timing, "no telemetry published");
    const TelemetrySnapshot& snapshot = telemetry_.latest();
    if (snapshot.cycle != timing.cycle_index) fail(timing, "telemetry of another cycle");
    if (snapshot.latched_faults != latched)
      fail(timing, "telemetry's latched faults differ from the chain's");
    published_ = snapshot.latched_faults;
    for (std::size_t i = 0; i < first_channels_.size(); ++i) {
      const InstrumentTelemetry& instrument = snapshot.instruments[i];
      double force_squared = 0.0;
      for (const float component : instrument.force_n) {
        force_squared += static_cast<double>(component) * static_cast<double>(component);
      }
      if (!(std::sqrt(force_squared) <= scene_.safety.max_force_n * (1.0 + 1e-5))) {
        fail(timing, "telemetry force beyond max_force_n or non-finite");
      }
      for (std::size_t j = 0; j < kJointCount; ++j) {
        const float written = actuators_->last[first_channels_[i] + j].effort;
        if (instrument.joint_efforts[j] != written) {
          fail(timing, "telemetry effort differs from the command written");
        }
      }
    }

    // No fault lost: what was raised is latched and published now; latched faults clear only
    // when an explicit reset arms; a newly published fault is logged.
    const std::uint32_t reportable = ~safety::bit(safety::Fault::not_armed);
    if ((raised & ~latched) != 0) {
      fail(timing, "fault raised but not latched at the end of the cycle (raised " +
                       std::to_string(raised) + ", latched " + std::to_string(latched) + ")");
    }
    if (!armed_this_cycle && (latched & (latched_before | between)) != (latched_before | between)) {
      fail(timing, "a latched fault cleared without an explicit reset");
    }
    if (armed_this_cycle && !reset_this_cycle) fail(timing, "armed without a reset request");
    if (armed_this_cycle) ++coverage_.arms;
    const std::uint32_t newly =
        (armed_this_cycle ? latched : latched & ~published_before) & reportable;
    std::uint32_t logged = 0;
    core::LogRecord record;
    while (log_.pop(record)) {
      if (std::strcmp(record.format, "fault latched: {} at cycle {}") != 0) continue;
      for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
        if (std::strcmp(record.args[0].s,
                        safety::to_string(static_cast<safety::Fault>(1U << kind))) == 0) {
          logged |= 1U << kind;
        }
      }
    }
    if ((newly & ~logged) != 0) {
      fail(timing, "fault latched and published but not logged (new " + std::to_string(newly) +
                       ", logged " + std::to_string(logged) + ")");
    }
    if (log_.dropped() != 0) fail(timing, "log records dropped");

    // The faults the injected causes imply.
    check_expected_faults(timing, latched, reads_before);

    if (armed_now) {
      ++coverage_.armed_cycles;
      bool outside = false;
      for (std::size_t i = 0; i < first_channels_.size(); ++i) {
        for (std::size_t j = 0; j < kJointCount; ++j) {
          const std::size_t c = first_channels_[i] + j;
          const double position = static_cast<double>(snapshot.instruments[i].joints[j]);
          outside = outside || position < min_position_[c] || position > max_position_[c];
        }
      }
      if (outside) ++coverage_.armed_outside_range_cycles;
    }
    if (!failure_.empty()) stop_.store(true);
    // A step that takes long: overruns, a long dt next cycle, the overrun-streak fault.
    if (random_.chance(0.001)) {
      const auto stall_ns = static_cast<std::int64_t>(random_.uniform(0.2, 30.0) *
                                                      static_cast<double>(scene_.loop.period_ns));
      clock_.advance_ns(stall_ns);
      events_ += " stall " + std::to_string(stall_ns) + " ns;";
    }
    return core::Status::ok();
  }

  void on_overrun_fault(std::uint32_t streak) noexcept override {
    app_->on_overrun_fault(streak);
    check_write_failure("overrun fault");
  }

  const std::string& failure() const { return failure_; }
  const RunCoverage& coverage() const { return coverage_; }
  const CheckingActuators& actuators() const { return *actuators_; }
  double seconds() const { return seconds_; }

 private:
  void fail(const loop::CycleTiming& timing, const std::string& what) {
    if (!failure_.empty()) return;
    std::ostringstream text;
    text << name_ << ", cycle " << timing.cycle_index << " (dt " << timing.dt_s << " s): " << what
         << "\n  events this cycle:" << events_ << "\n  replay: TRAINER_PROPERTY_SEED=" << seed_
         << " force_property_test --gtest_filter=HapticAppProperty.*";
    failure_ = text.str();
  }
  void check_write_failure(const char* where) {
    if (failure_.empty() && !actuators_->failure.empty()) {
      failure_ = name_ + ", " + where + ": " + actuators_->failure +
                 "\n  events this cycle:" + events_ +
                 "\n  replay: TRAINER_PROPERTY_SEED=" + std::to_string(seed_) +
                 " force_property_test --gtest_filter=HapticAppProperty.*";
      stop_.store(true);
    }
  }

  // This cycle's random events, before the cycle runs.
  void inject(const loop::CycleTiming& timing) {
    hal::sim::SimDevice& device = *device_;
    const std::size_t channels = device.channel_count();
    const double dt_s = timing.dt_s;
    // The bench's switches and faults.
    if (random_.chance(estop_ ? 0.05 : 0.0005)) {
      estop_ = !estop_;
      device.set_estop(estop_);
      events_ += estop_ ? " e-stop pressed;" : " e-stop released;";
    }
    if (random_.chance(drive_fault_ ? 0.05 : 0.0005)) {
      drive_fault_ = !drive_fault_;
      if (drive_fault_) drive_fault_channel_ = random_.index(channels);
      (void)device.inject_drive_fault(drive_fault_channel_, drive_fault_);
      events_ += " drive fault " + std::string(drive_fault_ ? "on" : "off") + " channel " +
                 std::to_string(drive_fault_channel_) + ";";
    }
    if (random_.chance(0.0005)) {
      const auto count = static_cast<std::uint32_t>(1 + random_.index(6));
      device.inject_read_failures(count);
      events_ += " " + std::to_string(count) + " read failures;";
    }
    // A stuck encoder comes loose after 10 ms to 2 s (when it does, its reading jumps).
    for (std::size_t channel = 0; channel < channels; ++channel) {
      if (stuck_until_[channel] != 0 && timing.cycle_index >= stuck_until_[channel]) {
        (void)device.inject_stuck_encoder(channel, false);
        stuck_until_[channel] = 0;
        events_ += " encoder " + std::to_string(channel) + " unstuck;";
      }
    }
    if (random_.chance(0.0005)) {
      const std::size_t channel = random_.index(channels);
      if (stuck_until_[channel] == 0) {
        (void)device.inject_stuck_encoder(channel, true);
        stuck_until_[channel] = timing.cycle_index + 10 + random_.index(1990);
        events_ += " encoder " + std::to_string(channel) + " stuck;";
      }
    }
    if (random_.chance(0.0003)) {
      const auto delay_ns = static_cast<std::int64_t>(random_.uniform(0.5, 20.0) *
                                                      static_cast<double>(scene_.loop.period_ns));
      const auto count = static_cast<std::uint32_t>(1 + random_.index(15));
      device.inject_late_reply(delay_ns, count);
      events_ +=
          " " + std::to_string(count) + " late replies of " + std::to_string(delay_ns) + " ns;";
    }
    if (random_.chance(0.0005)) {
      inputs_->fail_next = true;
      events_ += " digital input read fails;";
    }
    if (random_.chance(0.0005)) {
      actuators_->force_write_code =
          random_.chance(0.5) ? hal::ReturnCode::error : hal::ReturnCode::deactivate;
      events_ += " actuator write returns " +
                 std::string(hal::to_string(actuators_->force_write_code)) + ";";
    }
    if (random_.chance(0.0005)) {
      actuators_->fault_next_status = true;
      actuators_->fault_channel = random_.index(channels);
      events_ += " actuator status reports a fault;";
    }
    // The encoders: drifts (armed far outside the range) and glitches. A drift creeps back
    // to zero after 0.1–3 s.
    for (std::size_t c = 0; c < channels; ++c) {
      if (drift_until_[c] != 0 && timing.cycle_index >= drift_until_[c]) {
        encoders_->drift(c, 0.0F, drift_rate_[c]);
        drift_until_[c] = 0;
      }
    }
    if (random_.chance(drift_probability_)) {
      const std::size_t c = random_.index(channels);
      const double span = max_position_[c] - min_position_[c];
      const double speed = prismatic_[c] ? scene_.safety.max_insertion_speed_m_per_s
                                         : scene_.safety.max_joint_speed_rad_per_s;
      const auto target = static_cast<float>(random_.uniform(-2.0, 2.0) * span);
      const auto rate = static_cast<float>(random_.uniform(0.01, 0.3) * speed * 1e-9 *
                                           static_cast<double>(scene_.loop.period_ns));
      encoders_->drift(c, target, rate);
      drift_rate_[c] = rate;
      drift_until_[c] = timing.cycle_index + 100 + random_.index(2900);
      events_ +=
          " encoder " + std::to_string(c) + " drifts to " + property::number_text(target) + ";";
    }
    if (random_.chance(0.003)) {
      HostileEncoders::Plan& plan = encoders_->plan;
      plan.channel = random_.index(channels);
      const std::size_t c = plan.channel;
      const double speed = prismatic_[c] ? scene_.safety.max_insertion_speed_m_per_s
                                         : scene_.safety.max_joint_speed_rad_per_s;
      const double span = max_position_[c] - min_position_[c];
      switch (random_.index(7)) {
        case 0:
          plan.glitch = HostileEncoders::Glitch::jitter;
          plan.value = static_cast<float>(random_.uniform(-0.4, 0.4) * speed * dt_s);
          break;
        case 1:
          plan.glitch = HostileEncoders::Glitch::jump;
          plan.value =
              static_cast<float>(random_.sign() * random_.log_uniform(2.0, 1e3) * speed * dt_s);
          break;
        case 2:
          plan.glitch = HostileEncoders::Glitch::teleport;
          plan.value =
              static_cast<float>(random_.uniform(min_position_[c] - span, max_position_[c] + span));
          break;
        case 3:
          plan.glitch = HostileEncoders::Glitch::hostile_value;
          plan.value = random_.hostile();
          break;
        case 4: plan.glitch = HostileEncoders::Glitch::invalid; break;
        case 5: plan.code = hal::ReturnCode::error; break;
        default:
          plan.code = random_.chance(0.2) ? hal::ReturnCode::deactivate : hal::ReturnCode::error;
          break;
      }
      ++coverage_.glitches;
      events_ += " encoder glitch " + std::to_string(static_cast<int>(plan.glitch)) +
                 " on channel " + std::to_string(c) + " value " +
                 property::number_text(plan.value) + " code " + hal::to_string(plan.code) + ";";
    }
    perturb_models(timing);
    // Explicit resets: often while faulted, rarely while armed.
    if (random_.chance(app_->safety().armed() ? 0.0005 : 0.05)) {
      app_->request_reset();
      reset_requested_ = true;
      events_ += " reset requested;";
    }
  }

  void perturb_models(const loop::CycleTiming& timing) {
    HapticApp& app = *app_;
    for (std::size_t m = 0; m < HapticAppTestAccess::modal_count(app); ++m) {
      if (random_.chance(0.01)) {
        // Mostly up to the tools' own forces; one load in twenty up to 10^4 N, which throws the
        // duct metres out of shape (it is linear) for the tenth of a second it takes to ring
        // down.
        const std::size_t loads = 1 + random_.index(5);
        const auto vertices = HapticAppTestAccess::modal_vertex_count(app, m);
        for (std::size_t k = 0; k < loads; ++k) {
          const double magnitude_n =
              random_.chance(0.05) ? random_.log_uniform(1.0, 1e4) : random_.log_uniform(1e-3, 1.0);
          Vec3 force = random_.unit_vector() * static_cast<float>(magnitude_n);
          if (random_.chance(0.02))
            force[static_cast<Eigen::Index>(random_.index(3))] = random_.hostile();
          (void)HapticAppTestAccess::add_modal_load(
              app, m, static_cast<std::uint32_t>(random_.index(vertices)), force);
        }
        ++coverage_.model_perturbations;
        events_ += " " + std::to_string(loads) + " loads on model " + std::to_string(m) + ";";
      }
      if (random_.chance(0.0005)) {
        HapticAppTestAccess::reset_modal(app, m);
        events_ += " model " + std::to_string(m) + " reset;";
      }
    }
    for (std::size_t c = 0; c < HapticAppTestAccess::catheter_count(app); ++c) {
      model::Catheter& catheter = HapticAppTestAccess::catheter(app, c);
      const std::uint32_t particles = catheter.particle_count();
      for (std::uint32_t p = 0; p < particles && p < catheter_hold_release_.size(); ++p) {
        if (catheter_hold_release_[p] != 0 && timing.cycle_index >= catheter_hold_release_[p]) {
          (void)catheter.release(p);
          catheter_hold_release_[p] = 0;
        }
      }
      if (random_.chance(0.005)) {
        // A particle dragged somewhere around the duct's opening, the tools and beyond.
        const auto p = static_cast<std::uint32_t>(random_.index(particles));
        const Vec3 around(-0.02F, 0.0F, -0.1F);
        Vec3 target =
            around + random_.unit_vector() * static_cast<float>(random_.log_uniform(1e-4, 0.2));
        if (random_.chance(0.02))
          target[static_cast<Eigen::Index>(random_.index(3))] = random_.hostile();
        (void)catheter.hold(p, target);
        if (p < catheter_hold_release_.size()) {
          catheter_hold_release_[p] = timing.cycle_index + 1 + random_.index(300);
        }
        ++coverage_.model_perturbations;
        events_ += " catheter particle " + std::to_string(p) + " held at " +
                   property::vec_text(target) + ";";
      }
      if (random_.chance(0.0005)) {
        catheter.reset();
        std::fill(catheter_hold_release_.begin(), catheter_hold_release_.end(), 0);
        events_ += " catheter reset;";
      }
    }
  }

  // The faults the injected causes and the delivered readings imply at the end of the cycle.
  void check_expected_faults(const loop::CycleTiming& timing, std::uint32_t latched,
                             std::uint64_t reads_before) {
    const auto expect = [&](safety::Fault fault, const char* why) {
      if ((latched & safety::bit(fault)) == 0) {
        fail(timing, std::string(safety::to_string(fault)) + " not latched: " + why);
      }
    };
    if (estop_) expect(safety::Fault::estop, "the e-stop is pressed");
    if (inputs_->failed) expect(safety::Fault::estop, "the safety inputs could not be read");
    if (drive_fault_) expect(safety::Fault::drive_fault, "a drive reports a fault");
    if (encoders_->reads == reads_before) {
      fail(timing, "the cycle did not read the encoders");
      return;
    }
    const hal::ReturnCode code = encoders_->delivered_code;
    read_error_streak_ = code == hal::ReturnCode::ok ? 0 : read_error_streak_ + 1;
    if (code == hal::ReturnCode::deactivate)
      expect(safety::Fault::device_lost, "the encoders went to their safe state");
    if (read_error_streak_ > HapticApp::kToleratedErrorStreak) {
      expect(safety::Fault::device_lost, "encoder reads failed beyond the tolerated streak");
    }
    // Each instrument takes a reading whose five channels are all valid (else holds the last).
    const auto dt = static_cast<float>(timing.dt_s);
    for (std::size_t i = 0; i < first_channels_.size(); ++i) {
      bool all_valid = true;
      for (std::size_t j = 0; j < kJointCount; ++j)
        all_valid = all_valid && encoders_->delivered[first_channels_[i] + j].valid;
      if (!all_valid) continue;
      for (std::size_t j = 0; j < kJointCount; ++j) {
        const std::size_t c = first_channels_[i] + j;
        const float position = encoders_->delivered[c].position;
        if (!std::isfinite(position)) {
          expect(safety::Fault::non_finite, "a valid encoder reading is not finite");
        } else if (has_held_[i] && std::isfinite(held_[i][j])) {
          const double speed = prismatic_[c] ? scene_.safety.max_insertion_speed_m_per_s
                                             : scene_.safety.max_joint_speed_rad_per_s;
          const double step =
              std::fabs(static_cast<double>(position) - static_cast<double>(held_[i][j]));
          const double allowed =
              static_cast<double>(static_cast<float>(speed)) * static_cast<double>(dt);
          if (step > allowed * (1.0 + 1e-4))
            expect(safety::Fault::encoder_jump, "a joint moved faster than allowed");
        }
        held_[i][j] = position;
      }
      has_held_[i] = true;
    }
  }

  property::Random random_;
  std::uint64_t seed_;
  std::string name_;
  double drift_probability_;
  config::SceneConfig scene_;
  core::ManualClock clock_{0};
  std::unique_ptr<hal::sim::SimDevice> device_;
  std::unique_ptr<HostileEncoders> encoders_;
  std::unique_ptr<HostileDigitalInputs> inputs_;
  std::unique_ptr<CheckingActuators> actuators_;
  std::unique_ptr<core::Arena> arena_;
  core::LogRing log_;
  core::TripleBuffer<TelemetrySnapshot> telemetry_;
  std::unique_ptr<HapticApp> app_;
  std::atomic<bool> stop_{false};

  std::vector<std::size_t> first_channels_;
  std::vector<double> min_position_, max_position_;
  std::vector<bool> prismatic_;
  std::array<std::uint64_t, hal::sim::kMaxChannels> stuck_until_{};  // 0: not stuck
  std::array<std::uint64_t, hal::sim::kMaxChannels> drift_until_{};  // 0: no drift going out
  std::array<float, hal::sim::kMaxChannels> drift_rate_{};
  std::vector<std::array<float, kJointCount>> held_;
  std::vector<bool> has_held_;
  std::vector<std::uint64_t> catheter_hold_release_;
  std::uint32_t read_error_streak_ = 0;
  bool estop_ = false;
  bool drive_fault_ = false;
  std::size_t drive_fault_channel_ = 0;
  bool reset_requested_ = false;
  std::uint32_t published_ = 0;
  std::array<std::uint64_t, safety::kFaultKinds> counts_end_{};
  std::string events_;
  std::string failure_;
  RunCoverage coverage_;
  double seconds_ = 0.0;
};

void report(const char* name, const ScenePropertyRun& run) {
  const RunCoverage& c = run.coverage();
  std::printf(
      "%s: %llu cycles in %.2f s, %llu writes (%llu commands) checked; armed %llu cycles "
      "(%llu with a joint outside its range), %llu writes pushing, %llu commands at a "
      "limit; arms %llu, encoder glitches %llu, model perturbations %llu, overrun fault %llu; "
      "contact %llu and catheter contact %llu instrument-cycles, tool on a duct %llu cycles, "
      "model step errors %llu\n"
      "  faults raised:",
      name, static_cast<unsigned long long>(c.cycles), run.seconds(),
      static_cast<unsigned long long>(run.actuators().writes),
      static_cast<unsigned long long>(run.actuators().commands_checked),
      static_cast<unsigned long long>(c.armed_cycles),
      static_cast<unsigned long long>(c.armed_outside_range_cycles),
      static_cast<unsigned long long>(run.actuators().pushing_writes),
      static_cast<unsigned long long>(run.actuators().at_limit),
      static_cast<unsigned long long>(c.arms), static_cast<unsigned long long>(c.glitches),
      static_cast<unsigned long long>(c.model_perturbations),
      static_cast<unsigned long long>(c.overrun_faults),
      static_cast<unsigned long long>(c.contact_cycles),
      static_cast<unsigned long long>(c.catheter_contact_cycles),
      static_cast<unsigned long long>(c.model_contact_cycles),
      static_cast<unsigned long long>(c.model_step_errors));
  for (std::size_t kind = 0; kind < safety::kFaultKinds; ++kind) {
    std::printf(" %s %llu", safety::to_string(static_cast<safety::Fault>(1U << kind)),
                static_cast<unsigned long long>(c.raised[kind]));
  }
  std::printf("\n");
}

TEST(HapticAppProperty, WallSceneCommandsStayFiniteWithinLimitsAndNoFaultIsLost) {
  const std::uint64_t seed = property::seed_for("HapticAppProperty wall", kCycleSeed);
  const std::uint64_t cycles = property::env_u64("TRAINER_PROPERTY_CYCLES").value_or(kWallCycles);
  // Drifts take the one instrument beyond its range, where its levers reach the effort limits.
  ScenePropertyRun run(seed, "wall", 1e-3);
  ASSERT_NO_FATAL_FAILURE(run.setup(property::kRepo / "config/scenes/wall.toml", {}, cycles));
  run.run(cycles);
  report("HapticAppProperty wall", run);
  ASSERT_TRUE(run.failure().empty()) << run.failure();
  EXPECT_EQ(run.coverage().cycles, cycles);
  // The run reached what the property is about.
  EXPECT_GT(run.coverage().armed_cycles, cycles / 2);
  EXPECT_GT(run.actuators().pushing_writes, cycles / 10);
  // The effort limits are reached when a drift takes the insertion far beyond its range while
  // the tip presses the wall: a few hundred cycles in the release run's 300,000, not always any
  // in the sanitizer build's 40,000.
  if (!kSanitizerBuild) {
    EXPECT_GT(run.actuators().at_limit, cycles / 6000);
  }
  EXPECT_GT(run.coverage().armed_outside_range_cycles, cycles / 100);
  EXPECT_GT(run.coverage().arms, 10U);
}

TEST(HapticAppProperty, CbdSceneCommandsStayFiniteWithinLimitsAndNoFaultIsLost) {
  const std::uint64_t seed = property::seed_for("HapticAppProperty cbd", kCycleSeed ^ 0xCBDU);
  const std::uint64_t cycles = property::env_u64("TRAINER_PROPERTY_CYCLES").value_or(kCbdCycles);
  const std::filesystem::path& image = duct_image();
  ASSERT_FALSE(image.empty()) << "building the duct image failed";
  ASSERT_EQ(test::build_catheter_images(property::kRepo / "config/scenes/cbd.toml"), "");
  // Fewer drifts: a drifted joint takes a tool off the small duct.
  ScenePropertyRun run(seed, "cbd", 2e-4);
  ASSERT_NO_FATAL_FAILURE(run.setup(property::kRepo / "config/scenes/cbd.toml", image, cycles));
  run.run(cycles);
  report("HapticAppProperty cbd", run);
  ASSERT_TRUE(run.failure().empty()) << run.failure();
  EXPECT_EQ(run.coverage().cycles, cycles);
  EXPECT_GT(run.coverage().armed_cycles, cycles / 2);
  EXPECT_GT(run.actuators().pushing_writes, cycles / 10);
  EXPECT_GT(run.coverage().catheter_contact_cycles, cycles / 100);
  EXPECT_GT(run.coverage().model_contact_cycles, cycles / 20);
  EXPECT_GT(run.coverage().model_perturbations, cycles / 100);
}

// Hand-made cases the random runs met or could meet, on the wall scene with both instruments
// (the right one touching the wall too), the right encoder readings under the test's control.
class TwoInstrumentWall : public ::testing::Test {
 protected:
  void SetUp() override {
    std::ifstream in(property::kRepo / "config/scenes/wall.toml");
    std::ostringstream text;
    text << in.rdbuf();
    std::string scene = text.str();
    const auto replace = [&](const std::string& from, const std::string& to) {
      const std::size_t at = scene.find(from);
      ASSERT_NE(at, std::string::npos) << from;
      scene.replace(at, from.size(), to);
    };
    replace("\"../devices/sim.toml\"",
            "\"" + (property::kRepo / "config/devices/sim.toml").string() + "\"");
    replace("\"../trajectories/wall_press.csv\"",
            "\"" + (property::kRepo / "config/trajectories/wall_press.csv").string() + "\"");
    replace("touched_by = [\"left\"]", "touched_by = [\"left\", \"right\"]");
    replace("[[object]]",
            "[[instrument]]\nname = \"right\"\ndevice_instrument = \"right\"\n\n[[object]]");
    const std::filesystem::path file = TemporaryDirectory::path() / "two_instrument_wall.toml";
    std::ofstream(file) << scene;
    auto loaded = config::load_scene(file);
    ASSERT_TRUE(loaded) << loaded.error().message;
    scene_ = std::move(*loaded);
    device_ = std::make_unique<hal::sim::SimDevice>(clock_, sim_params_from(scene_));
    ASSERT_TRUE(device_->configure());
    ASSERT_TRUE(device_->activate());
    encoders_ = std::make_unique<HostileEncoders>(*device_->encoders());
    auto arena = core::Arena::create(scene_.memory.arena_bytes);
    ASSERT_TRUE(arena);
    arena_ = std::make_unique<core::Arena>(std::move(*arena));
    auto app = HapticApp::create(scene_,
                                 {encoders_.get(), device_->actuators(), device_->digital_inputs(),
                                  device_->digital_outputs()},
                                 *arena_, log_, telemetry_, clock_);
    ASSERT_TRUE(app) << app.error().message;
    app_ = std::move(*app);
    // The right instrument has not been read yet.
    for (std::size_t c = kJointCount; c < 2 * kJointCount; ++c) encoders_->invalid[c] = true;
    app_->request_reset();
  }
  void step() {
    clock_.advance_ns(scene_.loop.period_ns);
    loop::CycleTiming timing{};
    timing.cycle_index = cycle_++;
    timing.deadline_ns = timing.wake_ns = clock_.now_ns();
    timing.dt_s = static_cast<double>(scene_.loop.period_ns) * 1e-9;
    (void)app_->run_cycle(timing);
  }
  double applied_effort() const {
    double total = 0.0;
    for (std::size_t c = 0; c < device_->actuator_count(); ++c)
      total += std::fabs(device_->applied_effort(c));
    return total;
  }

  config::SceneConfig scene_;
  core::ManualClock clock_{0};
  std::unique_ptr<hal::sim::SimDevice> device_;
  std::unique_ptr<HostileEncoders> encoders_;
  std::unique_ptr<core::Arena> arena_;
  core::LogRing log_;
  core::TripleBuffer<TelemetrySnapshot> telemetry_;
  std::unique_ptr<HapticApp> app_;
  std::uint64_t cycle_ = 0;
};

TEST_F(TwoInstrumentWall, ANonFiniteFirstReadingLatches) {
  for (int i = 0; i < 10; ++i) step();
  ASSERT_TRUE(app_->safety().armed());
  // The right instrument's first reading: roll NaN. No jaw force uses roll, so no effort turns
  // NaN; the reading itself must latch the fault.
  for (std::size_t c = kJointCount; c < 2 * kJointCount; ++c) encoders_->invalid[c] = false;
  encoders_->forced[kJointCount + kinematics::kRoll] = std::numeric_limits<float>::quiet_NaN();
  step();
  EXPECT_EQ(app_->safety().first_fault(), safety::Fault::non_finite);
  EXPECT_EQ(applied_effort(), 0.0);
}

TEST_F(TwoInstrumentWall, TelemetryReportsNoForceInACycleAnotherInstrumentFaulted) {
  while (clock_.now_ns() < 7'000'000'000) step();  // the left tip presses the wall
  ASSERT_TRUE(app_->safety().armed());
  ASSERT_TRUE(telemetry_.update());
  ASSERT_GT(std::fabs(telemetry_.latest().instruments[0].force_n[2]), 0.5F);
  // The right instrument's first reading puts its tip 1e37 m behind the wall: its penalty
  // force overflows, and the chain faults after the left one was rendered.
  for (std::size_t c = kJointCount; c < 2 * kJointCount; ++c) encoders_->invalid[c] = false;
  encoders_->forced[kJointCount + kinematics::kInsertion] = 1e37F;
  step();
  ASSERT_EQ(app_->safety().first_fault(), safety::Fault::non_finite);
  EXPECT_EQ(applied_effort(), 0.0);
  ASSERT_TRUE(telemetry_.update());
  for (std::size_t i = 0; i < 2; ++i) {
    const InstrumentTelemetry& out = telemetry_.latest().instruments[i];
    for (const float value : out.force_n) EXPECT_EQ(value, 0.0F) << "instrument " << i;
    for (const float value : out.joint_efforts) EXPECT_EQ(value, 0.0F) << "instrument " << i;
  }
}

}  // namespace
}  // namespace trainer::app
