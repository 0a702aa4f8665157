// The telemetry wire format: a frame with every section survives encode → decode bit for bit;
// the byte layout is the one docs/telemetry.md documents (checked at fixed offsets); and
// decode refuses — with its reason and offset — every truncation, every bit flip, random
// bytes, and malformed frames that carry a correct CRC (bad counts, lengths, indices, values).
#include "trainer/telemetry/wire_format.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "trainer/core/alloc_counter.hpp"

namespace trainer::telemetry {
namespace {

using Bytes = std::vector<std::byte>;

// A cbd-like frame: a 40-mode duct with static correction and loads, a liver-like tensor
// model, an 11-particle catheter, two instruments, three contacts.
std::unique_ptr<Frame> sample_frame() {
  auto frame = std::make_unique<Frame>();
  Frame& f = *frame;
  f.stream_id = 0xA1B2C3D4U;
  f.sequence = 123456789012ULL;
  f.cycle = 98765;
  f.cycle_time_ns = 5'000'000'123;
  f.send_time_ns = 5'000'400'000;
  f.send_wall_ns = 1'795'000'000'000'000'000;
  f.latched_faults = 0x24;
  f.flags = kFlagContactsTruncated;
  f.model_count = 3;
  ModelState& duct = f.models[0];
  duct.kind = ModelKind::modal;
  duct.scene_index = 0;
  duct.flags = kModalStaticCorrection;
  duct.image_checksum = 0x0123456789ABCDEFULL;
  duct.mode_count = 40;
  for (std::size_t k = 0; k < 40; ++k) duct.modal_coordinates[k] = 1e-4F * static_cast<float>(k) - 1e-3F;
  duct.load_count = 5;
  for (std::uint32_t k = 0; k < 5; ++k) duct.loads[k] = {100 + 7 * k, {0.1F * static_cast<float>(k), -0.2F, 0.3F}};
  ModelState& liver = f.models[1];
  liver.kind = ModelKind::tensor;
  liver.scene_index = 1;
  liver.image_checksum = 0xFEDCBA9876543210ULL;
  liver.contact_count = 3;
  for (std::uint32_t k = 0; k < 3; ++k) liver.contacts[k] = {1900 + k, {0.0F, 0.001F, -0.002F * static_cast<float>(k)}};
  ModelState& catheter = f.models[2];
  catheter.kind = ModelKind::catheter;
  catheter.scene_index = 3;
  catheter.image_checksum = 42;
  catheter.particle_count = 11;
  for (std::size_t k = 0; k < 11; ++k) catheter.particles_m[k] = {-0.18F + 0.015F * static_cast<float>(k), 0.0F, -0.1F};
  f.instrument_count = 2;
  for (std::size_t i = 0; i < 2; ++i) {
    InstrumentState& s = f.instruments[i];
    const float side = i == 0 ? -1.0F : 1.0F;
    s.flags = i == 0 ? (kInstrumentGrasping | kInstrumentCatheterContact) : kInstrumentWallContact;
    s.grip_rad = 0.3F * static_cast<float>(i);
    s.tip_m = {0.05F * side, 0.0F, -0.1F};
    s.hinge_m = {0.05F * side, 0.0F, -0.085F};
    s.shaft_start_m = {0.05F * side, 0.0F, 0.275F};
    s.opening_direction = {0.0F, 1.0F, 0.0F};
    s.force_n = {0.5F, -0.25F, 1.0F};
  }
  f.contact_count = 3;
  f.contacts[0] = {0, kNoModel, ContactKind::jaw0, {0.01F, 0.02F, 0.03F}, {1.0F, 2.0F, 3.0F}};
  f.contacts[1] = {1, 0, ContactKind::shaft, {-0.01F, 0.0F, -0.09F}, {0.0F, 0.0F, -0.7F}};
  f.contacts[2] = {1, 1, ContactKind::tip, {0.0F, 0.0F, 0.0F}, {0.1F, 0.0F, 0.0F}};
  return frame;
}

Bytes encode_to_bytes(const Frame& f) {
  Bytes out(encoded_size(f));
  const EncodeResult r = encode(f, out);
  EXPECT_TRUE(r.ok()) << r.error;
  out.resize(r.bytes);
  return out;
}

std::uint32_t read_u32(const Bytes& b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v |= std::to_integer<std::uint32_t>(b[at + i]) << (8 * i);
  return v;
}
void write_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  if (b.size() < at + 4) return;  // (also tells GCC's null-dereference analysis the size)
  for (std::size_t i = 0; i < 4; ++i) b[at + i] = std::byte(static_cast<std::uint8_t>(v >> (8 * i)));
}
void write_u16(Bytes& b, std::size_t at, std::uint16_t v) {
  if (b.size() < at + 2) return;
  b[at] = std::byte(static_cast<std::uint8_t>(v));
  b[at + 1] = std::byte(static_cast<std::uint8_t>(v >> 8));
}
// After a deliberate corruption: a correct length and CRC, so decode must find the real fault.
void fix_length_and_crc(Bytes& b) {
  write_u16(b, 6, static_cast<std::uint16_t>(b.size()));
  write_u32(b, 8, 0);
  write_u32(b, 8, crc32(b));
}

DecodeResult decode_bytes(const Bytes& b, Frame& out) { return decode(b, out); }

void set_u8(Bytes& b, std::size_t at, std::uint8_t v) { b[at] = std::byte{v}; }

void expect_same(const Frame& a, const Frame& b) {
  EXPECT_EQ(a.stream_id, b.stream_id);
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.cycle, b.cycle);
  EXPECT_EQ(a.cycle_time_ns, b.cycle_time_ns);
  EXPECT_EQ(a.send_time_ns, b.send_time_ns);
  EXPECT_EQ(a.send_wall_ns, b.send_wall_ns);
  EXPECT_EQ(a.latched_faults, b.latched_faults);
  EXPECT_EQ(a.flags, b.flags);
  ASSERT_EQ(a.model_count, b.model_count);
  for (std::size_t i = 0; i < a.model_count; ++i) {
    const ModelState& x = a.models[i];
    const ModelState& y = b.models[i];
    EXPECT_EQ(x.kind, y.kind);
    EXPECT_EQ(x.scene_index, y.scene_index);
    EXPECT_EQ(x.flags, y.flags);
    EXPECT_EQ(x.image_checksum, y.image_checksum);
    ASSERT_EQ(x.mode_count, y.mode_count);
    for (std::size_t k = 0; k < x.mode_count; ++k) EXPECT_EQ(x.modal_coordinates[k], y.modal_coordinates[k]);
    ASSERT_EQ(x.load_count, y.load_count);
    for (std::size_t k = 0; k < x.load_count; ++k) {
      EXPECT_EQ(x.loads[k].node, y.loads[k].node);
      EXPECT_EQ(x.loads[k].force_n, y.loads[k].force_n);
    }
    ASSERT_EQ(x.contact_count, y.contact_count);
    for (std::size_t k = 0; k < x.contact_count; ++k) {
      EXPECT_EQ(x.contacts[k].node, y.contacts[k].node);
      EXPECT_EQ(x.contacts[k].displacement_m, y.contacts[k].displacement_m);
    }
    ASSERT_EQ(x.particle_count, y.particle_count);
    for (std::size_t k = 0; k < x.particle_count; ++k) EXPECT_EQ(x.particles_m[k], y.particles_m[k]);
  }
  ASSERT_EQ(a.instrument_count, b.instrument_count);
  for (std::size_t i = 0; i < a.instrument_count; ++i) {
    const InstrumentState& x = a.instruments[i];
    const InstrumentState& y = b.instruments[i];
    EXPECT_EQ(x.flags, y.flags);
    EXPECT_EQ(x.grip_rad, y.grip_rad);
    EXPECT_EQ(x.tip_m, y.tip_m);
    EXPECT_EQ(x.hinge_m, y.hinge_m);
    EXPECT_EQ(x.shaft_start_m, y.shaft_start_m);
    EXPECT_EQ(x.opening_direction, y.opening_direction);
    EXPECT_EQ(x.force_n, y.force_n);
  }
  ASSERT_EQ(a.contact_count, b.contact_count);
  for (std::size_t i = 0; i < a.contact_count; ++i) {
    EXPECT_EQ(a.contacts[i].instrument, b.contacts[i].instrument);
    EXPECT_EQ(a.contacts[i].model, b.contacts[i].model);
    EXPECT_EQ(a.contacts[i].kind, b.contacts[i].kind);
    EXPECT_EQ(a.contacts[i].point_m, b.contacts[i].point_m);
    EXPECT_EQ(a.contacts[i].force_n, b.contacts[i].force_n);
  }
  ASSERT_EQ(a.has_metrics, b.has_metrics);
  if (a.has_metrics) {
    const SessionMetrics& x = a.metrics;
    const SessionMetrics& y = b.metrics;
    EXPECT_EQ(x.flags, y.flags);
    EXPECT_EQ(x.session_time_s, y.session_time_s);
    EXPECT_EQ(x.task_time_s, y.task_time_s);
    EXPECT_EQ(x.time_above_safe_s, y.time_above_safe_s);
    EXPECT_EQ(x.damage_impulse_n_s, y.damage_impulse_n_s);
    EXPECT_EQ(x.insertion_depth_m, y.insertion_depth_m);
    EXPECT_EQ(x.time_to_target_s, y.time_to_target_s);
    ASSERT_EQ(x.instrument_count, y.instrument_count);
    for (std::size_t i = 0; i < x.instrument_count; ++i) {
      const InstrumentMetrics& p = x.instruments[i];
      const InstrumentMetrics& q = y.instruments[i];
      EXPECT_EQ(p.path_length_m, q.path_length_m);
      EXPECT_EQ(p.idle_time_s, q.idle_time_s);
      EXPECT_EQ(p.peak_force_n, q.peak_force_n);
      EXPECT_EQ(p.mean_contact_force_n, q.mean_contact_force_n);
      EXPECT_EQ(p.time_above_safe_s, q.time_above_safe_s);
      EXPECT_EQ(p.movements, q.movements);
      EXPECT_EQ(p.grasps, q.grasps);
      EXPECT_EQ(p.slips, q.slips);
    }
  }
}

