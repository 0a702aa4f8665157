// Tests of load_scene: the repository's wall scene (and a copy with its own trajectory file in
// a temporary tree), defaults, multi-instrument scenes, and one specific message per kind of
// mistake, each asserted to name the file, the line, the key, the bad value and the expected
// range/unit.
#include <gtest/gtest.h>

#include <string>
#include <string_view>

#include "config_test_files.hpp"
#include "trainer/config/scene.hpp"

namespace trainer::config {
namespace {

using testing::ConfigFileTest;
using testing::expect_contains;
using testing::line_of;
using testing::read_text;
using testing::replace_first;
using testing::repo_path;

std::string error_message(const core::Expected<SceneConfig>& result) {
  EXPECT_FALSE(result.has_value()) << "expected the load to fail";
  return result.has_value() ? std::string{} : result.error().message;
}

// ---------------------------------------------------------------- the repository file

// The trajectory CSV belongs to someone else and may be absent: check it only by path here.
TEST(WallSceneFile, LoadsWithSiValuesAndItsDevice) {
  const auto scene =
      load_scene(repo_path("config/scenes/wall.toml"), LoadOptions{.require_script_file = false});
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  EXPECT_EQ(scene->name, "wall");
  EXPECT_TRUE(scene->source_path.is_absolute());
  EXPECT_EQ(scene->loop.period_ns, 1'000'000);  // 1000 us
  EXPECT_EQ(scene->loop.overrun_streak_limit, 10U);
  EXPECT_EQ(scene->loop.priority, 80);
  EXPECT_EQ(scene->loop.cpu, 1);
  EXPECT_TRUE(scene->loop.lock_memory);
  EXPECT_EQ(scene->loop.stack_prefault_bytes, 256U * 1024U);
  EXPECT_EQ(scene->memory.arena_bytes, 1024U * 1024U);
  EXPECT_DOUBLE_EQ(scene->safety.max_force_n, 8.0);
  EXPECT_DOUBLE_EQ(scene->safety.max_force_rate_n_per_s, 4000.0);
  EXPECT_DOUBLE_EQ(scene->safety.max_joint_speed_rad_per_s, 20.0);
  EXPECT_DOUBLE_EQ(scene->safety.max_insertion_speed_m_per_s, 1.0);
  EXPECT_DOUBLE_EQ(scene->safety.passivity_energy_bound_j, 0.5);
  EXPECT_FALSE(scene->safety.require_enable_input);
  EXPECT_FALSE(is_builtin_script(scene->trainee.script));
  EXPECT_EQ(std::filesystem::path(scene->trainee.script),
            repo_path("config/trajectories/wall_press.csv").lexically_normal());

  EXPECT_EQ(scene->device.name, "sim-two-port");
  ASSERT_EQ(scene->instruments.size(), 1U);
  EXPECT_EQ(scene->instruments[0].name, "left");
  const auto& device_left = scene->device.instruments.at(scene->instruments[0].device_instrument);
  EXPECT_EQ(device_left.name, "left");

  ASSERT_EQ(scene->objects.size(), 1U);
  const ObjectConfig& wall = scene->objects[0];
  EXPECT_EQ(wall.kind, ObjectKind::plane);
  EXPECT_DOUBLE_EQ(wall.stiffness_n_per_m, 400.0);
  EXPECT_DOUBLE_EQ(wall.damping_n_s_per_m, 1.0);
  EXPECT_EQ(wall.touched_by, (std::vector<std::size_t>{0}));
  // The wall is where the left tip arrives after 0.09 m of insertion, facing the tool.
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(wall.point_m[i],
                device_left.trocar_position_m[i] + 0.09 * device_left.shaft_axis[i], 1e-12);
    EXPECT_NEAR(wall.normal[i], -device_left.shaft_axis[i], 1e-12);
  }
}

// ---------------------------------------------------------------- copies in a temporary tree

// Lays out <root>/scenes, <root>/devices/sim.toml (the repository's) and
// <root>/trajectories/wall_press.csv, as the scene's relative paths expect.
class SceneFileTest : public ConfigFileTest {
 protected:
  void SetUp() override {
    ConfigFileTest::SetUp();
    device_path_ = write("devices/sim.toml", read_text(repo_path("config/devices/sim.toml")));
    script_path_ = write("trajectories/wall_press.csv", "time_s,insertion_m\n0,0\n1,0.1\n");
    wall_text_ = read_text(repo_path("config/scenes/wall.toml"));
  }
  std::filesystem::path write_scene(const std::string& text) const {
    return write("scenes/scene.toml", text);
  }

