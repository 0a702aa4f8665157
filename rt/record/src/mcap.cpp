#include "trainer/record/mcap.hpp"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <limits>

namespace trainer::record::mcap {
namespace {

constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Op : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// Little-endian appenders (the host is little-endian: x86-64 and the ARM appliances).
void put_u8(std::vector<std::uint8_t>& out, std::uint8_t v) {
  out.push_back(v);
}
template <class T>
void put_le(std::vector<std::uint8_t>& out, T v) {
  for (std::size_t k = 0; k < sizeof(T); ++k) {
    out.push_back(static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> (8 * k)));
  }
}
void put_u16(std::vector<std::uint8_t>& out, std::uint16_t v) {
  put_le(out, v);
}
void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  put_le(out, v);
}
void put_u64(std::vector<std::uint8_t>& out, std::uint64_t v) {
  put_le(out, v);
}
void put_bytes(std::vector<std::uint8_t>& out, std::span<const std::uint8_t> bytes) {
  out.insert(out.end(), bytes.begin(), bytes.end());
}
void put_string(std::vector<std::uint8_t>& out, const std::string& s) {
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  out.insert(out.end(), s.begin(), s.end());
}
void put_string_map(std::vector<std::uint8_t>& out, const std::map<std::string, std::string>& m) {
  std::vector<std::uint8_t> body;
  for (const auto& [key, value] : m) {
    put_string(body, key);
    put_string(body, value);
  }
  put_u32(out, static_cast<std::uint32_t>(body.size()));
  put_bytes(out, body);
}
// A record: opcode, content length, content.
void put_record(std::vector<std::uint8_t>& out, std::uint8_t op,
                const std::vector<std::uint8_t>& content) {
  put_u8(out, op);
  put_u64(out, content.size());
  put_bytes(out, content);
}

std::uint32_t crc32_of(std::span<const std::uint8_t> bytes) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const std::size_t n = std::min<std::size_t>(bytes.size() - done, 1U << 30);
    crc = ::crc32(crc, bytes.data() + done, static_cast<uInt>(n));
    done += n;
  }
  return static_cast<std::uint32_t>(crc);
}

// Bounds-checked little-endian reader over one record's content.
class Cursor {
 public:
  explicit Cursor(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  bool ok() const { return ok_; }
  std::size_t left() const { return bytes_.size() - at_; }
  template <class T>
  T le() {
    if (left() < sizeof(T)) {
      ok_ = false;
      at_ = bytes_.size();
      return T{};
    }
    std::uint64_t v = 0;
    for (std::size_t k = 0; k < sizeof(T); ++k)
      v |= static_cast<std::uint64_t>(bytes_[at_ + k]) << (8 * k);
    at_ += sizeof(T);
    return static_cast<T>(v);
  }
  std::span<const std::uint8_t> take(std::uint64_t n) {
    if (left() < n) {
      ok_ = false;
      at_ = bytes_.size();
      return {};
    }
    auto s = bytes_.subspan(at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
    return s;
  }
  std::string str() {
    const auto n = le<std::uint32_t>();
    const auto s = take(n);
    return std::string(s.begin(), s.end());
  }
  std::map<std::string, std::string> str_map() {
    const auto n = le<std::uint32_t>();
    Cursor inner(take(n));
    std::map<std::string, std::string> m;
    while (ok_ && inner.ok() && inner.left() > 0) {
      std::string key = inner.str();
      m[key] = inner.str();
    }
    if (!inner.ok()) ok_ = false;
    return m;
  }
  std::span<const std::uint8_t> rest() { return take(left()); }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t at_ = 0;
  bool ok_ = true;
};

}  // namespace

Writer::~Writer() {
  if (file_ != nullptr) std::fclose(file_);
}

core::Expected<void> Writer::write_bytes(std::span<const std::uint8_t> bytes) {
  if (file_ == nullptr) return core::make_error(path_.string() + ": not open");
  if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
    return core::make_error(path_.string() + ": write failed: " + std::strerror(errno));
  }
  offset_ += bytes.size();
  return {};
}

core::Expected<void> Writer::open(const std::filesystem::path& path, WriterOptions options) {
  path_ = path;
  options_ = std::move(options);
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr)
    return core::make_error(path.string() + ": cannot create: " + std::strerror(errno));
  std::vector<std::uint8_t> out(std::begin(kMagic), std::end(kMagic));
  std::vector<std::uint8_t> header;
  put_string(header, options_.profile);
  put_string(header, options_.library);
  put_record(out, kHeader, header);
  return write_bytes(out);
}

core::Expected<void> Writer::add_schema(std::uint16_t id, const std::string& name,
                                        const std::string& encoding,
                                        std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> content;
  put_u16(content, id);
  put_string(content, name);
  put_string(content, encoding);
  put_u32(content, static_cast<std::uint32_t>(data.size()));
  put_bytes(content, data);
  std::vector<std::uint8_t> record;
  put_record(record, kSchema, content);
  put_bytes(schema_records_, record);
  ++schema_count_;
  return write_bytes(record);
}