// The sample frame with the session metrics section (since 1.1).
std::unique_ptr<Frame> sample_frame_with_metrics() {
  auto frame = sample_frame();
  frame->has_metrics = true;
  SessionMetrics& m = frame->metrics;
  m.flags = kMetricsTaskStarted | kMetricsInsertionGoal | kMetricsTargetReached;
  m.session_time_s = 6.5F;
  m.task_time_s = 6.25F;
  m.time_above_safe_s = 0.027F;
  m.damage_impulse_n_s = 0.0F;
  m.insertion_depth_m = 0.0119F;
  m.time_to_target_s = 6.095F;
  m.instrument_count = 2;
  m.instruments[0] = {0.075F, 3.49F, 0.44F, 0.43F, 0.0F, 2, 1, 0};
  m.instruments[1] = {0.076F, 3.64F, 1.52F, 0.23F, 0.027F, 2, 0, 0};
  return frame;
}

TEST(TelemetryWireFormat, RoundTripKeepsEveryField) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  auto decoded = std::make_unique<Frame>();
  const DecodeResult r = decode_bytes(bytes, *decoded);
  ASSERT_TRUE(r.ok()) << to_string(r.error) << " at " << r.offset << ": " << r.detail;
  expect_same(*frame, *decoded);
}

// The sizes docs/telemetry.md gives: header 64, section header 4, modal 13 + 4r + 14L,
// tensor 10 + 14c, catheter 10 + 12n, instrument 65, contacts 1 + 27k.
TEST(TelemetryWireFormat, SizeIsTheDocumentedSum) {
  const auto frame = sample_frame();
  const std::size_t expected = 64 + (4 + 13 + 4 * 40 + 14 * 5) + (4 + 10 + 14 * 3) +
                               (4 + 10 + 12 * 11) + 2 * (4 + 65) + (4 + 1 + 27 * 3);
  EXPECT_EQ(encoded_size(*frame), expected);
  EXPECT_EQ(encode_to_bytes(*frame).size(), expected);
}

