// The viewer's main loop, apart from main() so tests drive it: frames from a source, rebuilt
// and encoded, sent to every page; once a second the session panel's JSON.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "frame_source.hpp"
#include "view_frame.hpp"
#include "web_server.hpp"

namespace trainer::viewer {

struct LoopSummary {
  std::uint64_t frames = 0;   // accepted from the source
  std::uint64_t refused = 0;  // refused by the source or the encoder
  std::uint64_t last_cycle = 0;
  double seconds = 0.0;
  double mean_frame_bytes = 0.0;  // WebSocket frame
  double max_frame_bytes = 0.0;
  double mean_reconstruct_us = 0.0;  // rebuild + encode in the viewer
  double max_reconstruct_us = 0.0;
  std::string last_error;
};

// Runs until `seconds` have passed (0: no limit) or should_stop() is true. The session panel's
// trainee metrics: the newest frame's (the appliance computes them from every cycle; wire format
// 1.1), instruments named by `instrument_names` (scene order); or, when `metrics_file` is not
// empty, that file's JSON object, read once a second (a file another process rewrites; missing
// or unparsable: the panel shows none).
LoopSummary run_viewer_loop(FrameSource& source, ViewFrameEncoder& encoder, WebServer& server,
                            double seconds, const std::function<bool()>& should_stop,
                            const std::string& metrics_file = {},
                            const std::vector<std::string>& instrument_names = {});

// The panel's JSON object of a frame's trainee metrics (times in s, lengths in mm, forces in N).
std::string stream_metrics_json(const telemetry::SessionMetrics& metrics,
                                const std::vector<std::string>& instrument_names);

void print_summary(const LoopSummary& summary, WebServer& server, const FrameSource& source);

// The session panel's JSON (text message {"type":"session",...}); `metrics_json` is the
// trainee metrics object ("{}" until the metrics are joined).
std::string session_json(const LoopSummary& summary, const FrameSource& source,
                         const std::string& metrics_json);

}  // namespace trainer::viewer
