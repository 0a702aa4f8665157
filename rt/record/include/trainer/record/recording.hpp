// The session recording file (docs/recording.md): an MCAP file with
//   * Metadata "session" (before the first cycle): scene and device file paths and texts, each
//     model's definition path and text and image checksum, period, time source, program
//     version, the cycle record's layout and channel count;
//   * channel 1 "/trainer/cycle": one message per haptic cycle, the CycleRecord's bytes
//     (log_time = the cycle's wake time on the loop's clock, sequence = cycle index mod 2^32);
//   * Metadata "session_end" (when the session closed the file cleanly): cycles recorded,
//     cycles dropped because the ring was full.
//   * channel 2 "/trainer/telemetry": the telemetry frames at the stream's rate (the same
//     encoded bytes the UDP stream sends, docs/telemetry.md; log_time = the frame's cycle time,
//     sequence = the frame's sequence mod 2^32), written whenever a recording is on.
// Non-RT only.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>

#include "trainer/core/expected.hpp"
#include "trainer/record/cycle_record.hpp"
#include "trainer/record/mcap.hpp"

namespace trainer::record {

inline constexpr std::uint16_t kCycleChannel = 1;
inline constexpr std::uint16_t kTelemetryChannel = 2;
inline constexpr const char* kTelemetryTopic = "/trainer/telemetry";
inline constexpr const char* kTelemetryEncoding = "trainer-telemetry-frame";
inline constexpr const char* kCycleTopic = "/trainer/cycle";
inline constexpr const char* kCycleEncoding = "trainer-cycle-record";
inline constexpr const char* kProfile = "trainer-session";

using SessionInfo = std::map<std::string, std::string>;

class RecordingWriter {
 public:
  // Creates `path`, writes the header, the cycle channel and the "session" metadata.
  core::Expected<void> open(const std::filesystem::path& path, const SessionInfo& session,
                            mcap::Compression compression = mcap::Compression::zstd);
  core::Expected<void> add(const CycleRecord& record);
  // One telemetry frame (its encoded bytes) on channel 2, log_time = the frame's cycle time.
  core::Expected<void> add_telemetry(std::span<const std::byte> frame, std::int64_t cycle_time_ns,
                                     std::uint64_t sequence);
  std::uint64_t telemetry_frames() const noexcept { return telemetry_frames_; }
  // Writes the open chunk (called about once a second so a crash loses little).
  core::Expected<void> flush() { return writer_.flush_chunk(); }
  // "session_end" metadata, summary, footer.
  core::Expected<void> close(std::uint64_t dropped_cycles);
  std::uint64_t records() const noexcept { return records_; }
  std::uint64_t bytes_written() const noexcept { return writer_.bytes_written(); }

 private:
  mcap::Writer writer_;
  std::uint64_t records_ = 0;
  std::uint64_t telemetry_frames_ = 0;
};

struct RecordingScan {
  SessionInfo session;
  std::optional<SessionInfo> session_end;  // absent when the session did not close the file
  mcap::ScanResult mcap;
  std::uint64_t records = 0;  // cycle records delivered
  std::uint64_t telemetry_frames = 0;  // telemetry frames delivered (on_telemetry given)
};

// Reads `path`, calling `on_record` for every cycle record in order (false stops). Errors: not
// MCAP, no "session" metadata before the first record, another record layout. A truncated or
// corrupt file delivers the records before the damage; RecordingScan.mcap.damage says where.
core::Expected<RecordingScan> scan_recording(
    const std::filesystem::path& path, const std::function<bool(const CycleRecord&)>& on_record);

// A telemetry frame of channel 2: its log time (the frame's cycle time) and encoded bytes
// (valid during the call only).
struct TelemetryMessage {
  std::uint64_t log_time_ns = 0;
  std::uint32_t sequence = 0;
  std::span<const std::uint8_t> bytes;
};

// As above, also calling `on_telemetry` for every channel-2 frame in file order (either
// callback returning false stops). `on_record` may be empty.
core::Expected<RecordingScan> scan_recording(
    const std::filesystem::path& path, const std::function<bool(const CycleRecord&)>& on_record,
    const std::function<bool(const TelemetryMessage&)>& on_telemetry);

}  // namespace trainer::record