// 1.1: the metrics section, 4 + 26 + 26 n bytes, round-trips and its malformations are refused.
TEST(TelemetryWireFormat, TheMetricsSectionRoundTripsAtItsDocumentedSize) {
  const auto frame = sample_frame_with_metrics();
  const Bytes bytes = encode_to_bytes(*frame);
  EXPECT_EQ(bytes.size(), encoded_size(*sample_frame()) + 4 + 26 + 26 * 2);
  auto decoded = std::make_unique<Frame>();
  const DecodeResult r = decode_bytes(bytes, *decoded);
  ASSERT_TRUE(r.ok()) << to_string(r.error) << " at " << r.offset << ": " << r.detail;
  expect_same(*frame, *decoded);
  const std::size_t at = encoded_size(*sample_frame());  // the metrics section header
  ASSERT_EQ(std::to_integer<int>(bytes[at]), 18);
  struct Case {
    const char* name;
    DecodeError expected;
    std::size_t offset;
    std::uint32_t value;
    int width;  // bytes written at `offset`
  };
  const Case cases[] = {
      {"unknown metrics flag", DecodeError::bad_value, at + 4, 0x80, 1},
      {"metrics instrument count beyond capacity", DecodeError::capacity_exceeded, at + 4 + 25, 5, 1},
      {"metrics instrument count beyond the body", DecodeError::bad_section, at + 4 + 25, 3, 1},
      {"NaN session time", DecodeError::non_finite, at + 4 + 1, 0x7FC00000U, 4},
      {"metrics index not 0", DecodeError::bad_index, at + 1, 1, 1},
  };
  for (const Case& c : cases) {
    Bytes b = bytes;
    if (c.width == 1) set_u8(b, c.offset, static_cast<std::uint8_t>(c.value));
    else write_u32(b, c.offset, c.value);
    fix_length_and_crc(b);
    const DecodeResult bad = decode_bytes(b, *decoded);
    EXPECT_EQ(bad.error, c.expected) << c.name << ": got " << to_string(bad.error) << " ("
                                     << bad.detail << ") at " << bad.offset;
  }
  // Metrics naming more instruments than the frame carries.
  auto more = sample_frame_with_metrics();
  more->metrics.instrument_count = 3;
  Bytes b = encode_to_bytes(*more);
  EXPECT_EQ(decode_bytes(b, *decoded).error, DecodeError::bad_index);
  // A second metrics section.
  Bytes twice = bytes;
  twice.insert(twice.end(), bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.end());
  fix_length_and_crc(twice);
  EXPECT_EQ(decode_bytes(twice, *decoded).error, DecodeError::bad_index);
}