core::Expected<void> Writer::add_channel(std::uint16_t id, std::uint16_t schema_id,
                                         const std::string& topic,
                                         const std::string& message_encoding,
                                         const std::map<std::string, std::string>& metadata) {
  std::vector<std::uint8_t> content;
  put_u16(content, id);
  put_u16(content, schema_id);
  put_string(content, topic);
  put_string(content, message_encoding);
  put_string_map(content, metadata);
  std::vector<std::uint8_t> record;
  put_record(record, kChannel, content);
  put_bytes(channel_records_, record);
  ++channel_count_;
  channel_messages_[id] = 0;
  return write_bytes(record);
}

core::Expected<void> Writer::add_metadata(const std::string& name,
                                          const std::map<std::string, std::string>& metadata) {
  std::vector<std::uint8_t> content;
  put_string(content, name);
  put_string_map(content, metadata);
  std::vector<std::uint8_t> record;
  put_record(record, kMetadata, content);
  metadata_index_.emplace_back(offset_, record.size());
  metadata_names_.push_back(name);
  return write_bytes(record);
}

core::Expected<void> Writer::add_message(std::uint16_t channel, std::uint32_t sequence,
                                         std::uint64_t log_time, std::uint64_t publish_time,
                                         std::span<const std::uint8_t> data) {
  if (chunk_.empty()) {
    chunk_start_ = log_time;
    chunk_end_ = log_time;
  }
  chunk_start_ = std::min(chunk_start_, log_time);
  chunk_end_ = std::max(chunk_end_, log_time);
  chunk_messages_[channel].emplace_back(log_time, chunk_.size());
  put_u8(chunk_, kMessage);
  put_u64(chunk_, 2 + 4 + 8 + 8 + data.size());
  put_u16(chunk_, channel);
  put_u32(chunk_, sequence);
  put_u64(chunk_, log_time);
  put_u64(chunk_, publish_time);
  put_bytes(chunk_, data);
  if (message_count_ == 0) {
    message_start_ = log_time;
    message_end_ = log_time;
  }
  message_start_ = std::min(message_start_, log_time);
  message_end_ = std::max(message_end_, log_time);
  ++message_count_;
  ++channel_messages_[channel];
  if (chunk_.size() >= options_.chunk_bytes) return flush_chunk();
  return {};
}

core::Expected<void> Writer::flush_chunk() {
  if (chunk_.empty()) return {};
  std::vector<std::uint8_t> compressed;
  std::string compression;
  std::span<const std::uint8_t> payload = chunk_;
  if (options_.compression == Compression::zstd) {
    compressed.resize(ZSTD_compressBound(chunk_.size()));
    const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_.data(),
                                        chunk_.size(), options_.zstd_level);
    if (ZSTD_isError(n) != 0U)
      return core::make_error(path_.string() + ": zstd: " + ZSTD_getErrorName(n));
    compressed.resize(n);
    payload = compressed;
    compression = "zstd";
  }
  std::vector<std::uint8_t> content;
  put_u64(content, chunk_start_);
  put_u64(content, chunk_end_);
  put_u64(content, chunk_.size());
  put_u32(content, crc32_of(chunk_));
  put_string(content, compression);
  put_u64(content, payload.size());
  put_bytes(content, payload);
  std::vector<std::uint8_t> record;
  put_record(record, kChunk, content);
  ChunkIndexEntry index{chunk_start_, chunk_end_,     offset_,      record.size(), {}, 0,
                        compression,  payload.size(), chunk_.size()};
  // Message Index records follow the chunk, one per channel with messages in it.
  std::vector<std::uint8_t> indexes;
  for (const auto& [channel, entries] : chunk_messages_) {
    std::vector<std::uint8_t> body;
    put_u16(body, channel);
    put_u32(body, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, where] : entries) {
      put_u64(body, time);
      put_u64(body, where);
    }
    index.index_offsets[channel] = offset_ + record.size() + indexes.size();
    put_record(indexes, kMessageIndex, body);
  }
  index.index_length = indexes.size();
  if (auto w = write_bytes(record); !w) return w;
  if (auto w = write_bytes(indexes); !w) return w;
  if (std::fflush(file_) != 0)
    return core::make_error(path_.string() + ": flush failed: " + std::strerror(errno));
  chunk_indexes_.push_back(std::move(index));
  chunk_.clear();
  chunk_messages_.clear();
  return {};
}

