#include "trainer/app/session_recording.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "trainer/app/haptic_app.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/core/clock.hpp"
#include "trainer/core/log_ring.hpp"
#include "trainer/core/triple_buffer.hpp"
#include "trainer/record/cycle_sample.hpp"

#ifndef TRAINER_GIT_DESCRIBE
#define TRAINER_GIT_DESCRIBE "unknown"
#endif

namespace trainer::app {
namespace {

std::string text_of_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Flush a chunk about once a second at 1 kHz, so a crash loses at most about that much.
constexpr std::uint64_t kFlushEveryRecords = 1000;

}  // namespace

record::SessionInfo session_info(const config::SceneConfig& scene,
                                 const std::vector<LoadedModelInfo>& models,
                                 const std::string& time_source, bool digital_inputs,
                                 bool digital_outputs) {
  record::SessionInfo info;
  info["program"] = std::string("trainer ") + TRAINER_GIT_DESCRIBE;
  info["record_layout"] = std::to_string(record::kCycleRecordLayout);
  info["scene_name"] = scene.name;
  info["scene_file"] = scene.source_path.string();
  info["scene_text"] = text_of_file(scene.source_path);
  info["device_file"] = scene.device.source_path.string();
  info["device_text"] = text_of_file(scene.device.source_path);
  info["period_ns"] = std::to_string(scene.loop.period_ns);
  info["time_source"] = time_source;
  info["digital_inputs"] = digital_inputs ? "1" : "0";
  info["digital_outputs"] = digital_outputs ? "1" : "0";
  info["model_count"] = std::to_string(models.size());
  for (std::size_t m = 0; m < models.size(); ++m) {
    const std::string key = "model." + std::to_string(m) + ".";
    info[key + "name"] = models[m].name;
    info[key + "definition_file"] = models[m].definition_path;
    info[key + "definition_text"] = text_of_file(models[m].definition_path);
    info[key + "image_file"] = models[m].image_path;
    info[key + "image_checksum"] = std::to_string(models[m].image_checksum);
  }
  return info;
}

metrics::SessionSetup metrics_setup(const config::SceneConfig& scene) {
  metrics::SessionSetup setup;
  setup.thresholds = scene.metrics;
  setup.period_ns = scene.loop.period_ns;
  setup.instrument_count = static_cast<std::uint32_t>(scene.instruments.size());
  for (const config::SceneModelConfig& entry : scene.models) {
    if (entry.definition.kind == config::ModelKind::catheter && entry.insertion) {
      setup.insertion_target_depth_m = entry.insertion->target_depth_m;
      break;
    }
  }
  return setup;
}

std::unique_ptr<SessionRecorder> SessionRecorder::metrics_only() {
  return std::unique_ptr<SessionRecorder>(new SessionRecorder());
}

core::Expected<std::unique_ptr<SessionRecorder>> SessionRecorder::open(
    const std::filesystem::path& path, const record::SessionInfo& session) {
  std::unique_ptr<SessionRecorder> recorder(new SessionRecorder());
  recorder->path_ = path;
  if (auto opened = recorder->writer_.open(path, session); !opened)
    return core::make_error("--record " + opened.error().message);
  return recorder;
}

void SessionRecorder::drain() {
  record::CycleRecord record;
  while (ring_->pop(record)) {
    if (metrics_ && !metrics_->add(record::cycle_sample_of(record))) ++refused_samples_;
    if (!recording() || !error_.empty() || closed_) continue;
    if (auto added = writer_.add(record); !added) {
      error_ = added.error().message;
      continue;
    }
    if (++unflushed_ >= kFlushEveryRecords) {
      unflushed_ = 0;
      if (auto flushed = writer_.flush(); !flushed) error_ = flushed.error().message;
    }
  }
}

void SessionRecorder::add_telemetry(std::span<const std::byte> frame, std::int64_t cycle_time_ns,
                                    std::uint64_t sequence) {
  if (!error_.empty() || closed_) return;
  if (auto added = writer_.add_telemetry(frame, cycle_time_ns, sequence); !added)
    error_ = added.error().message;
}

void SessionRecorder::close() {
  drain();
  if (closed_) return;
  closed_ = true;
  if (!recording() || !error_.empty()) return;
  if (auto closed = writer_.close(ring_->dropped()); !closed) error_ = closed.error().message;
}

namespace {

// The HAL of a replay: returns the current recorded cycle's inputs, swallows the outputs (the
// taps around it record them).
class ReplayHal final : public hal::EncoderInterface,
                        public hal::ActuatorInterface,
                        public hal::DigitalInputInterface,
                        public hal::DigitalOutputInterface {
 public:
  explicit ReplayHal(std::size_t channels) : channels_(channels) {}
  void set(const record::CycleRecord& record) { current_ = &record; }

  std::size_t encoder_count() const noexcept override { return channels_; }
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override {
    for (std::size_t c = 0; c < out.size() && c < record::kMaxRecordChannels; ++c) {
      out[c].counts = current_->encoders[c].counts;
      out[c].position = current_->encoders[c].position;
      out[c].valid = current_->encoders[c].valid != 0;
    }
    return code(current_->encoder_rc);
  }
  std::size_t actuator_count() const noexcept override { return channels_; }
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand>) noexcept override {
    return code(current_->actuator_write_rc);
  }
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus> out) noexcept override {
    for (std::size_t c = 0; c < out.size() && c < record::kMaxRecordChannels; ++c) {
      out[c].applied_effort = current_->status[c].applied_effort;
      out[c].enabled = current_->status[c].enabled != 0;
      out[c].saturated = current_->status[c].saturated != 0;
      out[c].fault = current_->status[c].fault != 0;
    }
    return code(current_->status_rc);
  }
  std::size_t digital_input_count() const noexcept override { return 32; }
  hal::ReturnCode read_digital_inputs(std::uint32_t& levels) noexcept override {
    levels = current_->digital_in_levels;
    return code(current_->digital_in_rc);
  }
  std::size_t digital_output_count() const noexcept override { return 32; }
  hal::ReturnCode write_digital_outputs(std::uint32_t) noexcept override {
    return code(current_->digital_out_rc);
  }