TEST(TelemetryWireFormat, HeaderFieldsAreLittleEndianAtTheDocumentedOffsets) {
  const auto frame = sample_frame();
  const Bytes b = encode_to_bytes(*frame);
  EXPECT_EQ(std::to_integer<char>(b[0]), 'T');
  EXPECT_EQ(std::to_integer<char>(b[1]), 'R');
  EXPECT_EQ(std::to_integer<char>(b[2]), 'T');
  EXPECT_EQ(std::to_integer<char>(b[3]), 'L');
  EXPECT_EQ(std::to_integer<int>(b[4]), kVersionMajor);
  EXPECT_EQ(std::to_integer<int>(b[5]), kVersionMinor);
  EXPECT_EQ(std::to_integer<std::size_t>(b[6]) | (std::to_integer<std::size_t>(b[7]) << 8), b.size());
  EXPECT_EQ(read_u32(b, 12), 0xA1B2C3D4U);
  EXPECT_EQ(read_u32(b, 16), static_cast<std::uint32_t>(123456789012ULL));
  EXPECT_EQ(read_u32(b, 20), static_cast<std::uint32_t>(123456789012ULL >> 32));
  EXPECT_EQ(read_u32(b, 24), 98765U);
  EXPECT_EQ(read_u32(b, 56), 0x24U);
  EXPECT_EQ(read_u32(b, 60), static_cast<std::uint32_t>(kFlagContactsTruncated));
  // The first section: the duct, type 1, index 0, its body length, its checksum.
  EXPECT_EQ(std::to_integer<int>(b[64]), 1);
  EXPECT_EQ(std::to_integer<int>(b[65]), 0);
  EXPECT_EQ(std::to_integer<std::size_t>(b[66]), 13U + 160U + 70U);
  EXPECT_EQ(read_u32(b, 68), 0x89ABCDEFU);
  EXPECT_EQ(read_u32(b, 72), 0x01234567U);
  // q_0 = -1e-3 as binary32.
  float q0 = 0.0F;
  const std::uint32_t bits = read_u32(b, 68 + 13);
  std::memcpy(&q0, &bits, 4);
  EXPECT_EQ(q0, -1e-3F);
}

