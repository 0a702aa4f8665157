// The viewer's main loop, apart from main() so tests drive it: frames from a source, rebuilt
// and encoded, sent to every page; once a second the session panel's JSON.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

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

// Runs until `seconds` have passed (0: no limit) or should_stop() is true. `metrics_file`, when
// not empty, is read once a second: its JSON object becomes the session panel's trainee metrics
// (a file another process rewrites; missing or unparsable: the panel shows none).
LoopSummary run_viewer_loop(FrameSource& source, ViewFrameEncoder& encoder, WebServer& server,
                            double seconds, const std::function<bool()>& should_stop,
                            const std::string& metrics_file = {});

void print_summary(const LoopSummary& summary, WebServer& server, const FrameSource& source);

// The session panel's JSON (text message {"type":"session",...}); `metrics_json` is the
// trainee metrics object ("{}" until the metrics are joined).
std::string session_json(const LoopSummary& summary, const FrameSource& source,
                         const std::string& metrics_json);

}  // namespace trainer::viewer