  std::filesystem::path device_path_;
  std::filesystem::path script_path_;
  std::string wall_text_;
};

TEST_F(SceneFileTest, WallCopyLoadsAndResolvesItsScriptFile) {
  const auto scene = load_scene(write_scene(wall_text_));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  EXPECT_EQ(std::filesystem::path(scene->trainee.script), script_path_);
  EXPECT_TRUE(scene->trainee.end_run_with_script);
  EXPECT_EQ(scene->device.source_path, device_path_);
}

TEST_F(SceneFileTest, MissingScriptIsAnErrorUnlessRelaxed) {
  std::filesystem::remove(script_path_);
  const auto path = write_scene(wall_text_);
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ":" + std::to_string(line_of(wall_text_, "script =")) +
                ": trainee.script: file '../trajectories/wall_press.csv' not found (resolved to " +
                script_path_.string() + ")");
  const auto relaxed = load_scene(path, LoadOptions{.require_script_file = false});
  ASSERT_TRUE(relaxed.has_value()) << relaxed.error().message;
  EXPECT_EQ(std::filesystem::path(relaxed->trainee.script), script_path_);
}

TEST_F(SceneFileTest, BuiltinScriptNeedsNoFile) {
  const auto edited =
      replace_first(wall_text_, "\"../trajectories/wall_press.csv\"", "\"builtin:hold\"");
  const auto scene = load_scene(write_scene(edited.text));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  EXPECT_EQ(scene->trainee.script, "builtin:hold");
  EXPECT_TRUE(is_builtin_script(scene->trainee.script));
}

constexpr std::string_view kSceneHead =
    "[scene]\nname = \"two\"\ndevice = \"../devices/sim.toml\"\n\n"
    "[loop]\nperiod_us = 500\n\n"
    "[safety]\nmax_force_n = 5\nmax_force_rate_n_per_s = 1000\nmax_joint_speed_rad_per_s = 10\n"
    "max_insertion_speed_m_per_s = 0.5\npassivity_energy_bound_j = 0\n"
    "require_enable_input = true\n\n";

// Scene names differ from device names on purpose: touched_by refers to the scene's names.
constexpr std::string_view kTwoInstruments =
    "[[instrument]]\nname = \"main\"\ndevice_instrument = \"right\"\n\n"
    "[[instrument]]\nname = \"assist\"\ndevice_instrument = \"left\"\n\n";

TEST_F(SceneFileTest, MinimalSceneGetsDefaultsAndResolvesNames) {
  const std::string text = std::string(kSceneHead) + std::string(kTwoInstruments) +
                           "[[object]]\nkind = \"sphere\"\nname = \"ball\"\n"
                           "center_m = [0, 0, -0.1]\nradius_m = 0.02\nstiffness_n_per_m = 300\n\n"
                           "[[object]]\nkind = \"plane\"\nname = \"floor\"\n"
                           "point_m = [0, 0, -0.2]\nnormal = [0, 0, 5]\n"
                           "stiffness_n_per_m = 1000\ntouched_by = [\"assist\"]\n";
  const auto scene = load_scene(write_scene(text));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  EXPECT_EQ(scene->loop.period_ns, 500'000);
  // Documented defaults.
  EXPECT_EQ(scene->loop.overrun_streak_limit, 10U);
  EXPECT_EQ(scene->loop.priority, 0);
  EXPECT_EQ(scene->loop.cpu, -1);
  EXPECT_FALSE(scene->loop.lock_memory);
  EXPECT_EQ(scene->loop.stack_prefault_bytes, 256U * 1024U);
  EXPECT_EQ(scene->memory.arena_bytes, 1024U * 1024U);
  EXPECT_EQ(scene->trainee.script, "builtin:hold");
  EXPECT_FALSE(scene->trainee.end_run_with_script);
  EXPECT_DOUBLE_EQ(scene->safety.passivity_energy_bound_j, 0.0);
  EXPECT_TRUE(scene->safety.require_enable_input);

  ASSERT_EQ(scene->instruments.size(), 2U);
  EXPECT_EQ(scene->instruments[0].device_instrument, 1U);  // "right" is the device's second
  EXPECT_EQ(scene->instruments[1].device_instrument, 0U);

  ASSERT_EQ(scene->objects.size(), 2U);
  const ObjectConfig& ball = scene->objects[0];
  EXPECT_EQ(ball.kind, ObjectKind::sphere);
  EXPECT_EQ(ball.center_m, (Vec3{0.0, 0.0, -0.1}));
  EXPECT_DOUBLE_EQ(ball.radius_m, 0.02);
  EXPECT_DOUBLE_EQ(ball.damping_n_s_per_m, 0.0);
  EXPECT_EQ(ball.touched_by, (std::vector<std::size_t>{0, 1}));  // default: every instrument
  const ObjectConfig& floor = scene->objects[1];
  EXPECT_EQ(floor.normal, (Vec3{0.0, 0.0, 1.0}));  // normalised
  EXPECT_EQ(floor.touched_by, (std::vector<std::size_t>{1}));
}

TEST_F(SceneFileTest, UnknownTouchedByNameListsTheSceneInstruments) {
  const std::string text = std::string(kSceneHead) + std::string(kTwoInstruments) +
                           "[[object]]\nkind = \"plane\"\nname = \"a\"\npoint_m = [0, 0, 0]\n"
                           "normal = [0, 0, 1]\nstiffness_n_per_m = 100\n\n"
                           "[[object]]\nkind = \"plane\"\nname = \"b\"\npoint_m = [0, 0, 0]\n"
                           "normal = [0, 0, 1]\nstiffness_n_per_m = 100\n"
                           "touched_by = [\"main\", \"rigth\"]\n";
  const auto path = write_scene(text);
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ":" + std::to_string(line_of(text, "touched_by")) +
                ": object[1].touched_by[1] = \"rigth\": expected the name of an instrument in "
                "this scene (main, assist)");
}

