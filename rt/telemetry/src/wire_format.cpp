#include "trainer/telemetry/wire_format.hpp"

#include <bit>
#include <cstring>

namespace trainer::telemetry {
namespace {

// Section body sizes (bytes) before their arrays, and per array element.
constexpr std::size_t kModalFixedBytes = 8 + 2 + 2 + 1;  // checksum, r, load count, flags
constexpr std::size_t kLoadBytes = 2 + 12;               // u16 node, 3 × f32
constexpr std::size_t kTensorFixedBytes = 8 + 2;         // checksum, contact count
constexpr std::size_t kTensorContactBytes = 2 + 12;
constexpr std::size_t kCatheterFixedBytes = 8 + 2;       // checksum, particle count
constexpr std::size_t kParticleBytes = 12;
constexpr std::size_t kInstrumentBytes = 1 + 4 + 5 * 12;
constexpr std::size_t kContactsFixedBytes = 1;
constexpr std::size_t kContactBytes = 1 + 1 + 1 + 12 + 12;
constexpr std::size_t kMetricsFixedBytes = 1 + 6 * 4 + 1;  // flags, six f32, instrument count
constexpr std::size_t kInstrumentMetricsBytes = 5 * 4 + 3 * 2;
constexpr std::size_t kCrcOffset = 8;

constexpr std::uint8_t kKnownModalFlags = kModalStaticCorrection | kModalLoadsTruncated;
constexpr std::uint8_t kKnownInstrumentFlags = kInstrumentTissueContact | kInstrumentGrasping |
                                               kInstrumentWallContact | kInstrumentCatheterContact;
constexpr std::uint8_t kKnownMetricsFlags =
    kMetricsTaskStarted | kMetricsTaskCompleted | kMetricsInsertionGoal | kMetricsTargetReached;
constexpr std::uint32_t kKnownFrameFlags =
    kFlagNonFiniteReplaced | kFlagContactsTruncated | kFlagRunEnded;

constexpr std::array<std::uint32_t, 256> make_crc_table() noexcept {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t value = i;
    for (int bit = 0; bit < 8; ++bit) value = (value & 1U) != 0 ? (value >> 1) ^ 0xEDB88320U : value >> 1;
    table[i] = value;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

std::uint32_t crc_update(std::uint32_t crc, std::span<const std::byte> bytes) noexcept {
  for (const std::byte b : bytes)
    crc = kCrcTable[(crc ^ std::to_integer<std::uint32_t>(b)) & 0xFFU] ^ (crc >> 8);
  return crc;
}

// The frame's CRC: over every byte with the four CRC bytes taken as zero.
std::uint32_t frame_crc(std::span<const std::byte> frame) noexcept {
  constexpr std::array<std::byte, 4> zero{};
  std::uint32_t crc = 0xFFFFFFFFU;
  crc = crc_update(crc, frame.first(kCrcOffset));
  crc = crc_update(crc, zero);
  crc = crc_update(crc, frame.subspan(kCrcOffset + 4));
  return crc ^ 0xFFFFFFFFU;
}

bool float_is_finite(float value) noexcept {
  return (std::bit_cast<std::uint32_t>(value) & 0x7F800000U) != 0x7F800000U;
}

std::size_t modal_body_bytes(const ModelState& m) noexcept {
  return kModalFixedBytes + 4 * m.mode_count + kLoadBytes * m.load_count;
}
std::size_t model_body_bytes(const ModelState& m) noexcept {
  switch (m.kind) {
    case ModelKind::modal: return modal_body_bytes(m);
    case ModelKind::tensor: return kTensorFixedBytes + kTensorContactBytes * m.contact_count;
    case ModelKind::catheter: return kCatheterFixedBytes + kParticleBytes * m.particle_count;
  }
  return 0;
}

class WireWriter {
 public:
  explicit WireWriter(std::span<std::byte> out) noexcept : out_(out) {}
  void u8(std::uint8_t v) noexcept { out_[pos_++] = std::byte{v}; }
  void u16(std::uint16_t v) noexcept { put(v, 2); }
  void u32(std::uint32_t v) noexcept { put(v, 4); }
  void u64(std::uint64_t v) noexcept { put(v, 8); }
  void i64(std::int64_t v) noexcept { put(static_cast<std::uint64_t>(v), 8); }
  void f32(float v) noexcept {
    if (!float_is_finite(v)) {
      replaced_ = true;
      v = 0.0F;
    }
    u32(std::bit_cast<std::uint32_t>(v));
  }
  void vec3(const std::array<float, 3>& v) noexcept {
    for (const float c : v) f32(c);
  }
  std::size_t position() const noexcept { return pos_; }
  bool replaced_non_finite() const noexcept { return replaced_; }
  void patch_u32(std::size_t at, std::uint32_t v) noexcept {
    for (std::size_t i = 0; i < 4; ++i) out_[at + i] = std::byte(static_cast<std::uint8_t>(v >> (8 * i)));
  }

 private:
  void put(std::uint64_t v, std::size_t n) noexcept {
    for (std::size_t i = 0; i < n; ++i) out_[pos_ + i] = std::byte(static_cast<std::uint8_t>(v >> (8 * i)));
    pos_ += n;
  }
  std::span<std::byte> out_;
  std::size_t pos_ = 0;
  bool replaced_ = false;
};

void write_section_header(WireWriter& w, SectionType type, std::size_t index,
                          std::size_t body_bytes) noexcept {
  w.u8(static_cast<std::uint8_t>(type));
  w.u8(static_cast<std::uint8_t>(index));
  w.u16(static_cast<std::uint16_t>(body_bytes));
}

const char* check_frame_for_encoding(const Frame& frame) noexcept {
  if (frame.model_count > kMaxModels) return "more models than kMaxModels";
  if (frame.instrument_count > kMaxInstruments) return "more instruments than kMaxInstruments";
  if (frame.contact_count > kMaxContacts) return "more contacts than kMaxContacts";
  if (frame.has_metrics && frame.metrics.instrument_count > kMaxInstruments)
    return "more metrics instruments than kMaxInstruments";
  int previous = -1;
  for (std::size_t i = 0; i < frame.model_count; ++i) {
    const ModelState& m = frame.models[i];
    if (static_cast<int>(m.scene_index) <= previous || m.scene_index >= kMaxModels)
      return "model scene indices not ascending below kMaxModels";
    previous = m.scene_index;
    switch (m.kind) {
      case ModelKind::modal:
        if (m.mode_count > kMaxModes) return "more modes than kMaxModes";
        if (m.load_count > kMaxLoads) return "more loads than kMaxLoads";
        for (std::size_t k = 0; k < m.load_count; ++k)
          if (m.loads[k].node > kMaxNodeIndex) return "load node index above kMaxNodeIndex";
        break;
      case ModelKind::tensor:
        if (m.contact_count > kMaxTensorContacts) return "more tensor contacts than kMaxTensorContacts";
        for (std::size_t k = 0; k < m.contact_count; ++k)
          if (m.contacts[k].node > kMaxNodeIndex) return "tensor node index above kMaxNodeIndex";
        break;
      case ModelKind::catheter:
        if (m.particle_count > kMaxParticles) return "more particles than kMaxParticles";
        break;
      default:
        return "unknown model kind";
    }
  }
  return nullptr;
}

}  // namespace

std::uint32_t crc32(std::span<const std::byte> bytes) noexcept {
  return crc_update(0xFFFFFFFFU, bytes) ^ 0xFFFFFFFFU;
}

std::size_t encoded_size(const Frame& frame) noexcept {
  if (check_frame_for_encoding(frame) != nullptr) return 0;
  std::size_t bytes = kHeaderBytes;
  for (std::size_t i = 0; i < frame.model_count; ++i)
    bytes += kSectionHeaderBytes + model_body_bytes(frame.models[i]);
  bytes += frame.instrument_count * (kSectionHeaderBytes + kInstrumentBytes);
  if (frame.contact_count > 0)
    bytes += kSectionHeaderBytes + kContactsFixedBytes + kContactBytes * frame.contact_count;
  if (frame.has_metrics)
    bytes += kSectionHeaderBytes + kMetricsFixedBytes +
             kInstrumentMetricsBytes * frame.metrics.instrument_count;
  return bytes;
}

EncodeResult encode(const Frame& frame, std::span<std::byte> out) noexcept {
  if (const char* error = check_frame_for_encoding(frame); error != nullptr) return {0, error};
  const std::size_t size = encoded_size(frame);
  if (size > kMaxDatagramBytes) return {0, "frame larger than a UDP datagram"};
  if (out.size() < size) return {0, "output buffer too small"};
  WireWriter w(out);
  for (const std::uint8_t b : kMagic) w.u8(b);
  w.u8(kVersionMajor);
  w.u8(kVersionMinor);
  w.u16(static_cast<std::uint16_t>(size));
  w.u32(0);  // CRC, patched below
  w.u32(frame.stream_id);
  w.u64(frame.sequence);
  w.u64(frame.cycle);
  w.i64(frame.cycle_time_ns);
  w.i64(frame.send_time_ns);
  w.i64(frame.send_wall_ns);
  w.u32(frame.latched_faults);
  const std::size_t flags_at = w.position();
  w.u32(frame.flags);

  for (std::size_t i = 0; i < frame.model_count; ++i) {
    const ModelState& m = frame.models[i];
    switch (m.kind) {
      case ModelKind::modal:
        write_section_header(w, SectionType::modal, m.scene_index, model_body_bytes(m));
        w.u64(m.image_checksum);
        w.u16(static_cast<std::uint16_t>(m.mode_count));
        w.u16(static_cast<std::uint16_t>(m.load_count));
        w.u8(m.flags);
        for (std::size_t k = 0; k < m.mode_count; ++k) w.f32(m.modal_coordinates[k]);
        for (std::size_t k = 0; k < m.load_count; ++k) {
          w.u16(static_cast<std::uint16_t>(m.loads[k].node));
          w.vec3(m.loads[k].force_n);
        }
        break;
      case ModelKind::tensor:
        write_section_header(w, SectionType::tensor, m.scene_index, model_body_bytes(m));
        w.u64(m.image_checksum);
        w.u16(static_cast<std::uint16_t>(m.contact_count));
        for (std::size_t k = 0; k < m.contact_count; ++k) {
          w.u16(static_cast<std::uint16_t>(m.contacts[k].node));
          w.vec3(m.contacts[k].displacement_m);
        }
        break;
      case ModelKind::catheter:
        write_section_header(w, SectionType::catheter, m.scene_index, model_body_bytes(m));
        w.u64(m.image_checksum);
        w.u16(static_cast<std::uint16_t>(m.particle_count));
        for (std::size_t k = 0; k < m.particle_count; ++k) w.vec3(m.particles_m[k]);
        break;
    }
  }
  for (std::size_t i = 0; i < frame.instrument_count; ++i) {
    const InstrumentState& s = frame.instruments[i];
    write_section_header(w, SectionType::instrument, i, kInstrumentBytes);
    w.u8(s.flags);
    w.f32(s.grip_rad);
    w.vec3(s.tip_m);
    w.vec3(s.hinge_m);
    w.vec3(s.shaft_start_m);
    w.vec3(s.opening_direction);
    w.vec3(s.force_n);
  }
  if (frame.contact_count > 0) {
    write_section_header(w, SectionType::contacts, 0,
                         kContactsFixedBytes + kContactBytes * frame.contact_count);
    w.u8(static_cast<std::uint8_t>(frame.contact_count));
    for (std::size_t i = 0; i < frame.contact_count; ++i) {
      const ContactPoint& c = frame.contacts[i];
      w.u8(c.instrument);
      w.u8(c.model);
      w.u8(static_cast<std::uint8_t>(c.kind));
      w.vec3(c.point_m);
      w.vec3(c.force_n);
    }
  }
  if (frame.has_metrics) {
    const SessionMetrics& m = frame.metrics;
    write_section_header(w, SectionType::metrics, 0,
                         kMetricsFixedBytes + kInstrumentMetricsBytes * m.instrument_count);
    w.u8(m.flags);
    w.f32(m.session_time_s);
    w.f32(m.task_time_s);
    w.f32(m.time_above_safe_s);
    w.f32(m.damage_impulse_n_s);
    w.f32(m.insertion_depth_m);
    w.f32(m.time_to_target_s);
    w.u8(m.instrument_count);
    for (std::size_t i = 0; i < m.instrument_count; ++i) {
      const InstrumentMetrics& t = m.instruments[i];
      w.f32(t.path_length_m);
      w.f32(t.idle_time_s);
      w.f32(t.peak_force_n);
      w.f32(t.mean_contact_force_n);
      w.f32(t.time_above_safe_s);
      w.u16(t.movements);
      w.u16(t.grasps);
      w.u16(t.slips);
    }
  }
  if (w.replaced_non_finite()) w.patch_u32(flags_at, frame.flags | kFlagNonFiniteReplaced);
  w.patch_u32(kCrcOffset, frame_crc(out.first(size)));
  return {size, ""};
}

// ---- decoding ----

namespace {

// Bounds-checked little-endian reads over [begin, end) of the datagram; the first failure
// sticks (later reads return 0) so a body can be read straight through and checked once.
class WireReader {
 public:
  WireReader(std::span<const std::byte> bytes, std::size_t begin, std::size_t end) noexcept
      : bytes_(bytes), pos_(begin), end_(end) {}
  std::uint8_t u8() noexcept { return static_cast<std::uint8_t>(get(1)); }
  std::uint16_t u16() noexcept { return static_cast<std::uint16_t>(get(2)); }
  std::uint32_t u32() noexcept { return static_cast<std::uint32_t>(get(4)); }
  std::uint64_t u64() noexcept { return get(8); }
  std::int64_t i64() noexcept { return static_cast<std::int64_t>(get(8)); }
  float f32() noexcept {
    const std::size_t at = pos_;
    const float v = std::bit_cast<float>(u32());
    if (!float_is_finite(v) && !failed_ && non_finite_at_ == kNone) non_finite_at_ = at;
    return v;
  }
  std::array<float, 3> vec3() noexcept { return {f32(), f32(), f32()}; }