TEST(TelemetryWireFormat, NonFiniteValuesAreSentAsZeroAndFlagged) {
  auto frame = sample_frame();
  frame->models[0].modal_coordinates[3] = std::numeric_limits<float>::quiet_NaN();
  frame->instruments[1].tip_m[2] = std::numeric_limits<float>::infinity();
  const Bytes bytes = encode_to_bytes(*frame);
  auto decoded = std::make_unique<Frame>();
  ASSERT_TRUE(decode_bytes(bytes, *decoded).ok());
  EXPECT_NE(decoded->flags & kFlagNonFiniteReplaced, 0U);
  EXPECT_EQ(decoded->models[0].modal_coordinates[3], 0.0F);
  EXPECT_EQ(decoded->instruments[1].tip_m[2], 0.0F);
}

TEST(TelemetryWireFormat, EncodeRefusesWhatDoesNotFit) {
  auto frame = sample_frame();
  Bytes small(encoded_size(*frame) - 1);
  EXPECT_FALSE(encode(*frame, small).ok());
  frame->models[0].mode_count = kMaxModes + 1;
  Bytes big(kMaxDatagramBytes);
  EXPECT_FALSE(encode(*frame, big).ok());
  EXPECT_EQ(encoded_size(*frame), 0U);
  frame = sample_frame();
  frame->models[0].loads[0].node = kMaxNodeIndex + 1;
  EXPECT_FALSE(encode(*frame, big).ok());
  frame = sample_frame();
  frame->models[1].scene_index = 0;  // not ascending
  EXPECT_FALSE(encode(*frame, big).ok());
  frame = sample_frame();
  frame->contact_count = kMaxContacts + 1;
  EXPECT_FALSE(encode(*frame, big).ok());
}

TEST(TelemetryWireFormat, AFrameAtEveryCapacityFitsADatagram) {
  auto frame = std::make_unique<Frame>();
  frame->model_count = kMaxModels;
  for (std::size_t i = 0; i < kMaxModels; ++i) {
    frame->models[i].scene_index = static_cast<std::uint8_t>(i);
    frame->models[i].kind = ModelKind::catheter;  // the largest section
    frame->models[i].particle_count = kMaxParticles;
  }
  frame->instrument_count = kMaxInstruments;
  frame->contact_count = kMaxContacts;
  Bytes out(kMaxDatagramBytes);
  const EncodeResult r = encode(*frame, out);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.bytes, 13121U);  // docs/telemetry.md
  out.resize(r.bytes);
  auto decoded = std::make_unique<Frame>();
  EXPECT_TRUE(decode_bytes(out, *decoded).ok());
  expect_same(*frame, *decoded);
}

TEST(TelemetryWireFormat, EncodeAndDecodeDoNotAllocate) {
  const auto frame = sample_frame();
  auto decoded = std::make_unique<Frame>();
  Bytes out(4096);
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  const EncodeResult e = encode(*frame, out);
  const DecodeResult d = decode(std::span<const std::byte>(out.data(), e.bytes), *decoded);
  core::alloc::end_counting_this_thread();
  EXPECT_TRUE(e.ok());
  EXPECT_TRUE(d.ok());
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
}

TEST(TelemetryWireFormat, EveryTruncationIsRefused) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  auto decoded = std::make_unique<Frame>();
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const DecodeResult r = decode(std::span<const std::byte>(bytes.data(), n), *decoded);
    EXPECT_FALSE(r.ok()) << "prefix of " << n << " bytes accepted";
    EXPECT_EQ(r.error, n < kHeaderBytes ? DecodeError::too_short : DecodeError::length_mismatch);
  }
}

