// Where the viewer's frames come from: the live UDP stream, a session recording played back
// with seek (recording_source.hpp), a test pattern. The main loop only calls next(); the
// page's control messages (seek, pause, play, speed) reach the source through control().
#pragma once

#include <chrono>
#include <string>
#include <string_view>

#include "scene_frame.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::viewer {

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Waits up to `timeout` for the next frame. true: `frame` holds it; false: nothing yet. An
  // error is a frame refused (bad checksums, malformed): the source stays usable.
  virtual core::Expected<bool> next(SceneFrame& frame, std::chrono::milliseconds timeout) = 0;
  // One line for the start-up message ("udp 0.0.0.0:47800").
  virtual std::string describe() const = 0;
  // The stream's counters for the session panel, a JSON object.
  virtual std::string stats_json() const = 0;
  // A control message from the page (JSON text); live sources ignore it.
  virtual void control(std::string_view /*message*/) {}
  // The playback state for the page's playback bar (a JSON object with "type":"playback"),
  // "" for live sources (no bar).
  virtual std::string playback_json() const { return ""; }
};

}  // namespace trainer::viewer
