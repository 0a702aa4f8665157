// The recording's building blocks (docs/recording.md): the SPSC ring drops and counts when
// full; the MCAP writer's files read back record for record, compressed or not; a truncated
// file or a flipped byte is read up to the damage with the byte offset named; a file that is
// not MCAP is refused; the output comparison names the first differing field.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "trainer/core/spsc_ring.hpp"
#include "trainer/record/cycle_record.hpp"
#include "trainer/record/mcap.hpp"
#include "trainer/record/recording.hpp"

namespace trainer::record {
namespace {

namespace fs = std::filesystem;

fs::path temp_file(const std::string& name) {
  return fs::temp_directory_path() /
         ("trainer_record_" + std::to_string(::getpid()) + "_" + name + ".mcap");
}

CycleRecord record_for(std::uint64_t cycle) {
  CycleRecord r{};
  r.cycle_index = cycle;
  r.wake_ns = static_cast<std::int64_t>(1'000'000 * (cycle + 1));
  r.deadline_ns = r.wake_ns;
  r.dt_s = 1e-3;
  r.channel_count = 10;
  for (std::size_t c = 0; c < 10; ++c) {
    r.encoders[c].counts = static_cast<std::int64_t>(cycle * 3 + c);
    r.encoders[c].position = static_cast<float>(cycle) * 1e-4F + static_cast<float>(c);
    r.commands[c].effort = static_cast<float>(c) * 0.01F;
  }
  r.state_hash = cycle * 0x9E3779B97F4A7C15ULL;
  return r;
}

void write_session(const fs::path& path, std::uint64_t cycles, mcap::Compression compression) {
  RecordingWriter writer;
  ASSERT_TRUE(writer.open(path, {{"scene_name", "unit"}, {"scene_text", "x"}}, compression));
  for (std::uint64_t k = 0; k < cycles; ++k) {
    ASSERT_TRUE(writer.add(record_for(k)));
    if (k % 500 == 499) {
      ASSERT_TRUE(writer.flush());
    }
  }
  ASSERT_TRUE(writer.close(7));
}

std::vector<CycleRecord> read_all(const fs::path& path, RecordingScan* scan_out = nullptr) {
  std::vector<CycleRecord> records;
  auto scan = scan_recording(path, [&](const CycleRecord& r) {
    records.push_back(r);
    return true;
  });
  EXPECT_TRUE(scan) << (scan ? "" : scan.error().message);
  if (scan && scan_out != nullptr) *scan_out = *scan;
  return records;
}

TEST(SpscRing, FullRingRefusesAndCounts) {
  auto ring = std::make_unique<core::SpscRing<CycleRecord, 8>>();
  for (std::uint64_t k = 0; k < 20; ++k) ring->push(record_for(k));
  EXPECT_EQ(ring->dropped(), 12U);
  CycleRecord out{};
  for (std::uint64_t k = 0; k < 8; ++k) {
    ASSERT_TRUE(ring->pop(out));
    EXPECT_EQ(out.cycle_index, k);  // the oldest kept, the newest dropped
  }
  EXPECT_FALSE(ring->pop(out));
}

TEST(Recording, RoundTripCompressedAndPlain) {
  for (const auto compression : {mcap::Compression::zstd, mcap::Compression::none}) {
    const fs::path path = temp_file(compression == mcap::Compression::zstd ? "zstd" : "plain");
    write_session(path, 2000, compression);
    RecordingScan scan;
    const auto records = read_all(path, &scan);
    ASSERT_EQ(records.size(), 2000U);
    for (std::uint64_t k = 0; k < records.size(); ++k) {
      const CycleRecord expected = record_for(k);
      ASSERT_EQ(std::memcmp(&records[k], &expected, sizeof expected), 0) << "record " << k;
    }
    EXPECT_TRUE(scan.mcap.complete);
    EXPECT_TRUE(scan.mcap.damage.empty()) << scan.mcap.damage;
    EXPECT_EQ(scan.session.at("scene_name"), "unit");
    ASSERT_TRUE(scan.session_end.has_value());
    EXPECT_EQ(scan.session_end->at("cycles_recorded"), "2000");
    EXPECT_EQ(scan.session_end->at("cycles_dropped"), "7");
    if (compression == mcap::Compression::zstd) {
      EXPECT_LT(fs::file_size(path), 2000 * sizeof(CycleRecord) / 4);  // mostly zero channels
    }
    fs::remove(path);
  }
}

TEST(Recording, TruncatedFileIsReadUpToTheDamage) {
  const fs::path path = temp_file("whole");
  write_session(path, 2000, mcap::Compression::zstd);
  const auto bytes = *mcap::read_file(path);
  const fs::path cut_path = temp_file("cut");
  const auto write_cut = [&](std::size_t cut) {
    std::ofstream out(cut_path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(cut));
  };
  // Cut inside the header: refused, saying where.
  write_cut(40);
  auto refused = scan_recording(cut_path, [](const CycleRecord&) { return true; });
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("no session metadata (byte 8: file ends inside a record"),
            std::string::npos)
      << refused.error().message;
  // Cut at many places after the session metadata (it ends before byte 1000: the header, two
  // schemas and channels, the metadata): every cut reads a prefix of the records and
  // names a byte offset.
  std::size_t previous = 0;
  for (std::size_t cut = 1000; cut < bytes.size(); cut += bytes.size() / 37) {
    write_cut(cut);
    RecordingScan scan;
    const auto records = read_all(cut_path, &scan);
    EXPECT_FALSE(scan.mcap.complete);
    EXPECT_NE(scan.mcap.damage.find("byte "), std::string::npos) << scan.mcap.damage;
    EXPECT_LE(scan.mcap.damage_offset, cut);
    EXPECT_GE(records.size(), previous);
    previous = records.size();
    for (std::uint64_t k = 0; k < records.size(); ++k) ASSERT_EQ(records[k].cycle_index, k);
  }
  fs::remove(cut_path);
  EXPECT_GE(previous, 1000U);  // the flushed chunks before the last cut are all there
  fs::remove(path);
}

TEST(Recording, FlippedByteStopsAtTheCorruptChunk) {
  const fs::path path = temp_file("flip");
  write_session(path, 2000, mcap::Compression::none);  // plain: the CRC must catch it
  auto bytes = *mcap::read_file(path);
  bytes[bytes.size() / 2] ^= 0x40;
  {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size()));
  }
  RecordingScan scan;
  const auto records = read_all(path, &scan);
  EXPECT_LT(records.size(), 2000U);
  EXPECT_NE(scan.mcap.damage.find("CRC-32 mismatch"), std::string::npos) << scan.mcap.damage;
  for (std::uint64_t k = 0; k < records.size(); ++k) {
    const CycleRecord expected = record_for(k);
    ASSERT_EQ(std::memcmp(&records[k], &expected, sizeof expected), 0);
  }
  fs::remove(path);
}