core::Expected<void> Writer::close() {
  if (closed_) return {};
  if (auto flushed = flush_chunk(); !flushed) return flushed;
  std::vector<std::uint8_t> out;
  std::vector<std::uint8_t> data_end;
  put_u32(data_end, 0);  // data section CRC not computed (0 = none, as the spec allows)
  put_record(out, kDataEnd, data_end);
  const std::uint64_t summary_start = offset_ + out.size();
  struct Group {
    std::uint8_t op;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  const auto group = [&](std::uint8_t op, const std::vector<std::uint8_t>& records) {
    if (records.empty()) return;
    groups.push_back({op, offset_ + out.size(), records.size()});
    put_bytes(out, records);
  };
  group(kSchema, schema_records_);
  group(kChannel, channel_records_);
  std::vector<std::uint8_t> stats;
  {
    std::vector<std::uint8_t> c;
    put_u64(c, message_count_);
    put_u16(c, schema_count_);
    put_u32(c, channel_count_);
    put_u32(c, 0);  // attachments
    put_u32(c, static_cast<std::uint32_t>(metadata_index_.size()));
    put_u32(c, static_cast<std::uint32_t>(chunk_indexes_.size()));
    put_u64(c, message_start_);
    put_u64(c, message_end_);
    std::vector<std::uint8_t> counts;
    for (const auto& [channel, count] : channel_messages_) {
      put_u16(counts, channel);
      put_u64(counts, count);
    }
    put_u32(c, static_cast<std::uint32_t>(counts.size()));
    put_bytes(c, counts);
    put_record(stats, kStatistics, c);
  }
  group(kStatistics, stats);
  std::vector<std::uint8_t> chunk_index_records;
  for (const ChunkIndexEntry& e : chunk_indexes_) {
    std::vector<std::uint8_t> c;
    put_u64(c, e.start_time);
    put_u64(c, e.end_time);
    put_u64(c, e.chunk_offset);
    put_u64(c, e.chunk_length);
    std::vector<std::uint8_t> offsets;
    for (const auto& [channel, where] : e.index_offsets) {
      put_u16(offsets, channel);
      put_u64(offsets, where);
    }
    put_u32(c, static_cast<std::uint32_t>(offsets.size()));
    put_bytes(c, offsets);
    put_u64(c, e.index_length);
    put_string(c, e.compression);
    put_u64(c, e.compressed_size);
    put_u64(c, e.uncompressed_size);
    put_record(chunk_index_records, kChunkIndex, c);
  }
  group(kChunkIndex, chunk_index_records);
  std::vector<std::uint8_t> metadata_index_records;
  for (std::size_t k = 0; k < metadata_index_.size(); ++k) {
    std::vector<std::uint8_t> c;
    put_u64(c, metadata_index_[k].first);
    put_u64(c, metadata_index_[k].second);
    put_string(c, metadata_names_[k]);
    put_record(metadata_index_records, kMetadataIndex, c);
  }
  group(kMetadataIndex, metadata_index_records);
  const std::uint64_t summary_offset_start = offset_ + out.size();
  for (const Group& g : groups) {
    std::vector<std::uint8_t> c;
    put_u8(c, g.op);
    put_u64(c, g.start);
    put_u64(c, g.length);
    put_record(out, kSummaryOffset, c);
  }
  std::vector<std::uint8_t> footer;
  put_u64(footer, summary_start);
  put_u64(footer, summary_offset_start);
  put_u32(footer, 0);  // summary CRC not computed
  put_record(out, kFooter, footer);
  out.insert(out.end(), std::begin(kMagic), std::end(kMagic));
  if (auto w = write_bytes(out); !w) return w;
  closed_ = true;
  const bool closed_ok = std::fclose(file_) == 0;
  file_ = nullptr;
  if (!closed_ok)
    return core::make_error(path_.string() + ": close failed: " + std::strerror(errno));
  return {};
}

core::Expected<std::vector<std::uint8_t>> read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return core::make_error(path.string() + ": cannot open");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad()) return core::make_error(path.string() + ": read error");
  return bytes;
}

namespace {

// Scans the records of `bytes` (the data section, or a chunk's records at `base` in the
// file); messages go to the visitor. Returns false with `damage` set at the first bad record.
struct Scanner {
  Visitor& visitor;
  ScanResult& result;
  bool data_end = false;

  bool fail(std::uint64_t offset, const std::string& why) {
    result.damage = "byte " + std::to_string(offset) + ": " + why;
    result.damage_offset = offset;
    return false;
  }