TEST_F(SceneFileTest, DuplicateSceneInstrumentNameIsRefused) {
  std::string text = std::string(kSceneHead) + std::string(kTwoInstruments);
  const auto edited = replace_first(text, "name = \"assist\"", "name = \"main\"");
  const auto path = write_scene(edited.text);
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ":" + std::to_string(edited.line) +
                ": instrument[1].name = \"main\" duplicates instrument[0].name: expected unique "
                "instrument names");
}

TEST_F(SceneFileTest, DeviceInstrumentUsedTwiceIsRefused) {
  const auto edited =
      replace_first(std::string(kSceneHead) + std::string(kTwoInstruments),
                    "device_instrument = \"left\"", "device_instrument = \"right\"");
  const auto path = write_scene(edited.text);
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ":" + std::to_string(edited.line) +
                ": instrument[1].device_instrument = \"right\" is already used by instrument[0]: "
                "expected each device instrument at most once");
}

TEST_F(SceneFileTest, EnableInputRequiredButNotWiredIsRefused) {
  const auto device =
      replace_first(read_text(device_path_), "enable_input_bit = 1", "enable_input_bit = -1");
  write("devices/sim.toml", device.text);
  const std::string text = std::string(kSceneHead) + std::string(kTwoInstruments);
  const auto path = write_scene(text);
  const std::string message = error_message(load_scene(path));
  expect_contains(message, path.string() + ":" +
                               std::to_string(line_of(text, "require_enable_input")) +
                               ": safety.require_enable_input = true: expected false, because "
                               "device 'sim-two-port' (");
  expect_contains(message, "has no enable input wired (digital.enable_input_bit = -1)");
}

TEST_F(SceneFileTest, TooManyInstrumentsAndObjects) {
  std::string five = std::string(kSceneHead);
  for (int i = 0; i < 5; ++i) {
    five += "[[instrument]]\nname = \"i" + std::to_string(i) + "\"\ndevice_instrument = \"left\"\n";
  }
  const auto five_path = write_scene(five);
  EXPECT_EQ(error_message(load_scene(five_path)),
            five_path.string() + ":" + std::to_string(line_of(five, "name = \"i4\"") - 1) +
                ": instrument[4]: too many instruments (5): expected 1 to 4 instruments");

  std::string objects = std::string(kSceneHead) + std::string(kTwoInstruments);
  for (int i = 0; i < 17; ++i) {
    objects += "[[object]]\nkind = \"plane\"\nname = \"o" + std::to_string(i) +
               "\"\npoint_m = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness_n_per_m = 100\n";
  }
  const auto objects_path = write_scene(objects);
  EXPECT_EQ(error_message(load_scene(objects_path)),
            objects_path.string() + ":" + std::to_string(line_of(objects, "name = \"o16\"") - 2) +
                ": object[16]: too many objects (17): expected 0 to 16 objects");
  // Sixteen is the limit, not an error.
  const auto sixteen = replace_first(objects, "[[object]]\nkind = \"plane\"\nname = \"o16\"",
                                     "[[object]]\nkind = \"plane\"\nname = \"o16\"");
  const std::size_t cut = sixteen.text.find("[[object]]\nkind = \"plane\"\nname = \"o16\"");
  const auto sixteen_scene = load_scene(write_scene(sixteen.text.substr(0, cut)));
  ASSERT_TRUE(sixteen_scene.has_value()) << sixteen_scene.error().message;
  EXPECT_EQ(sixteen_scene->objects.size(), 16U);
}

