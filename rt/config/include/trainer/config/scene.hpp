// Scene configuration: what a scene file (config/scenes/*.toml) describes, as plain structs in
// SI units, and the loader that validates a scene file together with the device file it names.
// A scene lists only what the run needs: loop timing, memory, safety limits, the trainee input,
// the instruments used and the objects they touch. Key-by-key reference: docs/config.md.
//
// Setup path only: the loader allocates and returns core::Expected; nothing here runs per cycle.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/config/model.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/metrics/thresholds.hpp"

namespace trainer::config {

inline constexpr std::size_t kMaxSceneInstruments = 4;
inline constexpr std::size_t kMaxObjects = 16;
inline constexpr std::size_t kMaxModels = 4;

struct LoopConfig {                        // [loop]
  std::int64_t period_ns = 0;              // from period_us
  std::uint32_t overrun_streak_limit = 0;  // consecutive overruns that latch a fault
  int priority = 0;                        // SCHED_FIFO priority; 0 = SCHED_OTHER
  int cpu = -1;                            // CPU to pin the haptic thread to; -1 = no pinning
  bool lock_memory = false;                // mlockall(MCL_CURRENT | MCL_FUTURE) before arming
  std::size_t stack_prefault_bytes = 0;    // stack touched before arming, from stack_prefault_kib
  int cpu_dma_latency_us = -1;             // PM QoS wake-up latency held while running; -1 = none
  // RT self-check items (appliance::kRtCheckNames) whose failure stops the trainer before it
  // arms when it applies RT settings; `trainer --check-rt` exits 1 on them. Default: none.
  std::vector<std::string> rt_check_fatal;
};

struct MemoryConfig {           // [memory]
  std::size_t arena_bytes = 0;  // from arena_kib
};

struct SafetyConfig {                        // [safety]
  double max_force_n = 0.0;                  // per instrument tip
  double max_force_rate_n_per_s = 0.0;       // slew limit on the commanded tip force
  double max_joint_speed_rad_per_s = 0.0;    // faster revolute motion = encoder jump (fault)
  double max_insertion_speed_m_per_s = 0.0;  // same for the prismatic insertion joint
  double passivity_energy_bound_j = 0.0;     // 0 disables the passivity check
  bool require_enable_input = false;         // enable switch must be held to arm / stay armed
};

struct TraineeConfig {  // [trainee]
  // "builtin:<name>" (e.g. "builtin:hold"), or the absolute, lexically normal path of a
  // trajectory CSV (written relative to the scene file's directory in the file).
  std::string script;
  bool end_run_with_script = false;  // stop the run when the script ends
};

// True for "builtin:<name>" scripts, false for trajectory file paths.
bool is_builtin_script(std::string_view script) noexcept;

struct SceneInstrumentConfig {        // [[instrument]]
  std::string name;                   // unique within the scene; what objects' touched_by name
  std::size_t device_instrument = 0;  // index into DeviceConfig::instruments
};

enum class ObjectKind : std::uint8_t { plane, sphere };
std::string_view to_string(ObjectKind kind) noexcept;

struct ObjectConfig {  // [[object]]
  ObjectKind kind = ObjectKind::plane;
  std::string name;
  // plane: a point on it and the unit outward normal (the side the tool comes from)
  Vec3 point_m{};
  Vec3 normal{};
  // sphere
  Vec3 center_m{};
  double radius_m = 0.0;
  double stiffness_n_per_m = 0.0;
  double damping_n_s_per_m = 0.0;
  std::vector<std::size_t> touched_by;  // indices into SceneConfig::instruments, no repeats
};

// [model.insertion] of a catheter: where the lumen it is to be inserted into opens and how
// deep the procedure should take it. The run reports the insertion depth: the largest
// (p − entry_m)·direction over the catheter's particles p that lie within radius_m of the
// line through entry_m along direction (0 while none is inside).
struct InsertionGoalConfig {
  Vec3 entry_m{};           // centre of the opening, trainer frame, metres
  Vec3 direction{};         // into the lumen, unit (normalised on load)
  double radius_m = 0.0;    // (0, 1]: how far from the axis a particle still counts as inside
  double target_depth_m = 0.0;  // (0, 1]: the depth the procedure is meant to reach
};

struct SceneModelConfig {  // [[model]]: a model the scene uses, by its definition file
  std::string name;          // unique within the scene
  ModelDefinition definition;
  // Placement of the model's own frame (where it was built, e.g. the duct along +x from
  // x = 0) in the trainer frame: x_world = R · x_model + position_m, with
  // R = Rx(rx) · Ry(ry) · Rz(rz) for rotation_deg = [rx, ry, rz] — intrinsic rotations, first
  // about the model's x, then about the once-turned y, then about the twice-turned z.
  Vec3 position_m{};                    // metres, each component [-10, 10], default 0
  Vec3 rotation_deg{};                  // degrees, each component [-360, 360], default 0
  std::vector<std::size_t> touched_by;  // indices into SceneConfig::instruments, no repeats
  std::optional<InsertionGoalConfig> insertion;  // catheters only
};

struct SceneConfig {
  std::filesystem::path source_path;  // absolute, lexically normal path of the file loaded
  std::string name;                   // [scene] name
  LoopConfig loop;
  MemoryConfig memory;
  SafetyConfig safety;
  TraineeConfig trainee;
  std::vector<SceneInstrumentConfig> instruments;  // 1..kMaxSceneInstruments
  std::vector<ObjectConfig> objects;               // 0..kMaxObjects
  std::vector<SceneModelConfig> models;            // 0..kMaxModels
  // [metrics]: thresholds of the trainee metrics (docs/metrics.md); every key optional.
  metrics::MetricsThresholds metrics;
  DeviceConfig device;                             // loaded from [scene] device
};

struct LoadOptions {
  // When false, a trajectory script path is resolved but not required to exist (for checking
  // a scene on a machine that does not have the recordings).
  bool require_script_file = true;
  // When set, this device file replaces the one the scene names ([scene] device) and the scene
  // is checked against it (trainer --device FILE).
  std::optional<std::filesystem::path> device_file{};
};

// Values given on a command line (trainer, jitter) that replace the scene's [loop] keys of the
// same name for one run; unset members keep the file's value.
struct LoopOverrides {
  std::optional<std::int64_t> period_us{};  // loop.period_us
  std::optional<int> priority{};            // loop.priority
  std::optional<int> cpu{};                 // loop.cpu
  std::optional<std::int64_t> overrun_streak_limit{};  // loop.overrun_streak_limit
};

// Checks every set override against the range of its [loop] key (docs/config.md) and, only
// when all are valid, writes them into `loop`. The error names the key, the value, the range
// and that it came from an override rather than the file.
core::Expected<void> apply_loop_overrides(LoopConfig& loop, const LoopOverrides& overrides);

// Loads and validates a scene file and the device file it names ([scene] device, relative to
// the scene file's directory). On failure the message names the file (scene or device), the
// line (when there is one), the key, the bad value and what was expected.
core::Expected<SceneConfig> load_scene(const std::filesystem::path& file,
                                       const LoadOptions& options = {});
// The same for a scene file's text already in memory, read as if it were `file`: messages name
// `file`, and the device, model definitions and scripts it refers to are resolved from its
// directory and loaded from disk as load_scene does (options.device_file replaces the device
// reference). load_scene reads the file and parses it the same way.
core::Expected<SceneConfig> load_scene_text(std::string_view text,
                                            const std::filesystem::path& file,
                                            const LoadOptions& options = {});

}  // namespace trainer::config