  bool failed() const noexcept { return failed_; }
  bool has_non_finite() const noexcept { return non_finite_at_ != kNone; }
  std::size_t non_finite_at() const noexcept { return non_finite_at_; }
  std::size_t position() const noexcept { return pos_; }
  std::size_t remaining() const noexcept { return end_ - pos_; }

 private:
  static constexpr std::size_t kNone = ~std::size_t{0};
  std::uint64_t get(std::size_t n) noexcept {
    if (failed_ || end_ - pos_ < n) {
      failed_ = true;
      return 0;
    }
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < n; ++i)
      v |= std::to_integer<std::uint64_t>(bytes_[pos_ + i]) << (8 * i);
    pos_ += n;
    return v;
  }
  std::span<const std::byte> bytes_;
  std::size_t pos_;
  std::size_t end_;
  bool failed_ = false;
  std::size_t non_finite_at_ = kNone;
};

DecodeResult fail(DecodeError error, std::size_t offset, const char* detail) noexcept {
  return {error, offset, detail};
}

// After a body's known fields: fine when read exactly; trailing bytes only from a newer minor
// version (fields appended later); non-finite floats refused.
DecodeResult finish_body(const WireReader& r, std::size_t body_at, bool newer_minor,
                         const char* what) noexcept {
  if (r.failed()) return fail(DecodeError::bad_section, body_at, what);
  if (r.has_non_finite()) return fail(DecodeError::non_finite, r.non_finite_at(), what);
  if (r.remaining() != 0 && !newer_minor)
    return fail(DecodeError::bad_section, r.position(), "extra bytes after a section's fields");
  return {};
}

DecodeResult decode_modal(WireReader& r, std::size_t body_at, ModelState& m,
                          bool newer_minor) noexcept {
  m.kind = ModelKind::modal;
  m.image_checksum = r.u64();
  const std::uint16_t modes = r.u16();
  const std::uint16_t loads = r.u16();
  m.flags = r.u8();
  if (r.failed()) return fail(DecodeError::bad_section, body_at, "modal section shorter than its fixed fields");
  if (modes > kMaxModes) return fail(DecodeError::capacity_exceeded, body_at + 8, "modal mode count");
  if (loads > kMaxLoads) return fail(DecodeError::capacity_exceeded, body_at + 10, "modal load count");
  // Flag bits of a newer minor version are dropped; of this one, refused.
  if ((m.flags & ~kKnownModalFlags) != 0) {
    if (!newer_minor) return fail(DecodeError::bad_value, body_at + 12, "modal flags");
    m.flags &= kKnownModalFlags;
  }
  if (r.remaining() < 4 * std::size_t{modes} + kLoadBytes * loads)
    return fail(DecodeError::bad_section, body_at, "modal section shorter than its counts");
  m.mode_count = modes;
  m.load_count = loads;
  for (std::size_t k = 0; k < modes; ++k) m.modal_coordinates[k] = r.f32();
  for (std::size_t k = 0; k < loads; ++k) {
    m.loads[k].node = r.u16();
    m.loads[k].force_n = r.vec3();
  }
  return {};
}

DecodeResult decode_tensor(WireReader& r, std::size_t body_at, ModelState& m) noexcept {
  m.kind = ModelKind::tensor;
  m.image_checksum = r.u64();
  const std::uint16_t count = r.u16();
  if (r.failed()) return fail(DecodeError::bad_section, body_at, "tensor section shorter than its fixed fields");
  if (count > kMaxTensorContacts)
    return fail(DecodeError::capacity_exceeded, body_at + 8, "tensor contact count");
  if (r.remaining() < kTensorContactBytes * count)
    return fail(DecodeError::bad_section, body_at, "tensor section shorter than its count");
  m.contact_count = count;
  for (std::size_t k = 0; k < count; ++k) {
    m.contacts[k].node = r.u16();
    m.contacts[k].displacement_m = r.vec3();
  }
  return {};
}

DecodeResult decode_catheter(WireReader& r, std::size_t body_at, ModelState& m) noexcept {
  m.kind = ModelKind::catheter;
  m.image_checksum = r.u64();
  const std::uint16_t count = r.u16();
  if (r.failed()) return fail(DecodeError::bad_section, body_at, "catheter section shorter than its fixed fields");
  if (count > kMaxParticles) return fail(DecodeError::capacity_exceeded, body_at + 8, "catheter particle count");
  if (r.remaining() < kParticleBytes * count)
    return fail(DecodeError::bad_section, body_at, "catheter section shorter than its count");
  m.particle_count = count;
  for (std::size_t k = 0; k < count; ++k) m.particles_m[k] = r.vec3();
  return {};
}

DecodeResult decode_contacts(WireReader& r, std::size_t body_at, Frame& out) noexcept {
  const std::uint8_t count = r.u8();
  if (r.failed()) return fail(DecodeError::bad_section, body_at, "contacts section empty");
  if (count > kMaxContacts) return fail(DecodeError::capacity_exceeded, body_at, "contact count");
  if (r.remaining() < kContactBytes * count)
    return fail(DecodeError::bad_section, body_at, "contacts section shorter than its count");
  out.contact_count = count;
  for (std::size_t k = 0; k < count; ++k) {
    ContactPoint& c = out.contacts[k];
    const std::size_t at = r.position();
    c.instrument = r.u8();
    c.model = r.u8();
    const std::uint8_t kind = r.u8();
    if (kind > static_cast<std::uint8_t>(ContactKind::jaw1))
      return fail(DecodeError::bad_value, at + 2, "contact kind");
    if (c.instrument >= kMaxInstruments) return fail(DecodeError::bad_index, at, "contact instrument");
    if (c.model != kNoModel && c.model >= kMaxModels) return fail(DecodeError::bad_index, at + 1, "contact model");
    c.kind = static_cast<ContactKind>(kind);
    c.point_m = r.vec3();
    c.force_n = r.vec3();
  }
  return {};
}

DecodeResult decode_metrics(WireReader& r, std::size_t body_at, bool newer_minor,
                            SessionMetrics& m) noexcept {
  m.flags = r.u8();
  m.session_time_s = r.f32();
  m.task_time_s = r.f32();
  m.time_above_safe_s = r.f32();
  m.damage_impulse_n_s = r.f32();
  m.insertion_depth_m = r.f32();
  m.time_to_target_s = r.f32();
  const std::uint8_t count = r.u8();
  if (r.failed()) return fail(DecodeError::bad_section, body_at, "metrics section shorter than its fixed fields");
  if ((m.flags & ~kKnownMetricsFlags) != 0) {
    if (!newer_minor) return fail(DecodeError::bad_value, body_at, "metrics flags");
    m.flags &= kKnownMetricsFlags;
  }
  if (count > kMaxInstruments)
    return fail(DecodeError::capacity_exceeded, body_at + kMetricsFixedBytes - 1, "metrics instrument count");
  if (r.remaining() < kInstrumentMetricsBytes * count)
    return fail(DecodeError::bad_section, body_at, "metrics section shorter than its count");
  m.instrument_count = count;
  for (std::size_t i = 0; i < count; ++i) {
    InstrumentMetrics& t = m.instruments[i];
    t.path_length_m = r.f32();
    t.idle_time_s = r.f32();
    t.peak_force_n = r.f32();
    t.mean_contact_force_n = r.f32();
    t.time_above_safe_s = r.f32();
    t.movements = r.u16();
    t.grasps = r.u16();
    t.slips = r.u16();
  }
  return {};
}

}  // namespace

const char* to_string(DecodeError error) noexcept {
  switch (error) {
    case DecodeError::none: return "ok";
    case DecodeError::too_short: return "shorter than a header";
    case DecodeError::too_long: return "longer than a UDP datagram";
    case DecodeError::bad_magic: return "not a telemetry frame (magic)";
    case DecodeError::unsupported_version: return "unsupported major version";
    case DecodeError::length_mismatch: return "header length is not the datagram's";
    case DecodeError::bad_checksum: return "CRC-32 mismatch";
    case DecodeError::truncated_section: return "section runs past the end";
    case DecodeError::bad_section: return "malformed section";
    case DecodeError::capacity_exceeded: return "count beyond capacity";
    case DecodeError::bad_index: return "bad or repeated index";
    case DecodeError::non_finite: return "non-finite number";
    case DecodeError::bad_value: return "undefined enumeration or flag value";
  }
  return "unknown decode error";
}

DecodeResult decode(std::span<const std::byte> bytes, Frame& out) noexcept {
  const std::size_t size = bytes.size();
  if (size < kHeaderBytes) return fail(DecodeError::too_short, size, "header");
  if (size > kMaxDatagramBytes) return fail(DecodeError::too_long, kMaxDatagramBytes, "datagram");
  for (std::size_t i = 0; i < kMagic.size(); ++i)
    if (std::to_integer<std::uint8_t>(bytes[i]) != kMagic[i]) return fail(DecodeError::bad_magic, i, "magic");
  WireReader h(bytes, 4, kHeaderBytes);
  const std::uint8_t major = h.u8();
  const std::uint8_t minor = h.u8();
  if (major != kVersionMajor) return fail(DecodeError::unsupported_version, 4, "major version");
  const bool newer_minor = minor > kVersionMinor;
  if (h.u16() != size) return fail(DecodeError::length_mismatch, 6, "frame length");
  const std::uint32_t crc = h.u32();
  if (crc != frame_crc(bytes)) return fail(DecodeError::bad_checksum, kCrcOffset, "CRC-32");
  out.stream_id = h.u32();
  out.sequence = h.u64();
  out.cycle = h.u64();
  out.cycle_time_ns = h.i64();
  out.send_time_ns = h.i64();
  out.send_wall_ns = h.i64();
  out.latched_faults = h.u32();
  out.flags = h.u32();
  if ((out.flags & ~kKnownFrameFlags) != 0) {
    if (!newer_minor) return fail(DecodeError::bad_value, 60, "frame flags");
    out.flags &= kKnownFrameFlags;  // a newer minor version's flags: dropped
  }
  out.model_count = 0;
  out.instrument_count = 0;
  out.contact_count = 0;
  out.has_metrics = false;

  bool has_contacts = false;
  int last_model = -1;
  std::size_t pos = kHeaderBytes;
  while (pos < size) {
    if (size - pos < kSectionHeaderBytes)
      return fail(DecodeError::truncated_section, pos, "section header");
    WireReader sh(bytes, pos, pos + kSectionHeaderBytes);
    const std::uint8_t type = sh.u8();
    const std::uint8_t index = sh.u8();
    const std::size_t length = sh.u16();
    const std::size_t body_at = pos + kSectionHeaderBytes;
    if (size - body_at < length) return fail(DecodeError::truncated_section, pos + 2, "section length");
    WireReader r(bytes, body_at, body_at + length);
    DecodeResult result;
    switch (static_cast<SectionType>(type)) {
      case SectionType::modal:
      case SectionType::tensor:
      case SectionType::catheter: {
        if (index >= kMaxModels) return fail(DecodeError::bad_index, pos + 1, "model index");
        if (static_cast<int>(index) <= last_model)
          return fail(DecodeError::bad_index, pos + 1, "model indices not ascending");
        if (out.model_count >= kMaxModels) return fail(DecodeError::capacity_exceeded, pos, "model count");
        ModelState& m = out.models[out.model_count];
        m = ModelState{};
        m.scene_index = index;
        if (type == static_cast<std::uint8_t>(SectionType::modal)) {
          result = decode_modal(r, body_at, m, newer_minor);
        } else if (type == static_cast<std::uint8_t>(SectionType::tensor)) {
          result = decode_tensor(r, body_at, m);
        } else {
          result = decode_catheter(r, body_at, m);
        }
        if (!result.ok()) return result;
        result = finish_body(r, body_at, newer_minor, "model section");
        if (!result.ok()) return result;
        last_model = index;
        ++out.model_count;
        break;
      }
      case SectionType::instrument: {
        if (index != out.instrument_count || index >= kMaxInstruments)
          return fail(DecodeError::bad_index, pos + 1, "instrument index (0, 1, ... in order)");
        InstrumentState& s = out.instruments[index];
        s.flags = r.u8();
        s.grip_rad = r.f32();
        s.tip_m = r.vec3();
        s.hinge_m = r.vec3();
        s.shaft_start_m = r.vec3();
        s.opening_direction = r.vec3();
        s.force_n = r.vec3();
        result = finish_body(r, body_at, newer_minor, "instrument section shorter than its fields");
        if (!result.ok()) return result;
        if ((s.flags & ~kKnownInstrumentFlags) != 0) {
          if (!newer_minor) return fail(DecodeError::bad_value, body_at, "instrument flags");
          s.flags &= kKnownInstrumentFlags;
        }
        ++out.instrument_count;
        break;
      }
      case SectionType::contacts: {
        if (has_contacts || index != 0) return fail(DecodeError::bad_index, pos, "contacts section repeated or index not 0");
        has_contacts = true;
        result = decode_contacts(r, body_at, out);
        if (!result.ok()) return result;
        result = finish_body(r, body_at, newer_minor, "contacts section");
        if (!result.ok()) return result;
        break;
      }
      case SectionType::metrics: {
        if (out.has_metrics || index != 0)
          return fail(DecodeError::bad_index, pos, "metrics section repeated or index not 0");
        out.metrics = SessionMetrics{};
        result = decode_metrics(r, body_at, newer_minor, out.metrics);
        if (!result.ok()) return result;
        result = finish_body(r, body_at, newer_minor, "metrics section");
        if (!result.ok()) return result;
        out.has_metrics = true;
        break;
      }
      default:
        if (!newer_minor) return fail(DecodeError::bad_section, pos, "unknown section type");
        break;  // a newer minor version's section: skipped
    }
    pos = body_at + length;
  }
  if (out.has_metrics && out.metrics.instrument_count > out.instrument_count)
    return fail(DecodeError::bad_index, size, "metrics name more instruments than the frame has");
  for (std::size_t k = 0; k < out.contact_count; ++k) {
    if (out.contacts[k].instrument >= out.instrument_count)
      return fail(DecodeError::bad_index, size, "contact names an instrument the frame lacks");
    if (out.contacts[k].model != kNoModel && find_model(out, out.contacts[k].model) == nullptr)
      return fail(DecodeError::bad_index, size, "contact names a model the frame lacks");
  }
  return {};
}

const ModelState* find_model(const Frame& frame, std::uint8_t scene_index) noexcept {
  for (std::size_t i = 0; i < frame.model_count && i < kMaxModels; ++i)
    if (frame.models[i].scene_index == scene_index) return &frame.models[i];
  return nullptr;
}

}  // namespace trainer::telemetry