 private:
  // A call the recording did not see (255) replays as ok: the comparison reports the
  // difference in the write counts or outputs instead.
  static hal::ReturnCode code(std::uint8_t rc) noexcept {
    return rc <= 2 ? static_cast<hal::ReturnCode>(rc) : hal::ReturnCode::ok;
  }
  std::size_t channels_;
  const record::CycleRecord* current_ = nullptr;
};

std::uint64_t number_or_zero(const std::string& text) {
  std::uint64_t value = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return 0;
    value = value * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return value;
}

std::string value_or(const record::SessionInfo& info, const std::string& key) {
  const auto it = info.find(key);
  return it == info.end() ? std::string() : it->second;
}

// The scene as recorded: its embedded text, the device and model definition files checked
// against their recorded texts (a replay needs the same inputs to the setup as the session).
core::Expected<config::SceneConfig> recorded_scene(const std::filesystem::path& path,
                                                   const record::SessionInfo& info) {
  const std::string where = path.string() + ": ";
  const std::string device_file = value_or(info, "device_file");
  if (value_or(info, "scene_text").empty() || device_file.empty())
    return core::make_error(where + "the session metadata has no scene or device file");
  if (text_of_file(device_file) != value_or(info, "device_text")) {
    return core::make_error(where + "device file " + device_file +
                            " differs from the one recorded (or is missing): replay needs the "
                            "recorded device file");
  }
  config::LoadOptions options;
  options.require_script_file = false;
  options.device_file = device_file;
  auto scene =
      config::load_scene_text(value_or(info, "scene_text"), value_or(info, "scene_file"), options);
  if (!scene) return core::make_error(where + "the recorded scene: " + scene.error().message);
  const std::string period = value_or(info, "period_ns");
  if (period.empty()) return core::make_error(where + "the session metadata has no period_ns");
  scene->loop.period_ns = static_cast<std::int64_t>(number_or_zero(period));
  if (scene->loop.period_ns <= 0)
    return core::make_error(where + "period_ns '" + period + "': expected a positive integer");
  const std::size_t model_count = number_or_zero(value_or(info, "model_count"));
  for (std::size_t m = 0; m < model_count; ++m) {
    const std::string key = "model." + std::to_string(m) + ".";
    const std::string file = value_or(info, key + "definition_file");
    if (text_of_file(file) != value_or(info, key + "definition_text")) {
      return core::make_error(where + "model '" + value_or(info, key + "name") +
                              "': definition file " + file +
                              " differs from the one recorded (or is missing)");
    }
  }
  return scene;
}

}  // namespace

