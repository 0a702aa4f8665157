// The scene file schema: [scene], [loop], [memory], [safety], [trainee], [metrics],
// [[instrument]], [[object]], [[model]], plus the device file named by [scene] device and the model
// definition files named by [[model]] definition. Every key, unit, range and default
// here is documented in docs/config.md; keep them in step.
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "table_reader.hpp"
#include "trainer/appliance/rt_check.hpp"
#include "trainer/config/scene.hpp"
#include "value_text.hpp"

namespace trainer::config {

namespace {
constexpr std::string_view kBuiltinScriptPrefix = "builtin:";
}  // namespace

bool is_builtin_script(std::string_view script) noexcept {
  return script.starts_with(kBuiltinScriptPrefix);
}

std::string_view to_string(ObjectKind kind) noexcept {
  switch (kind) {
    case ObjectKind::plane: return "plane";
    case ObjectKind::sphere: return "sphere";
  }
  return "unknown";
}

namespace {

using detail::ErrorSink;
using detail::kNanosecondsPerMicrosecond;
using detail::IntRange;
using detail::RealRange;
using detail::StringItem;
using detail::TableReader;

constexpr std::int64_t kBytesPerKib = 1024;

constexpr IntRange kPeriodRangeUs{50, 100000};
constexpr IntRange kOverrunStreakRange{1, 100000};
constexpr std::int64_t kDefaultOverrunStreakLimit = 10;
constexpr IntRange kPriorityRange{0, 99};
constexpr IntRange kCpuRange{-1, 1023};
constexpr IntRange kStackPrefaultRangeKib{0, 65536};
constexpr IntRange kCpuDmaLatencyRangeUs{-1, 10000};
constexpr std::int64_t kDefaultStackPrefaultKib = 256;
constexpr IntRange kArenaRangeKib{1, 1048576};
constexpr std::int64_t kDefaultArenaKib = 1024;

constexpr RealRange kMaxForceRangeN = RealRange::left_open(0.0, 100.0);
constexpr RealRange kMaxForceRateRange = RealRange::left_open(0.0, 1e7);
constexpr RealRange kMaxJointSpeedRange = RealRange::left_open(0.0, 1e4);
constexpr RealRange kMaxInsertionSpeedRange = RealRange::left_open(0.0, 100.0);
constexpr RealRange kPassivityBoundRangeJ = RealRange::closed(0.0, 100.0);

constexpr std::string_view kDefaultScript = "builtin:hold";

constexpr std::array<std::string_view, 2> kObjectKinds = {"plane", "sphere"};
constexpr RealRange kPositionComponentRangeM = RealRange::closed(-10.0, 10.0);
constexpr RealRange kSphereRadiusRangeM = RealRange::left_open(0.0, 1.0);
constexpr RealRange kObjectStiffnessRange = RealRange::left_open(0.0, 1e6);
constexpr RealRange kObjectDampingRange = RealRange::closed(0.0, 1e4);
constexpr double kDefaultObjectDampingNsPerM = 0.0;
constexpr RealRange kRotationComponentRangeDeg = RealRange::closed(-360.0, 360.0);

constexpr RealRange kMetricsForceRangeN = RealRange::left_open(0.0, 100.0);
constexpr RealRange kMetricsSpeedRange = RealRange::left_open(0.0, 10.0);
constexpr RealRange kMinMovementRangeS = RealRange::closed(0.0, 10.0);
constexpr RealRange kSpeedWindowRangeS = RealRange::left_open(0.0, 1.0);
constexpr RealRange kPathDeadbandRangeM = RealRange::closed(0.0, 0.01);
constexpr RealRange kGraspOpenToleranceRangeRad = RealRange::closed(0.0, 1.0);

LoopConfig read_loop(TableReader& table) {
  LoopConfig loop;
  loop.period_ns =
      table.required_int("period_us", kPeriodRangeUs, "microseconds") * kNanosecondsPerMicrosecond;
  loop.overrun_streak_limit = static_cast<std::uint32_t>(
      table.optional_int("overrun_streak_limit", kDefaultOverrunStreakLimit, kOverrunStreakRange,
                         "consecutive overrunning cycles"));
  loop.priority = static_cast<int>(
      table.optional_int("priority", 0, kPriorityRange, "SCHED_FIFO priority, 0 = SCHED_OTHER"));
  loop.cpu =
      static_cast<int>(table.optional_int("cpu", -1, kCpuRange, "CPU index, -1 = no pinning"));
  loop.lock_memory = table.optional_bool("lock_memory", false);
  loop.stack_prefault_bytes =
      static_cast<std::size_t>(table.optional_int("stack_prefault_kib", kDefaultStackPrefaultKib,
                                                  kStackPrefaultRangeKib, "kibibytes") *
                               kBytesPerKib);
  loop.cpu_dma_latency_us = static_cast<int>(
      table.optional_int("cpu_dma_latency_us", -1, kCpuDmaLatencyRangeUs,
                         "microseconds, -1 = no request"));
  if (auto fatal = table.optional_string_array("rt_check_fatal", 0, appliance::kRtCheckCount,
                                               "RT self-check names")) {
    for (const StringItem& item : *fatal) {
      if (!appliance::rt_check_from_name(item.value)) {
        std::string known;
        for (const std::string_view name : appliance::kRtCheckNames)
          known += (known.empty() ? "" : ", ") + std::string(name);
        table.fail_item(item, ": unknown RT self-check; expected one of " + known);
      } else if (std::find(loop.rt_check_fatal.begin(), loop.rt_check_fatal.end(), item.value) !=
                 loop.rt_check_fatal.end()) {
        table.fail_item(item, ": listed twice");
      } else {
        loop.rt_check_fatal.push_back(item.value);
      }
    }
  }
  table.finish();
  return loop;
}

MemoryConfig read_memory(TableReader& table) {
  MemoryConfig memory;
  memory.arena_bytes = static_cast<std::size_t>(
      table.optional_int("arena_kib", kDefaultArenaKib, kArenaRangeKib, "kibibytes") *
      kBytesPerKib);
  table.finish();
  return memory;
}

SafetyConfig read_safety(TableReader& table) {
  SafetyConfig safety;
  safety.max_force_n = table.required_double("max_force_n", kMaxForceRangeN, "newtons");
  safety.max_force_rate_n_per_s =
      table.required_double("max_force_rate_n_per_s", kMaxForceRateRange, "newtons per second");
  safety.max_joint_speed_rad_per_s =
      table.required_double("max_joint_speed_rad_per_s", kMaxJointSpeedRange, "radians per second");
  safety.max_insertion_speed_m_per_s = table.required_double(
      "max_insertion_speed_m_per_s", kMaxInsertionSpeedRange, "metres per second");
  safety.passivity_energy_bound_j = table.required_double(
      "passivity_energy_bound_j", kPassivityBoundRangeJ, "joules, 0 disables the check");
  safety.require_enable_input = table.required_bool("require_enable_input");
  table.finish();
  return safety;
}

TraineeConfig read_trainee(TableReader& table, const LoadOptions& options) {
  TraineeConfig trainee;
  const std::optional<std::string> written = table.optional_string(
      "script", "\"builtin:<name>\" or a trajectory CSV path relative to this file");
  if (!written) {
    trainee.script = std::string(kDefaultScript);
  } else if (is_builtin_script(*written)) {
    const std::string_view builtin_name =
        std::string_view{*written}.substr(kBuiltinScriptPrefix.size());
    if (detail::is_valid_name(builtin_name)) {
      trainee.script = *written;
    } else {
      table.fail_value("script",
                       ": expected \"builtin:<name>\" with a name of 1 to " +
                           std::to_string(detail::kMaxNameLength) +
                           " characters from A-Z, a-z, 0-9, '_' and '-', or a trajectory CSV "
                           "path relative to this file");
    }
  } else if (!written->empty()) {
    trainee.script = table.check_file("script", *written, options.require_script_file).string();
  }
  trainee.end_run_with_script = table.optional_bool("end_run_with_script", false);
  table.finish();
  return trainee;
}

std::string real_text(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", value);
  return buffer;
}

// [metrics]: every key optional (defaults in metrics::MetricsThresholds). Checks across keys
// report the key that was written: damage ≥ safe force, stop ≤ start speed, and a speed window
// of at most metrics::kMaxSpeedWindowSamples loop periods (the default window is shortened to
// that when the loop period is short).
metrics::MetricsThresholds read_metrics(TableReader& table, std::int64_t period_ns,
                                        ErrorSink& errors) {
  const metrics::MetricsThresholds defaults{};
  metrics::MetricsThresholds m;
  m.safe_force_n =
      table.optional_double("safe_force_n", defaults.safe_force_n, kMetricsForceRangeN, "newtons");
  m.damage_force_n = table.optional_double("damage_force_n", defaults.damage_force_n,
                                           kMetricsForceRangeN, "newtons");
  m.movement_start_speed_m_per_s =
      table.optional_double("movement_start_speed_m_per_s", defaults.movement_start_speed_m_per_s,
                            kMetricsSpeedRange, "metres per second");
  m.movement_stop_speed_m_per_s =
      table.optional_double("movement_stop_speed_m_per_s", defaults.movement_stop_speed_m_per_s,
                            kMetricsSpeedRange, "metres per second");
  m.min_movement_s = table.optional_double("min_movement_s", defaults.min_movement_s,
                                           kMinMovementRangeS, "seconds");
  const double max_window_s = period_ns > 0
                                  ? static_cast<double>(metrics::kMaxSpeedWindowSamples) *
                                        static_cast<double>(period_ns) * 1e-9
                                  : defaults.speed_window_s;
  m.speed_window_s = table.optional_double("speed_window_s",
                                           std::min(defaults.speed_window_s, max_window_s),
                                           kSpeedWindowRangeS, "seconds");
  m.path_deadband_m = table.optional_double("path_deadband_m", defaults.path_deadband_m,
                                            kPathDeadbandRangeM, "metres");
  m.grasp_open_tolerance_rad =
      table.optional_double("grasp_open_tolerance_rad", defaults.grasp_open_tolerance_rad,
                            kGraspOpenToleranceRangeRad, "radians");
  if (errors.ok() && m.damage_force_n < m.safe_force_n) {
    if (table.has("damage_force_n")) {
      table.fail_value("damage_force_n", ": expected at least metrics.safe_force_n (" +
                                             real_text(m.safe_force_n) + " N)");
    } else {
      table.fail_value("safe_force_n", ": expected at most metrics.damage_force_n (" +
                                           real_text(m.damage_force_n) + " N, its default)");
    }
  }
  if (errors.ok() && m.movement_stop_speed_m_per_s > m.movement_start_speed_m_per_s) {
    if (table.has("movement_stop_speed_m_per_s")) {
      table.fail_value("movement_stop_speed_m_per_s",
                       ": expected at most metrics.movement_start_speed_m_per_s (" +
                           real_text(m.movement_start_speed_m_per_s) + " m/s)");
    } else {
      table.fail_value("movement_start_speed_m_per_s",
                       ": expected at least metrics.movement_stop_speed_m_per_s (" +
                           real_text(m.movement_stop_speed_m_per_s) + " m/s, its default)");
    }
  }
  if (errors.ok() && period_ns > 0 && m.speed_window_s > max_window_s * (1.0 + 1e-9)) {
    table.fail_value("speed_window_s",
                     ": expected at most " + std::to_string(metrics::kMaxSpeedWindowSamples) +
                         " loop periods (" + real_text(max_window_s) + " s with loop.period_us = " +
                         std::to_string(period_ns / kNanosecondsPerMicrosecond) + ")");
  }
  table.finish();
  return m;
}

std::string instrument_names(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) {
    if (!text.empty()) text += ", ";
    text += name;
  }
  return text;
}

std::vector<SceneInstrumentConfig> read_instruments(TableReader& root, const DeviceConfig* device,
                                                    const std::string& device_display,
                                                    ErrorSink& errors) {
  std::vector<std::string> device_names;
  if (device != nullptr) {
    for (const auto& instrument : device->instruments) device_names.push_back(instrument.name);
  }
  std::vector<SceneInstrumentConfig> instruments;
  auto tables = root.array_of_tables("instrument", 1, kMaxSceneInstruments, "instruments");
  for (std::size_t i = 0; i < tables.size(); ++i) {
    TableReader& table = tables[i];
    SceneInstrumentConfig instrument;
    instrument.name = table.required_name("name");
    const std::string device_instrument = table.required_name("device_instrument");
    // Resolution needs the device; without it (an error already recorded) it would only add
    // a misleading second complaint.
    if (device != nullptr && errors.ok()) {
      const auto found = std::find(device_names.begin(), device_names.end(), device_instrument);
      if (found == device_names.end()) {
        table.fail_value("device_instrument",
                         ": expected the name of an instrument in device file '" + device_display +
                             "' (" + instrument_names(device_names) + ")");
      } else {
        instrument.device_instrument =
            static_cast<std::size_t>(std::distance(device_names.begin(), found));
      }
    }
    for (std::size_t earlier = 0; errors.ok() && earlier < i; ++earlier) {
      if (instruments[earlier].name == instrument.name) {
        table.fail_value("name", " duplicates " + tables[earlier].qualified("name") +
                                     ": expected unique instrument names");
      } else if (instruments[earlier].device_instrument == instrument.device_instrument) {
        table.fail_value("device_instrument", " is already used by " + tables[earlier].prefix() +
                                                  ": expected each device instrument at most once");
      }
    }
    table.finish();
    instruments.push_back(std::move(instrument));
  }
  return instruments;
}

std::vector<std::size_t> resolve_touched_by(TableReader& table,
                                            const std::vector<StringItem>& items,
                                            const std::vector<SceneInstrumentConfig>& instruments,
                                            ErrorSink& errors) {
  std::vector<std::string> names;
  for (const auto& instrument : instruments) names.push_back(instrument.name);
  std::vector<std::size_t> indices;
  for (std::size_t i = 0; errors.ok() && i < items.size(); ++i) {
    const auto found = std::find(names.begin(), names.end(), items[i].value);
    if (found == names.end()) {
      table.fail_item(items[i], ": expected the name of an instrument in this scene (" +
                                    instrument_names(names) + ")");
      break;
    }
    const auto index = static_cast<std::size_t>(std::distance(names.begin(), found));
    if (std::find(indices.begin(), indices.end(), index) != indices.end()) {
      table.fail_item(items[i], ": expected each instrument at most once");
      break;
    }
    indices.push_back(index);
  }
  return indices;
}

ObjectConfig read_object(TableReader& table, const std::vector<SceneInstrumentConfig>& instruments,
                         ErrorSink& errors) {
  ObjectConfig object;
  const auto kind = table.required_choice("kind", kObjectKinds);
  if (kind) object.kind = static_cast<ObjectKind>(*kind);
  object.name = table.required_name("name");
  // Only the keys of the object's own kind are read, so e.g. radius_m on a plane is reported
  // as an unknown key rather than silently ignored.
  if (kind && object.kind == ObjectKind::plane) {
    object.point_m = table.required_vec3("point_m", kPositionComponentRangeM, "metres");
    object.normal = table.required_direction("normal");
  } else if (kind && object.kind == ObjectKind::sphere) {
    object.center_m = table.required_vec3("center_m", kPositionComponentRangeM, "metres");
    object.radius_m = table.required_double("radius_m", kSphereRadiusRangeM, "metres");
  }
  object.stiffness_n_per_m =
      table.required_double("stiffness_n_per_m", kObjectStiffnessRange, "newtons per metre");
  object.damping_n_s_per_m = table.optional_double("damping_n_s_per_m", kDefaultObjectDampingNsPerM,
                                                   kObjectDampingRange, "newton-seconds per metre");
  const auto touched_by = table.optional_string_array("touched_by", 1, kMaxSceneInstruments,
                                                      "names of instruments in this scene");
  if (!touched_by) {
    for (std::size_t i = 0; i < instruments.size(); ++i) object.touched_by.push_back(i);
  } else {
    object.touched_by = resolve_touched_by(table, *touched_by, instruments, errors);
  }
  if (!kind) return object;  // the other keys depend on the kind; don't call them unknown
  table.finish();
  return object;
}

SceneConfig read_scene(const detail::ParsedFile& parsed, const LoadOptions& options,
                       ErrorSink& errors, std::optional<core::Error>& device_error) {
  SceneConfig config;
  config.source_path = parsed.file.absolute_path;
  TableReader root = detail::root_reader(parsed, errors);

  TableReader scene = root.required_table("scene");
  config.name = scene.required_name("name");
  std::filesystem::path device_display;
  const std::filesystem::path device_path = scene.required_file("device", true, &device_display);
  scene.finish();
  bool device_loaded = false;
  if (options.device_file) {
    device_display = *options.device_file;
  }
  if (!device_path.empty() || options.device_file) {
    auto device = load_device(device_display);
    if (!device) {
      device_error = std::move(device).error();
      return config;
    }
    config.device = std::move(*device);
    device_loaded = true;
  }

  TableReader loop = root.required_table("loop");
  config.loop = read_loop(loop);
  TableReader memory = root.optional_table("memory");
  config.memory = read_memory(memory);
  TableReader safety = root.required_table("safety");
  config.safety = read_safety(safety);
  if (errors.ok() && device_loaded && config.safety.require_enable_input &&
      config.device.digital.enable_input_bit < 0) {
    safety.fail_value("require_enable_input",
                      ": expected false, because device '" + config.device.name + "' (" +
                          device_display.string() +
                          ") has no enable input wired (digital.enable_input_bit = -1)");
  }
  TableReader trainee = root.optional_table("trainee");
  config.trainee = read_trainee(trainee, options);
  TableReader metrics_table = root.optional_table("metrics");
  config.metrics = read_metrics(metrics_table, config.loop.period_ns, errors);

  config.instruments = read_instruments(root, device_loaded ? &config.device : nullptr,
                                        device_display.string(), errors);

  auto objects = root.array_of_tables("object", 0, kMaxObjects, "objects");
  for (std::size_t i = 0; i < objects.size(); ++i) {
    ObjectConfig object = read_object(objects[i], config.instruments, errors);
    for (std::size_t earlier = 0; errors.ok() && earlier < i; ++earlier) {
      if (config.objects[earlier].name == object.name) {
        objects[i].fail_value("name", " duplicates " + objects[earlier].qualified("name") +
                                          ": expected unique object names");
      }
    }
    config.objects.push_back(std::move(object));
  }
  auto models = root.array_of_tables("model", 0, kMaxModels, "models");
  for (TableReader& entry : models) {
    SceneModelConfig model;
    model.name = entry.required_name("name");
    std::filesystem::path display;
    const std::filesystem::path definition = entry.required_file("definition", true, &display);
    model.position_m =
        entry.optional_vec3("position_m", Vec3{}, kPositionComponentRangeM, "metres");
    model.rotation_deg = entry.optional_vec3(
        "rotation_deg", Vec3{}, kRotationComponentRangeDeg,
        "degrees, intrinsic: about x, then the turned y, then the turned z");
    const auto touched_by = entry.optional_string_array("touched_by", 1, kMaxSceneInstruments,
                                                        "names of instruments in this scene");
    if (!touched_by) {
      for (std::size_t i = 0; i < config.instruments.size(); ++i) model.touched_by.push_back(i);
    } else {
      model.touched_by = resolve_touched_by(entry, *touched_by, config.instruments, errors);
    }
    std::uint32_t insertion_line = 0;
    if (TableReader insertion = entry.optional_table("insertion"); insertion.present()) {
      insertion_line = entry.line("insertion");
      InsertionGoalConfig goal;
      goal.entry_m = insertion.required_vec3("entry_m", kPositionComponentRangeM, "metres");
      goal.direction = insertion.required_direction("direction");
      goal.radius_m = insertion.required_double("radius_m", RealRange::left_open(0.0, 1.0), "metres");
      goal.target_depth_m =
          insertion.required_double("target_depth_m", RealRange::left_open(0.0, 1.0), "metres");
      insertion.finish();
      model.insertion = goal;
    }
    entry.finish();
    for (const SceneModelConfig& earlier : config.models) {
      if (errors.ok() && earlier.name == model.name) {
        entry.fail_value("name", ": expected unique model names");
      }
    }
    if (!errors.ok() || definition.empty()) continue;
    auto loaded = load_model_definition(display);
    if (!loaded) {
      device_error = std::move(loaded).error();
      return config;
    }
    model.definition = std::move(*loaded);
    if (model.insertion && model.definition.kind != ModelKind::catheter) {
      device_error = core::make_error(config.source_path.string() + ":" + std::to_string(insertion_line) +
                                      ": model '" + model.name +
                                      "': [model.insertion] is for catheters; this model's kind is not catheter");
      return config;
    }
    config.models.push_back(std::move(model));
  }
  root.finish();
  return config;
}

}  // namespace