TEST(Recording, NotMcapIsRefused) {
  const fs::path path = temp_file("text");
  {
    std::ofstream out(path);
    out << "[scene]\nname = \"not a recording\"\n";
  }
  auto scan = scan_recording(path, [](const CycleRecord&) { return true; });
  ASSERT_FALSE(scan);
  EXPECT_NE(scan.error().message.find("not an MCAP file"), std::string::npos);
  EXPECT_NE(scan.error().message.find(path.string()), std::string::npos);
  fs::remove(path);
}

TEST(CycleRecordCompare, NamesTheFirstDifferingOutput) {
  const CycleRecord a = record_for(5);
  CycleRecord b = a;
  EXPECT_EQ(first_output_difference(a, b), "");
  b.encoders[2].position += 1.0F;  // an input: not compared
  EXPECT_EQ(first_output_difference(a, b), "");
  b.commands[3].effort = std::nextafter(a.commands[3].effort, 1.0F);
  const std::string text = first_output_difference(a, b);
  EXPECT_NE(text.find("command[channel 3].effort: recorded 0.0299999993"), std::string::npos)
      << text;
  b = a;
  b.state_hash ^= 1;
  EXPECT_NE(first_output_difference(a, b).find("state_hash"), std::string::npos);
}

}  // namespace
}  // namespace trainer::record