TEST_F(SceneFileTest, DeviceFileErrorsNameTheDeviceFile) {
  const auto device =
      replace_first(read_text(device_path_), "gear_ratio = 15.0", "gear_ratio = -3");
  write("devices/sim.toml", device.text);
  const std::string message = error_message(load_scene(write_scene(wall_text_)));
  EXPECT_EQ(message, device_path_.string() + ":" + std::to_string(device.line) +
                         ": instrument[0].pitch.gear_ratio = -3 is out of range: expected more "
                         "than 0 and at most 1000 (motor revolutions per joint revolution)");
}

TEST_F(SceneFileTest, MissingSceneFileIsReported) {
  const auto path = root_ / "scenes" / "nope.toml";
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ": file not found (resolved to " + path.string() + ")");
}

TEST_F(SceneFileTest, MissingRequiredKeyHasNoLineButNamesTypeAndUnit) {
  const auto edited = replace_first(
      wall_text_,
      "period_us = 1000                   # integer microseconds [50, 100000]: 1 kHz haptic loop\n",
      "");
  const auto path = write_scene(edited.text);
  EXPECT_EQ(error_message(load_scene(path)),
            path.string() + ": missing required key 'loop.period_us' (integer, microseconds)");
}

TEST_F(SceneFileTest, MissingSceneTableIsNamed) {
  const auto edited = replace_first(wall_text_, "[scene]\n", "");
  const auto path = write_scene(edited.text);
  // Without its header, name and device are root keys: the first one is the specific error.
  expect_contains(error_message(load_scene(path)),
                  path.string() + ":" + std::to_string(edited.line) + ": unknown key 'name'");
  const auto no_scene = write_scene(std::string(kSceneHead.substr(kSceneHead.find("[loop]"))) +
                                    std::string(kTwoInstruments));
  EXPECT_EQ(error_message(load_scene(no_scene)),
            no_scene.string() + ": missing required key 'scene' (table [scene])");
}

// ---------------------------------------------------------------- [metrics]

TEST_F(SceneFileTest, MetricsTableIsOptionalWithTheDocumentedDefaults) {
  const auto scene = load_scene(write_scene(wall_text_));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  const metrics::MetricsThresholds& m = scene->metrics;
  EXPECT_DOUBLE_EQ(m.safe_force_n, 2.0);
  EXPECT_DOUBLE_EQ(m.damage_force_n, 4.0);
  EXPECT_DOUBLE_EQ(m.movement_start_speed_m_per_s, 0.010);
  EXPECT_DOUBLE_EQ(m.movement_stop_speed_m_per_s, 0.005);
  EXPECT_DOUBLE_EQ(m.min_movement_s, 0.10);
  EXPECT_DOUBLE_EQ(m.speed_window_s, 0.050);
  EXPECT_DOUBLE_EQ(m.path_deadband_m, 1e-4);
  EXPECT_DOUBLE_EQ(m.grasp_open_tolerance_rad, 0.05);
}

TEST_F(SceneFileTest, DefaultSpeedWindowShrinksToTheLongestAShortPeriodAllows) {
  // 50 us loop: 512 periods are 25.6 ms, shorter than the 50 ms default.
  const auto edited = replace_first(wall_text_, "period_us = 1000", "period_us = 50");
  const auto scene = load_scene(write_scene(edited.text));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  EXPECT_NEAR(scene->metrics.speed_window_s, 0.0256, 1e-12);
}

TEST_F(SceneFileTest, MetricsKeysAreRead) {
  const auto edited = replace_first(
      wall_text_, "[[instrument]]",
      "[metrics]\nsafe_force_n = 1.5\ndamage_force_n = 3\nmovement_start_speed_m_per_s = 0.02\n"
      "movement_stop_speed_m_per_s = 0.01\nmin_movement_s = 0.2\nspeed_window_s = 0.1\n"
      "path_deadband_m = 0.0005\ngrasp_open_tolerance_rad = 0.1\n[[instrument]]");
  const auto scene = load_scene(write_scene(edited.text));
  ASSERT_TRUE(scene.has_value()) << scene.error().message;
  const metrics::MetricsThresholds& m = scene->metrics;
  EXPECT_DOUBLE_EQ(m.safe_force_n, 1.5);
  EXPECT_DOUBLE_EQ(m.damage_force_n, 3.0);
  EXPECT_DOUBLE_EQ(m.movement_start_speed_m_per_s, 0.02);
  EXPECT_DOUBLE_EQ(m.movement_stop_speed_m_per_s, 0.01);
  EXPECT_DOUBLE_EQ(m.min_movement_s, 0.2);
  EXPECT_DOUBLE_EQ(m.speed_window_s, 0.1);
  EXPECT_DOUBLE_EQ(m.path_deadband_m, 0.0005);
  EXPECT_DOUBLE_EQ(m.grasp_open_tolerance_rad, 0.1);
}

