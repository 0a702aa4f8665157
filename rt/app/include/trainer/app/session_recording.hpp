// The session recording's two ends in the app (docs/recording.md):
//  * SessionRecorder, non-RT: owns the ring the RT thread's HAL taps push into, the file (when
//    the session is recorded) and the session's trainee metrics (rt/metrics, fed with every
//    record's derived block, file or not); drain() (the supervisor loop, ~30 Hz) writes what
//    the ring holds, close() writes the end of the file with the count of cycles a full ring
//    dropped;
//  * replay_recording(): reruns the cycle code in simulated time on a recording's inputs and
//    compares every output and state hash (trainer --replay).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "trainer/app/hal_taps.hpp"
#include "trainer/app/scene_models.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/metrics/session_metrics.hpp"
#include "trainer/record/recording.hpp"

namespace trainer::app {

// The "session" metadata of a run: scene/device paths and texts, model definitions and image
// checksums, the loop period that ran, the time source, the program version.
record::SessionInfo session_info(const config::SceneConfig& scene,
                                 const std::vector<LoadedModelInfo>& models,
                                 const std::string& time_source, bool digital_inputs,
                                 bool digital_outputs);

// The trainee metrics' setup of a scene (docs/metrics.md): its [metrics] thresholds, loop
// period, instruments and the catheter's insertion target.
metrics::SessionSetup metrics_setup(const config::SceneConfig& scene);

class SessionRecorder {
 public:
  static core::Expected<std::unique_ptr<SessionRecorder>> open(const std::filesystem::path& path,
                                                               const record::SessionInfo& session);
  // No file: the ring is drained into the metrics only (a session run without --record).
  static std::unique_ptr<SessionRecorder> metrics_only();
  // Feeds every drained record's derived block to `metrics` from now on.
  void set_metrics(metrics::SessionMetrics metrics) { metrics_.emplace(std::move(metrics)); }
  const std::optional<metrics::SessionMetrics>& session_metrics() const noexcept {
    return metrics_;
  }
  // Samples the metrics refused (non-finite, instrument count; docs/metrics.md).
  std::uint64_t refused_samples() const noexcept { return refused_samples_; }
  bool recording() const noexcept { return !path_.empty(); }

  RecordRing& ring() noexcept { return *ring_; }
  // Writes every record in the ring. The first write error stops the recording (the run goes
  // on); error() says what it was.
  void drain();
  // One telemetry frame (encoded bytes) on the recording's channel 2, log time = the frame's
  // cycle time (the supervisor's frame sink; docs/recording.md). Errors as drain().
  void add_telemetry(std::span<const std::byte> frame, std::int64_t cycle_time_ns,
                     std::uint64_t sequence);
  std::uint64_t telemetry_frames() const noexcept { return writer_.telemetry_frames(); }
  // Drains, then writes the end of the file (the ring's drop count, the summary).
  void close();

  std::uint64_t records() const noexcept { return writer_.records(); }
  std::uint64_t dropped() const noexcept { return ring_->dropped(); }
  std::uint64_t bytes() const noexcept { return writer_.bytes_written(); }
  const std::string& error() const noexcept { return error_; }
  const std::filesystem::path& path() const noexcept { return path_; }

 private:
  SessionRecorder() = default;
  std::filesystem::path path_;
  std::unique_ptr<RecordRing> ring_ = std::make_unique<RecordRing>();
  record::RecordingWriter writer_;
  std::string error_;
  std::uint64_t unflushed_ = 0;
  bool closed_ = false;
  std::optional<metrics::SessionMetrics> metrics_;
  std::uint64_t refused_samples_ = 0;
};

struct ReplayResult {
  std::string scene_name;
  std::uint64_t cycles_replayed = 0;  // compared, identical up to the first difference
  bool identical = false;             // every replayed cycle's outputs and state hash
  std::optional<std::uint64_t> first_difference_cycle;
  std::string difference;  // "field: recorded X, replayed Y"
  std::string damage;      // the file's damage (replay went up to it), or empty
  bool complete = false;   // the session closed the file (session_end present)
  std::uint64_t dropped_cycles = 0;
  // The trainee metrics of the replayed (identical) cycles, with the scene's thresholds and
  // names for the report section (docs/metrics.md).
  std::optional<metrics::SessionResult> metrics;
  metrics::MetricsThresholds metrics_thresholds;
  std::vector<std::string> instrument_names;
  std::vector<std::string> model_names;
};

// `change` (tests): called on each recorded record before it is replayed, to alter inputs.
core::Expected<ReplayResult> replay_recording(
    const std::filesystem::path& path,
    const std::function<void(record::CycleRecord&)>& change = {});

// One line: "N cycles, all outputs and state hashes identical" or the first difference.
std::string replay_summary(const ReplayResult& result);

}  // namespace trainer::app