  // One record's content; false on damage or stop.
  bool record(std::uint8_t op, std::span<const std::uint8_t> content, std::uint64_t at,
              bool in_chunk) {
    Cursor c(content);
    switch (op) {
      case kChannel: {
        Channel ch;
        ch.id = c.le<std::uint16_t>();
        ch.schema_id = c.le<std::uint16_t>();
        ch.topic = c.str();
        ch.message_encoding = c.str();
        ch.metadata = c.str_map();
        if (!c.ok()) return fail(at, "malformed Channel record");
        visitor.on_channel(ch);
        return true;
      }
      case kMetadata: {
        std::string name = c.str();
        auto m = c.str_map();
        if (!c.ok()) return fail(at, "malformed Metadata record");
        visitor.on_metadata(name, m);
        return true;
      }
      case kMessage: {
        Message m;
        m.channel = c.le<std::uint16_t>();
        m.sequence = c.le<std::uint32_t>();
        m.log_time = c.le<std::uint64_t>();
        m.publish_time = c.le<std::uint64_t>();
        m.data = c.rest();
        if (!c.ok()) return fail(at, "malformed Message record");
        ++result.messages;
        if (!visitor.on_message(m)) {
          result.stopped = true;
          return false;
        }
        return true;
      }
      case kChunk: {
        if (in_chunk) return fail(at, "a Chunk inside a chunk");
        c.le<std::uint64_t>();
        c.le<std::uint64_t>();
        const auto uncompressed_size = c.le<std::uint64_t>();
        const auto crc = c.le<std::uint32_t>();
        const std::string compression = c.str();
        const auto size = c.le<std::uint64_t>();
        const auto payload = c.take(size);
        if (!c.ok()) return fail(at, "malformed Chunk record");
        std::vector<std::uint8_t> plain;
        std::span<const std::uint8_t> records = payload;
        if (compression == "zstd") {
          if (uncompressed_size > (1ULL << 32)) return fail(at, "chunk claims an absurd size");
          plain.resize(static_cast<std::size_t>(uncompressed_size));
          const std::size_t n =
              ZSTD_decompress(plain.data(), plain.size(), payload.data(), payload.size());
          if (ZSTD_isError(n) != 0U || n != plain.size())
            return fail(at, "chunk does not decompress (zstd) to its stated size");
          records = plain;
        } else if (!compression.empty()) {
          return fail(at, "chunk compression '" + compression + "' not supported");
        } else if (payload.size() != uncompressed_size) {
          return fail(at, "chunk size mismatch");
        }
        if (crc != 0 && crc32_of(records) != crc)
          return fail(at, "chunk CRC-32 mismatch (the chunk is corrupt)");
        ++result.chunks;
        return records_in(records, at, true);
      }
      case kDataEnd:
        if (in_chunk) return fail(at, "Data End inside a chunk");
        data_end = true;
        return true;
      default:  // Header, Schema, Message Index, Attachments...: nothing the recording needs
        return true;
    }
  }

  bool records_in(std::span<const std::uint8_t> bytes, std::uint64_t base, bool in_chunk) {
    std::size_t at = 0;
    while (at < bytes.size() && !data_end) {
      if (bytes.size() - at < 9)
        return fail(base + at, in_chunk ? "chunk ends inside a record header"
                                        : "file ends inside a record header (truncated)");
      const std::uint8_t op = bytes[at];
      std::uint64_t length = 0;
      for (int k = 0; k < 8; ++k)
        length |= static_cast<std::uint64_t>(bytes[at + 1 + static_cast<std::size_t>(k)])
                  << (8 * k);
      if (length > bytes.size() - at - 9) {
        return fail(base + at, std::string(in_chunk ? "chunk" : "file") +
                                   " ends inside a record (opcode " + std::to_string(op) + ", " +
                                   std::to_string(length) + " bytes; truncated)");
      }
      if (!record(op, bytes.subspan(at + 9, static_cast<std::size_t>(length)),
                  in_chunk ? base : base + at, in_chunk))
        return false;
      at += 9 + static_cast<std::size_t>(length);
    }
    return true;
  }
};

}  // namespace

core::Expected<ScanResult> scan(std::span<const std::uint8_t> file, Visitor& visitor) {
  ScanResult result;
  if (file.size() < 8 || std::memcmp(file.data(), kMagic, 8) != 0)
    return core::make_error("not an MCAP file (no MCAP magic at byte 0)");
  if (file.size() < 17 || file[8] != kHeader)
    return core::make_error("not an MCAP file (no Header record at byte 8)");
  Scanner scanner{visitor, result};
  const bool whole = scanner.records_in(file.subspan(8), 8, false);
  if (whole && !scanner.data_end && !result.stopped) {
    result.damage = "byte " + std::to_string(file.size()) +
                    ": the file ends without Data End (truncated: the session did not close it)";
    result.damage_offset = file.size();
  }
  if (whole && scanner.data_end) {
    result.complete =
        file.size() >= 16 && std::memcmp(file.data() + file.size() - 8, kMagic, 8) == 0;
    if (!result.complete) {
      result.damage = "byte " + std::to_string(file.size()) +
                      ": the summary or footer after Data End is cut off";
      result.damage_offset = file.size();
    }
  }
  return result;
}

}  // namespace trainer::record::mcap
