#include "viewer_loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace trainer::viewer {

namespace {

double viewer_frame_reconstruct_us(const std::vector<std::byte>& frame) {
  double value = 0.0;
  std::memcpy(&value, frame.data() + 56, sizeof value);
  return value;
}

// The metrics file's JSON object as text, "{}" when there is none (or it is not an object).
std::string read_metrics_file(const std::string& path) {
  if (path.empty()) return "{}";
  std::ifstream in(path);
  if (!in) return "{}";
  const nlohmann::json metrics = nlohmann::json::parse(in, nullptr, false);
  return metrics.is_object() ? metrics.dump() : "{}";
}

}  // namespace

std::string stream_metrics_json(const telemetry::SessionMetrics& m,
                                const std::vector<std::string>& instrument_names) {
  const auto rounded = [](double value, double unit) {
    return std::round(value * unit * 1000.0) / 1000.0;
  };
  nlohmann::json out;
  const bool started = (m.flags & telemetry::kMetricsTaskStarted) != 0;
  const bool completed = (m.flags & telemetry::kMetricsTaskCompleted) != 0;
  out["task"] = completed ? "completed" : (started ? "in progress" : "not started");
  out["task_time_s"] = rounded(m.task_time_s, 1.0);
  out["session_time_s"] = rounded(m.session_time_s, 1.0);
  out["above_safe_force_s"] = rounded(m.time_above_safe_s, 1.0);
  out["damage_impulse_n_s"] = rounded(m.damage_impulse_n_s, 1.0);
  if ((m.flags & telemetry::kMetricsInsertionGoal) != 0) {
    out["insertion_depth_mm"] = rounded(m.insertion_depth_m, 1e3);
    if ((m.flags & telemetry::kMetricsTargetReached) != 0)
      out["time_to_target_s"] = rounded(m.time_to_target_s, 1.0);
    else
      out["time_to_target_s"] = "not reached";
  }
  for (std::size_t i = 0; i < m.instrument_count && i < telemetry::kMaxInstruments; ++i) {
    const telemetry::InstrumentMetrics& t = m.instruments[i];
    const std::string name =
        i < instrument_names.size() ? instrument_names[i] : "instrument " + std::to_string(i);
    out[name] = {{"path_mm", rounded(t.path_length_m, 1e3)},
                 {"movements", t.movements},
                 {"idle_s", rounded(t.idle_time_s, 1.0)},
                 {"peak_force_n", rounded(t.peak_force_n, 1.0)},
                 {"mean_contact_force_n", rounded(t.mean_contact_force_n, 1.0)},
                 {"above_safe_force_s", rounded(t.time_above_safe_s, 1.0)},
                 {"grasps", t.grasps},
                 {"slips", t.slips}};
  }
  return out.dump();
}

std::string session_json(const LoopSummary& summary, const FrameSource& source,
                         const std::string& metrics_json) {
  nlohmann::json session;
  session["type"] = "session";
  session["frames"] = summary.frames;
  session["refused"] = summary.refused;
  session["cycle"] = summary.last_cycle;
  session["viewer_seconds"] = summary.seconds;
  session["mean_frame_bytes"] = summary.mean_frame_bytes;
  session["mean_reconstruct_us"] = summary.mean_reconstruct_us;
  session["stream"] = nlohmann::json::parse(source.stats_json(), nullptr, false);
  session["metrics"] = nlohmann::json::parse(metrics_json, nullptr, false);
  if (!summary.last_error.empty()) session["error"] = summary.last_error;
  return session.dump();
}

LoopSummary run_viewer_loop(FrameSource& source, ViewFrameEncoder& encoder, WebServer& server,
                            double seconds, const std::function<bool()>& should_stop,
                            const std::string& metrics_file,
                            const std::vector<std::string>& instrument_names) {
  LoopSummary summary;
  const auto start = std::chrono::steady_clock::now();
  auto next_session = start + std::chrono::seconds(1);
  auto next_playback = start;
  SceneFrame frame;
  std::string stream_metrics = "{}";  // the newest frame's trainee metrics
  std::vector<std::byte> encoded;
  double bytes_total = 0.0;
  double reconstruct_total = 0.0;
  while (!should_stop()) {
    const auto now = std::chrono::steady_clock::now();
    summary.seconds = std::chrono::duration<double>(now - start).count();
    if (seconds > 0.0 && summary.seconds >= seconds) break;
    if (now >= next_session) {
      next_session += std::chrono::seconds(1);
      server.broadcast_text(session_json(
          summary, source, metrics_file.empty() ? stream_metrics : read_metrics_file(metrics_file)));
    }
    // Playback requests from the page, and the playback state for its bar (~10 Hz, and at
    // once after a request).
    const std::vector<std::string> controls = server.take_controls();
    for (const std::string& c : controls) source.control(c);
    if (!controls.empty() || now >= next_playback) {
      next_playback = now + std::chrono::milliseconds(100);
      const std::string playback = source.playback_json();
      if (!playback.empty()) server.broadcast_text(playback);
    }
    auto got = source.next(frame, std::chrono::milliseconds(50));
    if (!got) {
      ++summary.refused;
      if (summary.last_error != got.error().message) {
        summary.last_error = got.error().message;
        std::fprintf(stderr, "viewer: %s\n", summary.last_error.c_str());
        nlohmann::json status{{"type", "status"}, {"error", summary.last_error}};
        server.broadcast_text(status.dump());
      }
      continue;
    }
    if (!*got) continue;
    if (frame.has_metrics) stream_metrics = stream_metrics_json(frame.metrics, instrument_names);
    auto encoded_ok = encoder.encode(frame, encoded);
    if (!encoded_ok) {
      ++summary.refused;
      if (summary.last_error != encoded_ok.error().message) {
        summary.last_error = encoded_ok.error().message;
        std::fprintf(stderr, "viewer: %s\n", summary.last_error.c_str());
      }
      continue;
    }
    ++summary.frames;
    summary.last_cycle = frame.cycle;
    const double size = static_cast<double>(encoded.size());
    const double us = viewer_frame_reconstruct_us(encoded);
    bytes_total += size;
    reconstruct_total += us;
    summary.max_frame_bytes = std::max(summary.max_frame_bytes, size);
    summary.max_reconstruct_us = std::max(summary.max_reconstruct_us, us);
    summary.mean_frame_bytes = bytes_total / static_cast<double>(summary.frames);
    summary.mean_reconstruct_us = reconstruct_total / static_cast<double>(summary.frames);
    server.broadcast_frame(encoded);
  }
  return summary;
}

void print_summary(const LoopSummary& summary, WebServer& server, const FrameSource& source) {
  std::printf("viewer: %.1f s, %llu frames (last cycle %llu), %llu refused, %llu sent to pages\n",
              summary.seconds, static_cast<unsigned long long>(summary.frames),
              static_cast<unsigned long long>(summary.last_cycle),
              static_cast<unsigned long long>(summary.refused),
              static_cast<unsigned long long>(server.frames_sent()));
  std::printf("  page frame %.0f bytes mean, %.0f max; rebuild + encode %.1f us mean, %.1f max\n",
              summary.mean_frame_bytes, summary.max_frame_bytes, summary.mean_reconstruct_us,
              summary.max_reconstruct_us);
  std::printf("  stream: %s\n", source.stats_json().c_str());
  const std::string page = server.last_page_stats();
  if (!page.empty()) std::printf("  page: %s\n", page.c_str());
  if (!summary.last_error.empty()) std::printf("  last error: %s\n", summary.last_error.c_str());
}

}  // namespace trainer::viewer