// Offsets into sample_frame()'s encoding.
constexpr std::size_t kDuct = 64;                            // section header
constexpr std::size_t kDuctBody = kDuct + 4;
constexpr std::size_t kLiver = kDuctBody + 13 + 160 + 70;    // section header
constexpr std::size_t kCatheter = kLiver + 4 + 10 + 42;
constexpr std::size_t kInstrument0 = kCatheter + 4 + 10 + 132;
constexpr std::size_t kContacts = kInstrument0 + 2 * 69;

// A truncated frame whose header was rewritten to match (length and CRC): refused where the
// cut falls inside a section; a cut between sections is a shorter valid frame.
TEST(TelemetryWireFormat, EveryConsistentTruncationInsideASectionIsRefused) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  auto decoded = std::make_unique<Frame>();
  int valid_cuts = 0;
  for (std::size_t n = kHeaderBytes + 1; n < bytes.size(); ++n) {
    Bytes cut(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    fix_length_and_crc(cut);
    const DecodeResult r = decode_bytes(cut, *decoded);
    const bool boundary = n == kLiver || n == kCatheter || n == kInstrument0 ||
                          n == kInstrument0 + 69 || n == kContacts;
    if (boundary) {
      EXPECT_TRUE(r.ok()) << "cut at section boundary " << n << ": " << r.detail;
      ++valid_cuts;
    } else {
      EXPECT_FALSE(r.ok()) << "consistent prefix of " << n << " bytes accepted";
      EXPECT_LE(r.offset, n);
    }
  }
  EXPECT_EQ(valid_cuts, 5);
}

TEST(TelemetryWireFormat, EveryBitFlipIsRefused) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  auto decoded = std::make_unique<Frame>();
  for (std::size_t i = 0; i < bytes.size() * 8; ++i) {
    Bytes flipped = bytes;
    flipped[i / 8] ^= std::byte(static_cast<std::uint8_t>(1U << (i % 8)));
    EXPECT_FALSE(decode_bytes(flipped, *decoded).ok()) << "bit " << i << " flipped, accepted";
  }
}

TEST(TelemetryWireFormat, RandomDatagramsAreRefused) {
  std::mt19937_64 random(1818);
  auto decoded = std::make_unique<Frame>();
  for (int trial = 0; trial < 20000; ++trial) {
    Bytes b(random() % 1500);
    for (std::byte& x : b) x = std::byte(static_cast<std::uint8_t>(random()));
    if (trial % 2 == 0 && b.size() >= kHeaderBytes) {  // past the magic and version
      b[0] = std::byte{'T'}; b[1] = std::byte{'R'}; b[2] = std::byte{'T'}; b[3] = std::byte{'L'};
      b[4] = std::byte{kVersionMajor};
      b[5] = std::byte{kVersionMinor};
      if (trial % 4 == 0) fix_length_and_crc(b);  // and past length and CRC
    }
    const DecodeResult r = decode_bytes(b, *decoded);
    if (r.ok()) {
      // Only possible for a header-only frame with valid flags: then it must re-encode to
      // the same bytes.
      EXPECT_EQ(b.size(), kHeaderBytes);
    } else {
      EXPECT_LE(r.offset, b.size());
    }
  }
}

// Mutations of a valid frame with length and CRC repaired: decode never reads out of bounds
// (ASan), and whatever it accepts re-encodes to a frame that decodes the same.
TEST(TelemetryWireFormat, MutatedFramesWithAValidCrcAreRefusedOrConsistent) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  std::mt19937_64 random(77);
  auto decoded = std::make_unique<Frame>();
  auto again = std::make_unique<Frame>();
  int accepted = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Bytes b = bytes;
    const int edits = 1 + static_cast<int>(random() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = kHeaderBytes + random() % (b.size() - kHeaderBytes);
      b[at] = std::byte(static_cast<std::uint8_t>(random()));
    }
    if (random() % 3 == 0) b.resize(kHeaderBytes + random() % (b.size() - kHeaderBytes));
    fix_length_and_crc(b);
    const DecodeResult r = decode_bytes(b, *decoded);
    if (!r.ok()) {
      EXPECT_LE(r.offset, b.size());
      continue;
    }
    ++accepted;
    const Bytes re = encode_to_bytes(*decoded);
    ASSERT_TRUE(decode_bytes(re, *again).ok());
    expect_same(*decoded, *again);
  }
  EXPECT_GT(accepted, 0);  // float payload edits are legitimate frames
}