TEST(RepositoryScenes, MetricsThresholdsAreTheScenesOwn) {
  struct Expected {
    const char* file;
    double safe_force_n;
    double damage_force_n;
  };
  // cbd and duct: the delicate duct; liver: a probe meant to indent; wall, catheter: defaults
  // (their forces come from a rigid plane or the catheter, docs/metrics.md).
  for (const Expected& e : {Expected{"config/scenes/cbd.toml", 1.0, 2.0},
                            Expected{"config/scenes/duct.toml", 1.0, 2.0},
                            Expected{"config/scenes/liver.toml", 4.0, 6.0},
                            Expected{"config/scenes/wall.toml", 2.0, 4.0},
                            Expected{"config/scenes/catheter.toml", 2.0, 4.0}}) {
    const auto scene = load_scene(repo_path(e.file), LoadOptions{.require_script_file = false});
    ASSERT_TRUE(scene.has_value()) << scene.error().message;
    EXPECT_DOUBLE_EQ(scene->metrics.safe_force_n, e.safe_force_n) << e.file;
    EXPECT_DOUBLE_EQ(scene->metrics.damage_force_n, e.damage_force_n) << e.file;
    EXPECT_DOUBLE_EQ(scene->metrics.speed_window_s, 0.05) << e.file;
  }
}

// ---------------------------------------------------------------- one edit, one message

struct SceneErrorCase {
  const char* name;
  const char* from;  // first occurrence in config/scenes/wall.toml is replaced
  const char* to;
  const char* expected;  // the message after "<file>:<line>: "; "{root}" = temp tree
  int line_offset = 0;
};

std::ostream& operator<<(std::ostream& stream, const SceneErrorCase& error_case) {
  return stream << error_case.name;
}

class SceneErrorTest : public SceneFileTest,
                       public ::testing::WithParamInterface<SceneErrorCase> {};

TEST_P(SceneErrorTest, MessageNamesFileLineKeyValueAndExpectation) {
  const SceneErrorCase& error_case = GetParam();
  const auto edited = replace_first(wall_text_, error_case.from, error_case.to);
  const auto path = write_scene(edited.text);
  std::string expected = error_case.expected;
  const std::size_t root_marker = expected.find("{root}");
  if (root_marker != std::string::npos) expected.replace(root_marker, 6, root_.string());
  const std::string message = error_message(load_scene(path));
  expect_contains(
      message,
      path.string() + ":" + std::to_string(edited.line + error_case.line_offset) + ": " + expected);
}

