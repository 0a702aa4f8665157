#include "trainer/record/recording.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <span>
#include <utility>

namespace trainer::record {
namespace {

// The schema's data: where the layout is documented (the bytes are the struct's).
constexpr const char* kCycleSchemaText =
    "trainer CycleRecord, layout 1: the bytes of struct trainer::record::CycleRecord "
    "(rt/record/include/trainer/record/cycle_record.hpp), little-endian, no padding; "
    "byte offsets in docs/recording.md";

constexpr const char* kTelemetrySchemaText =
    "trainer telemetry frame: the bytes of one UDP datagram of the telemetry stream "
    "(rt/telemetry, wire format in docs/telemetry.md), little-endian, versioned by its header";

}  // namespace

core::Expected<void> RecordingWriter::open(const std::filesystem::path& path,
                                           const SessionInfo& session,
                                           mcap::Compression compression) {
  mcap::WriterOptions options;
  options.profile = kProfile;
  options.library = "trainer rt/record";
  options.compression = compression;
  if (auto opened = writer_.open(path, options); !opened) return opened;
  const std::string schema = kCycleSchemaText;
  if (auto added =
          writer_.add_schema(1, "trainer.CycleRecord", kCycleEncoding,
                             {reinterpret_cast<const std::uint8_t*>(schema.data()), schema.size()});
      !added)
    return added;
  if (auto added = writer_.add_channel(kCycleChannel, 1, kCycleTopic, kCycleEncoding,
                                       {{"layout", std::to_string(kCycleRecordLayout)},
                                        {"record_bytes", std::to_string(sizeof(CycleRecord))}});
      !added)
    return added;
  const std::string telemetry_schema = kTelemetrySchemaText;
  if (auto added = writer_.add_schema(
          2, "trainer.TelemetryFrame", kTelemetryEncoding,
          {reinterpret_cast<const std::uint8_t*>(telemetry_schema.data()), telemetry_schema.size()});
      !added)
    return added;
  if (auto added = writer_.add_channel(kTelemetryChannel, 2, kTelemetryTopic, kTelemetryEncoding, {});
      !added)
    return added;
  return writer_.add_metadata("session", session);
}

core::Expected<void> RecordingWriter::add(const CycleRecord& record) {
  ++records_;
  return writer_.add_message(kCycleChannel, static_cast<std::uint32_t>(record.cycle_index),
                             static_cast<std::uint64_t>(record.wake_ns),
                             static_cast<std::uint64_t>(record.wake_ns),
                             {reinterpret_cast<const std::uint8_t*>(&record), sizeof record});
}

core::Expected<void> RecordingWriter::add_telemetry(std::span<const std::byte> frame,
                                                    std::int64_t cycle_time_ns,
                                                    std::uint64_t sequence) {
  ++telemetry_frames_;
  const auto time = static_cast<std::uint64_t>(cycle_time_ns);
  return writer_.add_message(kTelemetryChannel, static_cast<std::uint32_t>(sequence), time, time,
                             {reinterpret_cast<const std::uint8_t*>(frame.data()), frame.size()});
}

core::Expected<void> RecordingWriter::close(std::uint64_t dropped_cycles) {
  if (auto flushed = writer_.flush_chunk(); !flushed) return flushed;
  if (auto added =
          writer_.add_metadata("session_end", {{"cycles_recorded", std::to_string(records_)},
                                               {"cycles_dropped", std::to_string(dropped_cycles)}});
      !added)
    return added;
  return writer_.close();
}

namespace {

class CycleVisitor final : public mcap::Visitor {
 public:
  CycleVisitor(RecordingScan& scan, const std::function<bool(const CycleRecord&)>& on_record,
               const std::function<bool(const TelemetryMessage&)>& on_telemetry)
      : scan_(scan), on_record_(on_record), on_telemetry_(on_telemetry) {}