struct Malformation {
  const char* name;
  DecodeError expected;
  void (*apply)(Bytes&);
};


const Malformation kMalformations[] = {
    {"magic", DecodeError::bad_magic, [](Bytes& b) { set_u8(b, 0, 'X'); }},
    {"major version", DecodeError::unsupported_version, [](Bytes& b) { set_u8(b, 4, 2); }},
    {"length", DecodeError::length_mismatch, [](Bytes& b) { write_u16(b, 6, 64); write_u32(b, 8, 0); write_u32(b, 8, crc32(b)); }},
    {"unknown frame flag", DecodeError::bad_value, [](Bytes& b) { write_u32(b, 60, 1U << 20); }},
    {"section length past the end", DecodeError::truncated_section, [](Bytes& b) { write_u16(b, kDuct + 2, 0xFFFF); }},
    {"mode count beyond capacity", DecodeError::capacity_exceeded, [](Bytes& b) { write_u16(b, kDuctBody + 8, 257); }},
    {"mode count beyond the body", DecodeError::bad_section, [](Bytes& b) { write_u16(b, kDuctBody + 8, 100); }},
    {"mode count short of the body", DecodeError::bad_section, [](Bytes& b) { write_u16(b, kDuctBody + 8, 39); }},
    {"load count beyond capacity", DecodeError::capacity_exceeded, [](Bytes& b) { write_u16(b, kDuctBody + 10, 65); }},
    {"unknown modal flag", DecodeError::bad_value, [](Bytes& b) { set_u8(b, kDuctBody + 12, 0x80); }},
    {"NaN modal coordinate", DecodeError::non_finite, [](Bytes& b) { write_u32(b, kDuctBody + 13 + 8, 0x7FC00000U); }},
    {"model indices not ascending", DecodeError::bad_index, [](Bytes& b) { set_u8(b, kLiver + 1, 0); }},
    {"model index beyond capacity", DecodeError::bad_index, [](Bytes& b) { set_u8(b, kCatheter + 1, 9); }},
    {"unknown section type", DecodeError::bad_section, [](Bytes& b) { set_u8(b, kLiver, 99); }},
    {"tensor count beyond body", DecodeError::bad_section, [](Bytes& b) { write_u16(b, kLiver + 4 + 8, 4); }},
    {"particle count beyond capacity", DecodeError::capacity_exceeded, [](Bytes& b) { write_u16(b, kCatheter + 4 + 8, 300); }},
    {"instrument out of order", DecodeError::bad_index, [](Bytes& b) { set_u8(b, kInstrument0 + 1, 1); }},
    {"instrument flag", DecodeError::bad_value, [](Bytes& b) { set_u8(b, kInstrument0 + 4, 0x40); }},
    {"infinite instrument tip", DecodeError::non_finite, [](Bytes& b) { write_u32(b, kInstrument0 + 4 + 5, 0x7F800000U); }},
    {"contact kind", DecodeError::bad_value, [](Bytes& b) { set_u8(b, kContacts + 4 + 1 + 2, 9); }},
    {"contact instrument missing", DecodeError::bad_index, [](Bytes& b) { set_u8(b, kContacts + 4 + 1, 3); }},
    {"contact model missing", DecodeError::bad_index, [](Bytes& b) { set_u8(b, kContacts + 4 + 1 + 1, 2); }},
    {"contact count beyond body", DecodeError::bad_section, [](Bytes& b) { set_u8(b, kContacts + 4, 4); }},
    {"contact count beyond capacity", DecodeError::capacity_exceeded, [](Bytes& b) { set_u8(b, kContacts + 4, 17); }},
    {"extra byte in a section", DecodeError::bad_section, [](Bytes& b) {
       b.push_back(std::byte{0});
       set_u8(b, kContacts + 2, static_cast<std::uint8_t>(1 + 27 * 3 + 1));
     }},
    {"trailing byte after the sections", DecodeError::truncated_section, [](Bytes& b) { b.push_back(std::byte{0}); }},
};