core::Expected<void> apply_loop_overrides(LoopConfig& loop, const LoopOverrides& overrides) {
  const auto check = [](std::string_view key, std::int64_t value, IntRange range,
                        std::string_view unit) -> core::Expected<void> {
    if (value >= range.min && value <= range.max) return {};
    return core::make_error("override of loop." + std::string(key) + " = " + std::to_string(value) +
                            " is out of range: expected " + std::to_string(range.min) + " to " +
                            std::to_string(range.max) + " (" + std::string(unit) + ")");
  };
  if (overrides.period_us) {
    if (auto ok = check("period_us", *overrides.period_us, kPeriodRangeUs, "microseconds"); !ok) {
      return ok;
    }
  }
  if (overrides.priority) {
    if (auto ok = check("priority", *overrides.priority, kPriorityRange,
                        "SCHED_FIFO priority, 0 = SCHED_OTHER");
        !ok) {
      return ok;
    }
  }
  if (overrides.cpu) {
    if (auto ok = check("cpu", *overrides.cpu, kCpuRange, "CPU index, -1 = no pinning"); !ok) {
      return ok;
    }
  }
  if (overrides.overrun_streak_limit) {
    if (auto ok = check("overrun_streak_limit", *overrides.overrun_streak_limit,
                        kOverrunStreakRange, "consecutive overruns");
        !ok) {
      return ok;
    }
  }
  if (overrides.overrun_streak_limit) {
    loop.overrun_streak_limit = static_cast<std::uint32_t>(*overrides.overrun_streak_limit);
  }
  if (overrides.period_us) loop.period_ns = *overrides.period_us * kNanosecondsPerMicrosecond;
  if (overrides.priority) loop.priority = *overrides.priority;
  if (overrides.cpu) loop.cpu = *overrides.cpu;
  return {};
}

namespace {

core::Expected<SceneConfig> scene_from_parsed(core::Expected<detail::ParsedFile> parsed,
                                              const LoadOptions& options) {
  if (!parsed) return std::move(parsed).error();
  ErrorSink errors;
  std::optional<core::Error> device_error;
  SceneConfig config = read_scene(*parsed, options, errors, device_error);
  if (device_error) return std::move(*device_error);
  if (!errors.ok()) return errors.error();
  return config;
}

}  // namespace

core::Expected<SceneConfig> load_scene(const std::filesystem::path& file,
                                       const LoadOptions& options) {
  return scene_from_parsed(detail::parse_toml_file(file), options);
}

core::Expected<SceneConfig> load_scene_text(std::string_view text,
                                            const std::filesystem::path& file,
                                            const LoadOptions& options) {
  return scene_from_parsed(detail::parse_toml_text(text, file), options);
}

}  // namespace trainer::config
