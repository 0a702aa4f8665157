#include "recording_source.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>
#include <utility>

#include <nlohmann/json.hpp>

#include "trainer/record/recording.hpp"
#include "udp_source.hpp"

namespace trainer::viewer {
namespace {

std::int64_t playback_steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::int64_t playback_realtime_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

constexpr std::size_t kNoneShown = static_cast<std::size_t>(-1);

// A number field of a page request; NaN when absent or not a number (refused by the caller).
double playback_number(const nlohmann::json& request, const char* key) {
  const auto found = request.find(key);
  return found != request.end() && found->is_number() ? found->get<double>()
                                                      : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

core::Expected<std::unique_ptr<RecordingSource>> RecordingSource::open(
    const SceneAssets& assets, const std::filesystem::path& path, Clock clock) {
  std::unique_ptr<RecordingSource> source(new RecordingSource(assets));
  source->clock_ = clock ? std::move(clock) : Clock(playback_steady_ns);
  source->path_ = path;
  struct Raw {
    std::uint64_t log_ns;
    std::size_t offset;
    std::size_t size;
  };
  std::vector<Raw> raw;
  auto scan = record::scan_recording(path, {}, [&](const record::TelemetryMessage& m) {
    raw.push_back({m.log_time_ns, source->bytes_.size(), m.bytes.size()});
    const auto* bytes = reinterpret_cast<const std::byte*>(m.bytes.data());
    source->bytes_.insert(source->bytes_.end(), bytes, bytes + m.bytes.size());
    return true;
  });
  if (!scan) return core::make_error("--recording " + scan.error().message);
  source->damage_ = scan->mcap.damage;
  if (raw.empty()) {
    return core::make_error(
        "--recording " + path.string() +
        ": no telemetry frames (channel 2 /trainer/telemetry)" +
        (source->damage_.empty() ? std::string(": recorded by a trainer before channel 2")
                                 : "; damaged: " + source->damage_));
  }
  std::stable_sort(raw.begin(), raw.end(),
                   [](const Raw& a, const Raw& b) { return a.log_ns < b.log_ns; });
  const std::uint64_t first = raw.front().log_ns;
  source->index_.reserve(raw.size());
  for (const Raw& r : raw) {
    source->index_.push_back({static_cast<std::int64_t>(r.log_ns - first), r.offset, r.size});
  }
  source->decoded_ = std::make_unique<telemetry::Frame>();
  source->anchor_now_ns_ = source->clock_();
  return source;
}

double RecordingSource::duration_s() const noexcept {
  return static_cast<double>(index_.back().log_ns) * 1e-9;
}

std::int64_t RecordingSource::position_ns(std::int64_t now) const {
  if (paused_) return anchor_position_ns_;
  const double advanced = static_cast<double>(now - anchor_now_ns_) * speed_;
  const double position = static_cast<double>(anchor_position_ns_) + advanced;
  return std::clamp<std::int64_t>(static_cast<std::int64_t>(position), 0, index_.back().log_ns);
}

double RecordingSource::position_s() const {
  return static_cast<double>(position_ns(clock_())) * 1e-9;
}

bool RecordingSource::ended() const {
  return shown_ == index_.size() - 1 && position_ns(clock_()) >= index_.back().log_ns;
}

double RecordingSource::shown_s() const noexcept {
  return shown_ == kNoneShown ? -1.0 : static_cast<double>(index_[shown_].log_ns) * 1e-9;
}

void RecordingSource::set_position(std::int64_t position_ns) {
  anchor_position_ns_ = std::clamp<std::int64_t>(position_ns, 0, index_.back().log_ns);
  anchor_now_ns_ = clock_();
}

std::size_t RecordingSource::due_index(std::int64_t position_ns) const {
  // The last frame whose log time is at or before the position (the first one at 0).
  const auto after = std::upper_bound(
      index_.begin(), index_.end(), position_ns,
      [](std::int64_t t, const Entry& e) { return t < e.log_ns; });
  return after == index_.begin() ? 0 : static_cast<std::size_t>(after - index_.begin()) - 1;
}

core::Expected<bool> RecordingSource::next(SceneFrame& frame, std::chrono::milliseconds timeout) {
  std::size_t due = due_index(position_ns(clock_()));
  if (due == shown_) {
    // Nothing new: wait for the next frame's time (or the timeout), then look again.
    if (timeout.count() <= 0) return false;
    std::int64_t wait_ns = std::chrono::nanoseconds(timeout).count();
    if (!paused_ && due + 1 < index_.size() && speed_ > 0.0) {
      const auto until = static_cast<std::int64_t>(
          static_cast<double>(index_[due + 1].log_ns - position_ns(clock_())) / speed_);
      wait_ns = std::clamp<std::int64_t>(until, 0, wait_ns);
    }
    std::this_thread::sleep_for(std::chrono::nanoseconds(wait_ns));
    due = due_index(position_ns(clock_()));
    if (due == shown_) return false;
  }
  shown_ = due;
  const Entry& entry = index_[due];
  const telemetry::DecodeResult result =
      telemetry::decode({bytes_.data() + entry.offset, entry.size}, *decoded_);
  if (!result.ok()) {
    ++refused_;
    return core::make_error("recording frame at " + std::to_string(static_cast<double>(entry.log_ns) * 1e-9) +
                            " s: " + telemetry::to_string(result.error) + " at byte " +
                            std::to_string(result.offset) + " (" + result.detail + ")");
  }
  if (auto converted = scene_frame_from_telemetry(assets_, *decoded_, frame); !converted) {
    ++refused_;
    return std::move(converted).error();
  }
  // A recorded frame was sent long ago: no hop latencies on the page (it needs sent_ns > 0).
  frame.times.sent_ns = 0;
  frame.times.received_ns = playback_realtime_ns();
  ++frames_shown_;
  return true;
}

void RecordingSource::control(std::string_view message) {
  const nlohmann::json request = nlohmann::json::parse(message, nullptr, false);
  if (!request.is_object()) return;
  const auto type = request.find("type");
  const auto action_field = request.find("action");
  if (type == request.end() || *type != "playback" || action_field == request.end() ||
      !action_field->is_string())
    return;
  const std::string action = action_field->get<std::string>();
  const std::int64_t now = clock_();
  if (action == "pause") {
    set_position(position_ns(now));
    paused_ = true;
  } else if (action == "play") {
    const bool at_end = position_ns(now) >= index_.back().log_ns;
    set_position(at_end ? 0 : position_ns(now));
    paused_ = false;
  } else if (action == "seek") {
    const double t = playback_number(request, "t");
    if (!std::isfinite(t)) return;
    set_position(static_cast<std::int64_t>(t * 1e9));
    shown_ = kNoneShown;  // the frame at t is shown even while paused
  } else if (action == "speed") {
    const double speed = playback_number(request, "speed");
    if (!std::isfinite(speed) || speed <= 0.0 || speed > 16.0) return;
    set_position(position_ns(now));
    speed_ = speed;
  }
}

std::string RecordingSource::playback_json() const {
  nlohmann::json state{{"type", "playback"},
                       {"position_s", position_s()},
                       {"duration_s", duration_s()},
                       {"paused", paused_},
                       {"speed", speed_},
                       {"ended", ended()},
                       {"damage", damage_}};
  return state.dump();
}

std::string RecordingSource::describe() const {
  char duration[32];
  std::snprintf(duration, sizeof duration, "%.1f", duration_s());
  return "recording " + path_.string() + " (" + std::to_string(index_.size()) +
         " telemetry frames, " + duration + " s" +
         (damage_.empty() ? std::string(")") : "; read up to the damage: " + damage_ + ")");
}

std::string RecordingSource::stats_json() const {
  nlohmann::json stats{{"source", "recording"},
                       {"file", path_.string()},
                       {"frames", index_.size()},
                       {"frames_shown", frames_shown_},
                       {"refused", refused_},
                       {"position_s", position_s()},
                       {"duration_s", duration_s()},
                       {"paused", paused_},
                       {"speed", speed_}};
  if (!damage_.empty()) stats["damage"] = damage_;
  return stats.dump();
}

}  // namespace trainer::viewer