const SceneErrorCase kSceneErrorCases[] = {
    {"syntax_error", "period_us = 1000", "period_us = 1000 1000", "syntax error: "},
    {"period_below_range", "period_us = 1000", "period_us = 5",
     "loop.period_us = 5 is out of range: expected 50 to 100000 (microseconds)"},
    {"period_above_range", "period_us = 1000", "period_us = 100001",
     "loop.period_us = 100001 is out of range: expected 50 to 100000 (microseconds)"},
    {"period_wrong_type", "period_us = 1000", "period_us = \"fast\"",
     "loop.period_us = \"fast\" has type string: expected integer (microseconds)"},
    {"period_float", "period_us = 1000", "period_us = 1000.0",
     "loop.period_us = 1000.0 has type float: expected integer (microseconds)"},
    {"streak_zero", "overrun_streak_limit = 10", "overrun_streak_limit = 0",
     "loop.overrun_streak_limit = 0 is out of range: expected 1 to 100000 (consecutive "
     "overrunning cycles)"},
    {"priority_above_range", "priority = 80", "priority = 100",
     "loop.priority = 100 is out of range: expected 0 to 99 (SCHED_FIFO priority, 0 = "
     "SCHED_OTHER)"},
    {"cpu_below_range", "cpu = 1", "cpu = -2",
     "loop.cpu = -2 is out of range: expected -1 to 1023 (CPU index, -1 = no pinning)"},
    {"lock_memory_wrong_type", "lock_memory = true", "lock_memory = 1",
     "loop.lock_memory = 1 has type integer: expected boolean (true or false)"},
    {"stack_prefault_above_range", "stack_prefault_kib = 256", "stack_prefault_kib = 65537",
     "loop.stack_prefault_kib = 65537 is out of range: expected 0 to 65536 (kibibytes)"},
    {"cpu_dma_latency_below_range", "cpu_dma_latency_us = 0", "cpu_dma_latency_us = -2",
     "loop.cpu_dma_latency_us = -2 is out of range: expected -1 to 10000 (microseconds, -1 = no request)"},
    {"rt_check_fatal_unknown", "cpu_dma_latency_us = 0",
     "cpu_dma_latency_us = 0\nrt_check_fatal = [\"memlock\", \"preempt-rt\"]",
     "loop.rt_check_fatal[1] = \"preempt-rt\": unknown RT self-check; expected one of "
     "preempt_rt, isolated_cpu, cpu_dma_latency, cpu_governor, smt, rt_throttling, memlock, "
     "rtprio, irq_threads", 1},
    {"rt_check_fatal_twice", "cpu_dma_latency_us = 0",
     "cpu_dma_latency_us = 0\nrt_check_fatal = [\"memlock\", \"memlock\"]",
     "loop.rt_check_fatal[1] = \"memlock\": listed twice", 1},
    {"rt_check_fatal_not_array", "cpu_dma_latency_us = 0",
     "cpu_dma_latency_us = 0\nrt_check_fatal = \"memlock\"",
     "loop.rt_check_fatal = \"memlock\" has type string: expected an array of ", 1},
    {"arena_zero", "arena_kib = 1024", "arena_kib = 0",
     "memory.arena_kib = 0 is out of range: expected 1 to 1048576 (kibibytes)"},
    {"max_force_typo", "max_force_n = 8.0", "max_forse_n = 8.0",
     "unknown key 'safety.max_forse_n' (known: max_force_n, max_force_rate_n_per_s, "
     "max_joint_speed_rad_per_s, max_insertion_speed_m_per_s, passivity_energy_bound_j, "
     "require_enable_input); did you mean 'max_force_n'?"},
    {"max_force_infinite", "max_force_n = 8.0", "max_force_n = inf",
     "safety.max_force_n = inf is not a finite number: expected more than 0 and at most 100 "
     "(newtons)"},
    {"max_force_nan", "max_force_n = 8.0", "max_force_n = -nan",
     "safety.max_force_n = nan is not a finite number: expected more than 0 and at most 100 "
     "(newtons)"},
    {"max_force_zero", "max_force_n = 8.0", "max_force_n = 0",
     "safety.max_force_n = 0 is out of range: expected more than 0 and at most 100 (newtons)"},
    {"max_force_above_range", "max_force_n = 8.0", "max_force_n = 100.5",
     "safety.max_force_n = 100.5 is out of range: expected more than 0 and at most 100 "
     "(newtons)"},
    {"force_rate_above_range", "max_force_rate_n_per_s = 4000.0", "max_force_rate_n_per_s = 2e7",
     "safety.max_force_rate_n_per_s = 2e+07 is out of range: expected more than 0 and at most "
     "10000000 (newtons per second)"},
    {"joint_speed_zero", "max_joint_speed_rad_per_s = 20.0", "max_joint_speed_rad_per_s = 0.0",
     "safety.max_joint_speed_rad_per_s = 0.0 is out of range: expected more than 0 and at most "
     "10000 (radians per second)"},
    {"insertion_speed_negative", "max_insertion_speed_m_per_s = 1.0",
     "max_insertion_speed_m_per_s = -1",
     "safety.max_insertion_speed_m_per_s = -1 is out of range: expected more than 0 and at most "
     "100 (metres per second)"},
    {"passivity_negative", "passivity_energy_bound_j = 0.5", "passivity_energy_bound_j = -0.1",
     "safety.passivity_energy_bound_j = -0.1 is out of range: expected 0 to 100 (joules, 0 "
     "disables the check)"},
    {"enable_wrong_type", "require_enable_input = false", "require_enable_input = \"no\"",
     "safety.require_enable_input = \"no\" has type string: expected boolean (true or false)"},
    {"missing_device_file", "device = \"../devices/sim.toml\"", "device = \"devices/nope.toml\"",
     "scene.device: file 'devices/nope.toml' not found (resolved to "
     "{root}/scenes/devices/nope.toml)"},
    {"scene_name", "name = \"wall\"", "name = \"wall!\"",
     "scene.name = \"wall!\": expected a name of 1 to 32 characters from A-Z, a-z, 0-9, '_' and "
     "'-'"},
    {"bad_builtin_script", "\"../trajectories/wall_press.csv\"", "\"builtin:\"",
     "trainee.script = \"builtin:\": expected \"builtin:<name>\" with a name of 1 to 32 "
     "characters"},
    {"missing_script_file", "\"../trajectories/wall_press.csv\"", "\"../trajectories/x.csv\"",
     "trainee.script: file '../trajectories/x.csv' not found (resolved to "
     "{root}/trajectories/x.csv)"},
    {"end_run_wrong_type", "end_run_with_script = true", "end_run_with_script = \"yes\"",
     "trainee.end_run_with_script = \"yes\" has type string: expected boolean"},
    {"unknown_table", "[trainee]", "[traine]",
     "unknown key 'traine' (known: scene, loop, memory, safety, trainee, metrics, instrument, object, "
     "model); "
     "did you mean 'trainee'?"},
    {"unknown_device_instrument", "device_instrument = \"left\"", "device_instrument = \"center\"",
     "instrument[0].device_instrument = \"center\": expected the name of an instrument in device "
     "file '{root}/devices/sim.toml' (left, right)"},
    {"unknown_touched_by", "touched_by = [\"left\"]", "touched_by = [\"rigth\"]",
     "object[0].touched_by[0] = \"rigth\": expected the name of an instrument in this scene "
     "(left)"},
    {"touched_by_twice", "touched_by = [\"left\"]", "touched_by = [\"left\", \"left\"]",
     "object[0].touched_by[1] = \"left\": expected each instrument at most once"},
    {"touched_by_empty", "touched_by = [\"left\"]", "touched_by = []",
     "object[0].touched_by = [] has 0 elements: expected an array of 1 to 4 strings (names of "
     "instruments in this scene)"},
    {"touched_by_not_strings", "touched_by = [\"left\"]", "touched_by = [0]",
     "object[0].touched_by[0] = 0 has type integer: expected string (names of instruments in "
     "this scene)"},
    {"unknown_object_kind", "kind = \"plane\"", "kind = \"cube\"",
     "object[0].kind = \"cube\": expected one of: plane, sphere"},
    {"zero_normal", "normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]",
     "object[0].normal = [0.0, 0.0, 0.0] is a zero vector: expected a direction of length at "
     "least 1e-09 (it is normalised on load)"},
    {"point_not_finite", "point_m = [-0.05, 0.0, -0.09]", "point_m = [-0.05, inf, -0.09]",
     "object[0].point_m[1] = inf is not a finite number: expected -10 to 10 (metres)"},
    {"sphere_key_on_plane", "point_m = [-0.05, 0.0, -0.09]", "radius_m = 0.1",
     "unknown key 'object[0].radius_m' (known: kind, name, point_m, normal, stiffness_n_per_m, "
     "damping_n_s_per_m, touched_by)"},
    {"stiffness_above_range", "stiffness_n_per_m = 400.0", "stiffness_n_per_m = 2e6",
     "object[0].stiffness_n_per_m = 2e+06 is out of range: expected more than 0 and at most "
     "1000000 (newtons per metre)"},
    {"damping_negative", "damping_n_s_per_m = 1.0", "damping_n_s_per_m = -1.0",
     "object[0].damping_n_s_per_m = -1.0 is out of range: expected 0 to 10000 (newton-seconds "
     "per metre)"},
    // [metrics] (written before [[instrument]]; the key is on the line after the header)
    {"metrics_safe_zero", "[[instrument]]", "[metrics]\nsafe_force_n = 0\n[[instrument]]",
     "metrics.safe_force_n = 0 is out of range: expected more than 0 and at most 100 (newtons)", 1},
    {"metrics_damage_below_safe", "[[instrument]]",
     "[metrics]\nsafe_force_n = 3.0\ndamage_force_n = 2.5\n[[instrument]]",
     "metrics.damage_force_n = 2.5: expected at least metrics.safe_force_n (3 N)", 2},
    {"metrics_safe_above_default_damage", "[[instrument]]",
     "[metrics]\nsafe_force_n = 5.0\n[[instrument]]",
     "metrics.safe_force_n = 5.0: expected at most metrics.damage_force_n (4 N, its default)", 1},
    {"metrics_stop_above_start", "[[instrument]]",
     "[metrics]\nmovement_stop_speed_m_per_s = 0.02\n[[instrument]]",
     "metrics.movement_stop_speed_m_per_s = 0.02: expected at most "
     "metrics.movement_start_speed_m_per_s (0.01 m/s)", 1},
    {"metrics_speed_above_range", "[[instrument]]",
     "[metrics]\nmovement_start_speed_m_per_s = 11\n[[instrument]]",
     "metrics.movement_start_speed_m_per_s = 11 is out of range: expected more than 0 and at most "
     "10 (metres per second)", 1},
    {"metrics_window_too_long", "[[instrument]]", "[metrics]\nspeed_window_s = 0.6\n[[instrument]]",
     "metrics.speed_window_s = 0.6: expected at most 512 loop periods (0.512 s with "
     "loop.period_us = 1000)", 1},
    {"metrics_deadband_negative", "[[instrument]]",
     "[metrics]\npath_deadband_m = -0.1\n[[instrument]]",
     "metrics.path_deadband_m = -0.1 is out of range: expected 0 to 0.01 (metres)", 1},
    {"metrics_tolerance_wrong_type", "[[instrument]]",
     "[metrics]\ngrasp_open_tolerance_rad = \"small\"\n[[instrument]]",
     "metrics.grasp_open_tolerance_rad = \"small\" has type string: expected ", 1},
    {"metrics_typo", "[[instrument]]", "[metrics]\npath_deadband = 0.001\n[[instrument]]",
     "unknown key 'metrics.path_deadband' (known: safe_force_n, damage_force_n, "
     "movement_start_speed_m_per_s, movement_stop_speed_m_per_s, min_movement_s, speed_window_s, "
     "path_deadband_m, grasp_open_tolerance_rad); did you mean 'path_deadband_m'?", 1},
    {"instrument_typo", "device_instrument = \"left\"", "device_instrumnt = \"left\"",
     "unknown key 'instrument[0].device_instrumnt' (known: name, device_instrument); did you "
     "mean 'device_instrument'?"},
};

