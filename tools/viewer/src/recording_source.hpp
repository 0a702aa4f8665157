// The playback source: a session recording's telemetry frames (channel 2, docs/recording.md),
// read once at open with rt/record's reader into memory (each frame's bytes, ~1 KiB for cbd,
// and its log time: an hour at 60 Hz is ~3.6 MB) and indexed by log time. A damaged or
// truncated file is read up to the damage; the reader's message is kept (damage(), the
// session panel). next() hands out the frame due at the playback position (log time since
// the first frame, advancing with the clock × speed), newest wins when the page is slow;
// control() takes the page's playback requests:
//   {"type":"playback","action":"play"|"pause"|"seek"|"speed","t":SECONDS,"speed":X}
// A seek shows the frame at t even while paused; play at the end starts again from 0.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "frame_source.hpp"
#include "scene_assets.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::viewer {

class RecordingSource final : public FrameSource {
 public:
  // Nanoseconds on a monotonic clock (tests give their own).
  using Clock = std::function<std::int64_t()>;
  static core::Expected<std::unique_ptr<RecordingSource>> open(const SceneAssets& assets,
                                                               const std::filesystem::path& path,
                                                               Clock clock = {});

  core::Expected<bool> next(SceneFrame& frame, std::chrono::milliseconds timeout) override;
  std::string describe() const override;
  std::string stats_json() const override;
  void control(std::string_view message) override;
  std::string playback_json() const override;

  std::size_t frame_count() const noexcept { return index_.size(); }
  double duration_s() const noexcept;
  double position_s() const;
  bool paused() const noexcept { return paused_; }
  bool ended() const;
  const std::string& damage() const noexcept { return damage_; }
  // Log time (since the first frame) of the frame next() handed out last, -1 before any.
  double shown_s() const noexcept;

 private:
  struct Entry {
    std::int64_t log_ns = 0;  // since the first frame
    std::size_t offset = 0;   // into bytes_
    std::size_t size = 0;
  };
  RecordingSource(const SceneAssets& assets) : assets_(assets) {}
  std::int64_t position_ns(std::int64_t now) const;
  void set_position(std::int64_t position_ns);
  std::size_t due_index(std::int64_t position_ns) const;

  const SceneAssets& assets_;
  Clock clock_;
  std::filesystem::path path_;
  std::vector<std::byte> bytes_;
  std::vector<Entry> index_;
  std::string damage_;
  std::unique_ptr<telemetry::Frame> decoded_;
  bool paused_ = false;
  double speed_ = 1.0;
  std::int64_t anchor_position_ns_ = 0;
  std::int64_t anchor_now_ns_ = 0;
  std::size_t shown_ = static_cast<std::size_t>(-1);
  std::uint64_t frames_shown_ = 0;
  std::uint64_t refused_ = 0;
};

}  // namespace trainer::viewer