  void on_metadata(const std::string& name, const SessionInfo& metadata) override {
    if (name == "session") {
      scan_.session = metadata;
      have_session_ = true;
    } else if (name == "session_end") {
      scan_.session_end = metadata;
    }
  }
  void on_channel(const mcap::Channel& channel) override {
    if (channel.id != kCycleChannel) return;
    const auto layout = channel.metadata.find("layout");
    if (channel.message_encoding != kCycleEncoding || layout == channel.metadata.end() ||
        layout->second != std::to_string(kCycleRecordLayout)) {
      error_ = "channel " + std::string(kCycleTopic) + " holds encoding '" +
               channel.message_encoding + "' layout '" +
               (layout == channel.metadata.end() ? std::string("?") : layout->second) +
               "'; this program reads " + kCycleEncoding + " layout " +
               std::to_string(kCycleRecordLayout);
    }
  }
  bool on_message(const mcap::Message& message) override {
    if (!error_.empty()) return false;
    if (message.channel == kTelemetryChannel && on_telemetry_) {
      ++scan_.telemetry_frames;
      return on_telemetry_(TelemetryMessage{message.log_time, message.sequence, message.data});
    }
    if (message.channel != kCycleChannel) return true;
    if (!have_session_) {
      error_ = "a cycle record comes before the session metadata";
      return false;
    }
    if (message.data.size() != sizeof(CycleRecord)) {
      error_ = "cycle record " + std::to_string(scan_.records) + " has " +
               std::to_string(message.data.size()) + " bytes, expected " +
               std::to_string(sizeof(CycleRecord));
      return false;
    }
    CycleRecord record;
    std::memcpy(&record, message.data.data(), sizeof record);
    ++scan_.records;
    return !on_record_ || on_record_(record);
  }
  const std::string& error() const { return error_; }

 private:
  RecordingScan& scan_;
  const std::function<bool(const CycleRecord&)>& on_record_;
  const std::function<bool(const TelemetryMessage&)>& on_telemetry_;
  bool have_session_ = false;
  std::string error_;
};

// A read-only private mapping of a whole file (an empty file maps to no bytes).
class MappedFile {
 public:
  static core::Expected<MappedFile> open(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return core::make_error(path.string() + ": cannot open: " + std::strerror(errno));
    struct stat info {};
    if (::fstat(fd, &info) != 0) {
      const int error = errno;
      ::close(fd);
      return core::make_error(path.string() + ": cannot stat: " + std::strerror(error));
    }
    MappedFile file;
    file.size_ = static_cast<std::size_t>(info.st_size);
    if (file.size_ > 0) {
      void* data = ::mmap(nullptr, file.size_, PROT_READ, MAP_PRIVATE, fd, 0);
      if (data == MAP_FAILED) {
        const int error = errno;
        ::close(fd);
        return core::make_error(path.string() + ": cannot map: " + std::strerror(error));
      }
      file.data_ = static_cast<const std::uint8_t*>(data);
      (void)::madvise(data, file.size_, MADV_SEQUENTIAL);
    }
    ::close(fd);
    return file;
  }
  MappedFile(MappedFile&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}
  MappedFile& operator=(MappedFile&&) = delete;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile() {
    if (data_ != nullptr) (void)::munmap(const_cast<std::uint8_t*>(data_), size_);
  }
  std::span<const std::uint8_t> bytes() const noexcept { return {data_, size_}; }

 private:
  MappedFile() = default;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace

core::Expected<RecordingScan> scan_recording(
    const std::filesystem::path& path, const std::function<bool(const CycleRecord&)>& on_record) {
  return scan_recording(path, on_record, {});
}

core::Expected<RecordingScan> scan_recording(
    const std::filesystem::path& path, const std::function<bool(const CycleRecord&)>& on_record,
    const std::function<bool(const TelemetryMessage&)>& on_telemetry) {
  // Mapped, not read: an hour at 10 kHz is ~2.4 GB; the scan touches each page once.
  auto mapped = MappedFile::open(path);
  if (!mapped) return std::move(mapped).error();
  RecordingScan scan;
  CycleVisitor visitor(scan, on_record, on_telemetry);
  auto scanned = mcap::scan(mapped->bytes(), visitor);
  if (!scanned) return core::make_error(path.string() + ": " + scanned.error().message);
  if (!visitor.error().empty()) return core::make_error(path.string() + ": " + visitor.error());
  scan.mcap = *scanned;
  if (scan.session.empty() && scan.records == 0 && scan.telemetry_frames == 0) {
    return core::make_error(
        path.string() + ": no session metadata" +
        (scan.mcap.damage.empty() ? std::string() : " (" + scan.mcap.damage + ")"));
  }
  return scan;
}

}  // namespace trainer::record