core::Expected<ReplayResult> replay_recording(
    const std::filesystem::path& path, const std::function<void(record::CycleRecord&)>& change) {
  // First pass: the session metadata (and the end) — the scan stops at the first record.
  auto header = record::scan_recording(path, [](const record::CycleRecord&) { return false; });
  if (!header) return std::move(header).error();
  const record::SessionInfo info = header->session;
  auto scene = recorded_scene(path, info);
  if (!scene) return std::move(scene).error();

  const std::size_t channels = scene->device.instruments.size() * kinematics::kJointCount;
  ReplayHal replay_hal(channels);
  HalBinding inner{&replay_hal, &replay_hal,
                   value_or(info, "digital_inputs") == "1" ? &replay_hal : nullptr,
                   value_or(info, "digital_outputs") == "1" ? &replay_hal : nullptr};
  auto taps = HalTaps::create(inner, nullptr);
  if (!taps) return std::move(taps).error();
  auto arena = core::Arena::create(scene->memory.arena_bytes);
  if (!arena) return std::move(arena).error();
  auto log = std::make_unique<core::LogRing>();
  auto telemetry = std::make_unique<core::TripleBuffer<TelemetrySnapshot>>();
  core::ManualClock clock(0);
  auto app = HapticApp::create(*scene, (*taps)->binding(), *arena, *log, *telemetry, clock);
  if (!app) return std::move(app).error();
  HapticApp& haptic = **app;
  haptic.set_recorder(taps->get());
  const std::vector<LoadedModelInfo>& models = haptic.models();
  for (std::size_t m = 0; m < models.size(); ++m) {
    const std::string key = "model." + std::to_string(m) + ".";
    if (value_or(info, key + "image_checksum") != std::to_string(models[m].image_checksum)) {
      return core::make_error(path.string() + ": model '" + models[m].name + "' image " +
                              models[m].image_path + " has checksum " +
                              std::to_string(models[m].image_checksum) + ", the recording " +
                              value_or(info, key + "image_checksum") +
                              ": replay needs the images the session ran with");
    }
  }

  ReplayResult result;
  result.scene_name = scene->name;
  // The trainee metrics of the replayed cycles (the same as the session's when identical).
  auto session_metrics = metrics::SessionMetrics::create(metrics_setup(*scene));
  if (!session_metrics) return std::move(session_metrics).error();
  result.metrics_thresholds = scene->metrics;
  for (const config::SceneInstrumentConfig& instrument : scene->instruments)
    result.instrument_names.push_back(instrument.name);
  for (const config::SceneModelConfig& entry : scene->models) result.model_names.push_back(entry.name);
  std::uint64_t expected_cycle = 0;
  std::string gap;
  core::LogRecord discarded;
  auto scanned = record::scan_recording(path, [&](const record::CycleRecord& recorded_in) {
    record::CycleRecord recorded = recorded_in;
    if (change) change(recorded);
    if (recorded.cycle_index != expected_cycle) {
      gap = "cycle " + std::to_string(expected_cycle) + " is missing (the next record is cycle " +
            std::to_string(recorded.cycle_index) +
            "; the ring was full while recording): replay needs every cycle";
      return false;
    }
    ++expected_cycle;
    replay_hal.set(recorded);
    if (recorded.reset_requested != 0) haptic.request_reset();
    const loop::CycleTiming timing{recorded.cycle_index, recorded.deadline_ns, recorded.wake_ns,
                                   recorded.dt_s, recorded.overrun_streak};
    (void)haptic.run_cycle(timing);
    if (recorded.overrun_fault_streak != 0) haptic.on_overrun_fault(recorded.overrun_fault_streak);
    while (log->pop(discarded)) {
    }
    const std::string difference = record::first_output_difference(recorded, (*taps)->pending());
    if (!difference.empty()) {
      result.first_difference_cycle = recorded.cycle_index;
      result.difference = difference;
      return false;
    }
    ++result.cycles_replayed;
    (void)session_metrics->add(record::cycle_sample_of((*taps)->pending()));
    return true;
  });
  result.metrics = session_metrics->result();
  if (!scanned) return std::move(scanned).error();
  result.complete = scanned->session_end.has_value();
  if (scanned->session_end)
    result.dropped_cycles = number_or_zero(value_or(*scanned->session_end, "cycles_dropped"));
  if (!scanned->mcap.damage.empty()) {
    result.damage = path.string() + ": " + scanned->mcap.damage + " (cycles from " +
                    std::to_string(expected_cycle) + " on are not in the file)";
  }
  if (!gap.empty()) result.damage = path.string() + ": " + gap;
  result.identical = !result.first_difference_cycle && result.damage.empty();
  return result;
}

std::string replay_summary(const ReplayResult& result) {
  std::ostringstream out;
  if (result.first_difference_cycle) {
    out << "replay differs at cycle " << *result.first_difference_cycle << ": " << result.difference
        << " (" << result.cycles_replayed << " cycles identical before it)";
  } else if (!result.damage.empty()) {
    out << result.cycles_replayed
        << " cycles, all outputs and state hashes identical up to the damage: " << result.damage;
  } else {
    out << result.cycles_replayed << " cycles, all outputs and state hashes identical";
  }
  if (!result.complete && result.damage.empty()) out << " (the session did not close the file)";
  return out.str();
}

}  // namespace trainer::app