TEST(TelemetryWireFormat, EachMalformationIsRefusedWithItsReason) {
  const auto frame = sample_frame();
  const Bytes bytes = encode_to_bytes(*frame);
  ASSERT_EQ(bytes.size(), kContacts + 4 + 1 + 27 * 3);
  auto decoded = std::make_unique<Frame>();
  for (const Malformation& m : kMalformations) {
    Bytes b = bytes;
    m.apply(b);
    if (m.expected != DecodeError::bad_magic && m.expected != DecodeError::unsupported_version &&
        m.expected != DecodeError::length_mismatch)
      fix_length_and_crc(b);
    const DecodeResult r = decode_bytes(b, *decoded);
    EXPECT_EQ(r.error, m.expected) << m.name << ": got " << to_string(r.error) << " (" << r.detail
                                   << ") at " << r.offset;
  }
}

TEST(TelemetryWireFormat, ACorruptedCrcIsRefused) {
  const auto frame = sample_frame();
  Bytes b = encode_to_bytes(*frame);
  write_u32(b, 8, read_u32(b, 8) ^ 1U);
  auto decoded = std::make_unique<Frame>();
  EXPECT_EQ(decode_bytes(b, *decoded).error, DecodeError::bad_checksum);
}

// A newer minor version may append fields to a section and add section types: this reader
// skips both. The same bytes from this minor version are refused.
TEST(TelemetryWireFormat, ANewerMinorVersionsAdditionsAreSkipped) {
  const auto frame = sample_frame();
  Bytes b = encode_to_bytes(*frame);
  // Two extra bytes at the end of the contacts section, then an unknown section of 3 bytes.
  b.push_back(std::byte{0xAA});
  b.push_back(std::byte{0xBB});
  set_u8(b, kContacts + 2, static_cast<std::uint8_t>(1 + 27 * 3 + 2));
  for (const std::uint8_t x : {std::uint8_t{200}, std::uint8_t{0}, std::uint8_t{3}, std::uint8_t{0},
                               std::uint8_t{1}, std::uint8_t{2}, std::uint8_t{3}})
    b.push_back(std::byte{x});
  Bytes same_minor = b;
  fix_length_and_crc(same_minor);
  auto decoded = std::make_unique<Frame>();
  EXPECT_FALSE(decode_bytes(same_minor, *decoded).ok());
  set_u8(b, 5, kVersionMinor + 1);
  fix_length_and_crc(b);
  const DecodeResult r = decode_bytes(b, *decoded);
  ASSERT_TRUE(r.ok()) << to_string(r.error) << ": " << r.detail << " at " << r.offset;
  expect_same(*frame, *decoded);
  // Its new flag bits (frame, modal, instrument) are dropped, so what this reader holds
  // re-encodes as a frame of its own version (found by fuzz_telemetry_frame).
  write_u32(b, 60, read_u32(b, 60) | (1U << 20));
  set_u8(b, kDuctBody + 12, static_cast<std::uint8_t>(kModalStaticCorrection | 0x80));
  set_u8(b, kInstrument0 + 4, static_cast<std::uint8_t>(std::to_integer<std::uint8_t>(b[kInstrument0 + 4]) | 0x40));
  fix_length_and_crc(b);
  ASSERT_TRUE(decode_bytes(b, *decoded).ok());
  expect_same(*frame, *decoded);
  const Bytes again = encode_to_bytes(*decoded);
  auto reread = std::make_unique<Frame>();
  EXPECT_TRUE(decode_bytes(again, *reread).ok());
}

TEST(TelemetryWireFormat, Crc32MatchesTheStandardCheckValue) {
  const char* text = "123456789";
  std::vector<std::byte> b;
  for (const char* p = text; *p != 0; ++p) b.push_back(std::byte(static_cast<std::uint8_t>(*p)));
  EXPECT_EQ(crc32(b), 0xCBF43926U);
}

TEST(TelemetryWireFormat, FindModelByIndex) {
  const auto frame = sample_frame();
  ASSERT_NE(find_model(*frame, 3), nullptr);
  EXPECT_EQ(find_model(*frame, 3)->kind, ModelKind::catheter);
  EXPECT_EQ(find_model(*frame, 2), nullptr);
}

}  // namespace
}  // namespace trainer::telemetry