INSTANTIATE_TEST_SUITE_P(EveryMistake, SceneErrorTest, ::testing::ValuesIn(kSceneErrorCases),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// ---------------------------------------------------------------- [loop] overrides

TEST(LoopOverrides, ReplaceOnlyTheGivenKeys) {
  LoopConfig loop;
  loop.period_ns = 1'000'000;
  loop.priority = 80;
  loop.cpu = 1;
  ASSERT_TRUE(apply_loop_overrides(loop, LoopOverrides{.period_us = 100}).has_value());
  EXPECT_EQ(loop.period_ns, 100'000);
  EXPECT_EQ(loop.priority, 80);
  EXPECT_EQ(loop.cpu, 1);
  ASSERT_TRUE(apply_loop_overrides(loop, LoopOverrides{.priority = 0, .cpu = -1}).has_value());
  EXPECT_EQ(loop.period_ns, 100'000);
  EXPECT_EQ(loop.priority, 0);
  EXPECT_EQ(loop.cpu, -1);
  // The range ends are the file's: [50, 100000] us, [0, 99], [-1, 1023].
  EXPECT_TRUE(
      apply_loop_overrides(loop, LoopOverrides{.period_us = 50, .priority = 99, .cpu = 1023})
          .has_value());
  EXPECT_EQ(loop.period_ns, 50'000);
}

TEST(LoopOverrides, OutOfRangeNamesTheKeyAndLeavesTheLoopUntouched) {
  LoopConfig loop;
  loop.period_ns = 1'000'000;
  loop.priority = 80;
  loop.cpu = 1;
  // A valid period next to an invalid priority: nothing is applied.
  const auto bad_priority =
      apply_loop_overrides(loop, LoopOverrides{.period_us = 200, .priority = 100});
  ASSERT_FALSE(bad_priority.has_value());
  expect_contains(bad_priority.error().message, "override of loop.priority = 100");
  expect_contains(bad_priority.error().message, "expected 0 to 99");
  EXPECT_EQ(loop.period_ns, 1'000'000);
  EXPECT_EQ(loop.priority, 80);

  const auto bad_period = apply_loop_overrides(loop, LoopOverrides{.period_us = 20});
  ASSERT_FALSE(bad_period.has_value());
  expect_contains(bad_period.error().message, "loop.period_us = 20");
  expect_contains(bad_period.error().message, "expected 50 to 100000");
  expect_contains(bad_period.error().message, "microseconds");

  const auto bad_cpu = apply_loop_overrides(loop, LoopOverrides{.cpu = -2});
  ASSERT_FALSE(bad_cpu.has_value());
  expect_contains(bad_cpu.error().message, "loop.cpu = -2");
  expect_contains(bad_cpu.error().message, "expected -1 to 1023");
  EXPECT_EQ(loop.cpu, 1);
}

TEST(LoopOverrides, TheOverrunStreakLimitIsRangedLikeTheFilesKey) {
  LoopConfig loop;
  loop.overrun_streak_limit = 10;
  const auto bad = apply_loop_overrides(loop, LoopOverrides{.overrun_streak_limit = 0});
  ASSERT_FALSE(bad.has_value());
  expect_contains(bad.error().message, "override of loop.overrun_streak_limit = 0");
  expect_contains(bad.error().message, "expected 1 to 100000");
  EXPECT_EQ(loop.overrun_streak_limit, 10U);
  ASSERT_TRUE(apply_loop_overrides(loop, LoopOverrides{.overrun_streak_limit = 1000}).has_value());
  EXPECT_EQ(loop.overrun_streak_limit, 1000U);
}

}  // namespace
}  // namespace trainer::config
