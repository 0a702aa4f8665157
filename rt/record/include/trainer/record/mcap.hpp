// A small MCAP writer and reader (https://mcap.dev/spec, major version 0), enough for the
// session recording: Header, Schema, Channel and Metadata records in the data section, Messages
// in chunks (zstd or uncompressed, each with its CRC-32), a Message Index per channel after
// each chunk, Data End, and a summary section (Schemas, Channels, Statistics, Chunk Indexes,
// Metadata Indexes, Summary Offsets) with the Footer when the file is closed cleanly. No MCAP
// C++ library is packaged in Debian 12; tests/rt/record/mcap_node_check.mjs opens the files with
// the reference TypeScript reader (@mcap/core). Layout and choices: docs/recording.md.
//
// Non-RT only (heap, file I/O, exceptions from the standard library are caught and returned).
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "trainer/core/expected.hpp"

namespace trainer::record::mcap {

enum class Compression : std::uint8_t { none, zstd };

struct WriterOptions {
  std::string profile;                 // Header.profile ("" = none)
  std::string library;                 // Header.library
  std::size_t chunk_bytes = 1U << 19;  // uncompressed chunk payload before it is written
  Compression compression = Compression::zstd;
  int zstd_level = 3;
};

class Writer {
 public:
  Writer() = default;
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  ~Writer();

  // Creates (truncates) `path` and writes the magic and the Header.
  core::Expected<void> open(const std::filesystem::path& path, WriterOptions options);
  // Data-section records, written at once (before any message that uses them).
  core::Expected<void> add_schema(std::uint16_t id, const std::string& name,
                                  const std::string& encoding, std::span<const std::uint8_t> data);
  core::Expected<void> add_channel(std::uint16_t id, std::uint16_t schema_id,
                                   const std::string& topic, const std::string& message_encoding,
                                   const std::map<std::string, std::string>& metadata);
  core::Expected<void> add_metadata(const std::string& name,
                                    const std::map<std::string, std::string>& metadata);
  // Buffered into the current chunk; a full chunk is compressed and written.
  core::Expected<void> add_message(std::uint16_t channel, std::uint32_t sequence,
                                   std::uint64_t log_time, std::uint64_t publish_time,
                                   std::span<const std::uint8_t> data);
  // Writes the open chunk now (the file on disk then holds every message added so far).
  core::Expected<void> flush_chunk();
  // The last chunk, Data End, the summary section, the Footer and the closing magic.
  core::Expected<void> close();

  std::uint64_t bytes_written() const noexcept { return offset_; }
  std::uint64_t message_count() const noexcept { return message_count_; }

 private:
  struct ChunkIndexEntry {
    std::uint64_t start_time, end_time, chunk_offset, chunk_length;
    std::map<std::uint16_t, std::uint64_t> index_offsets;
    std::uint64_t index_length;
    std::string compression;
    std::uint64_t compressed_size, uncompressed_size;
  };
  core::Expected<void> write_bytes(std::span<const std::uint8_t> bytes);

  std::FILE* file_ = nullptr;
  std::filesystem::path path_;
  WriterOptions options_;
  std::uint64_t offset_ = 0;
  std::vector<std::uint8_t> schema_records_, channel_records_;           // repeated in the summary
  std::vector<std::pair<std::uint64_t, std::uint64_t>> metadata_index_;  // offset, length
  std::vector<std::string> metadata_names_;
  std::vector<ChunkIndexEntry> chunk_indexes_;
  // The open chunk.
  std::vector<std::uint8_t> chunk_;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_messages_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  // Statistics.
  std::uint64_t message_count_ = 0, message_start_ = 0, message_end_ = 0;
  std::uint16_t schema_count_ = 0;
  std::uint32_t channel_count_ = 0;
  std::map<std::uint16_t, std::uint64_t> channel_messages_;
  bool closed_ = false;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  std::map<std::string, std::string> metadata;
};

struct Message {
  std::uint16_t channel = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0;
  std::uint64_t publish_time = 0;
  std::span<const std::uint8_t> data;  // valid during the callback only
};

class Visitor {
 public:
  virtual ~Visitor() = default;
  virtual void on_channel(const Channel& channel) { (void)channel; }
  virtual void on_metadata(const std::string& name,
                           const std::map<std::string, std::string>& metadata) {
    (void)name;
    (void)metadata;
  }
  // false stops the scan (ScanResult.stopped).
  virtual bool on_message(const Message& message) = 0;
};

struct ScanResult {
  bool complete = false;  // Data End, Footer and closing magic found
  bool stopped = false;   // the visitor stopped the scan
  // Empty, or where and why the scan stopped short ("byte 1234: chunk CRC mismatch ...").
  std::string damage;
  std::uint64_t damage_offset = 0;
  std::uint64_t messages = 0;  // delivered to the visitor
  std::uint64_t chunks = 0;
};

// Reads the data section in order, up to the first damage: a file that is not MCAP at all
// (bad magic or Header) is an error; a truncated or corrupt one delivers every message before
// the damage and says where it is in ScanResult.damage.
core::Expected<ScanResult> scan(std::span<const std::uint8_t> file, Visitor& visitor);
core::Expected<std::vector<std::uint8_t>> read_file(const std::filesystem::path& path);

}  // namespace trainer::record::mcap
