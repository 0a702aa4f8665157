// The telemetry stream's wire format, version 1.1 (docs/telemetry.md has the byte layout): one
// frame per UDP datagram, sent by the appliance's telemetry thread at 30–120 Hz to the graphics
// host. A frame carries the state the graphics host needs to draw the scene from its own copy
// of the model images: per scene model its modal coordinates (plus the loads the static
// correction needs), a tensor model's imposed contact displacements, a catheter's particle
// positions; per instrument the shaft and jaws; contact points and forces; latched faults; the
// cycle counter and timestamps; each model image's XXH64 so a host whose images differ
// refuses the stream; and (since 1.1) the session's trainee metrics so far.
//
// Encoding: explicit little-endian, IEEE-754 binary32 floats, no padding. A 64-byte header
// (magic "TRTL", major.minor version, total length, CRC-32 of the frame, stream id, sequence,
// cycle, timestamps, faults, flags) and a list of sections (type, index, body length, body).
// decode() trusts nothing: every length is checked against the bytes that are there and the
// fixed capacities below, every float must be finite, indices in range and in order; it
// refuses with a reason and the byte offset where the frame went wrong.
//
// Versioning: a reader accepts the same major version and any minor version. A minor version
// may only append fields at the end of a section body (a reader skips the bytes it does not
// know after the ones it does) and add section types (a reader skips an unknown type); a frame
// of a minor version not newer than the reader's must have no such extra bytes. Anything else
// is a new major version, which readers of the old one refuse.
//
// Units: SI, metres and newtons. Frames: "trainer" is the trainer frame (instruments,
// contacts, catheter particles); "model" is a scene model's own frame as its image stores it
// (node loads, tensor displacements), placed in the trainer frame by the scene's
// [[model]] position_m/rotation_deg.
//
// Everything here is noexcept and allocation-free; a Frame is large (tens of KiB) and meant to
// be held in static or long-lived storage, not on a small stack.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace trainer::telemetry {

inline constexpr std::array<std::uint8_t, 4> kMagic{'T', 'R', 'T', 'L'};
inline constexpr std::uint8_t kVersionMajor = 1;
inline constexpr std::uint8_t kVersionMinor = 1;  // 1.1: the session metrics section
inline constexpr std::size_t kHeaderBytes = 64;
inline constexpr std::size_t kSectionHeaderBytes = 4;

// Fixed capacities (the sender checks a scene against them at configure time).
inline constexpr std::size_t kMaxModels = 4;             // scene models (app::kMaxSceneModels)
inline constexpr std::size_t kMaxModes = 256;            // modal coordinates per modal model
inline constexpr std::size_t kMaxLoads = 64;             // ModalModel::kMaxLoadedNodes
inline constexpr std::size_t kMaxTensorContacts = 64;    // TensorModel::kMaxContactsLimit
inline constexpr std::size_t kMaxParticles = 256;        // model::kMaxCatheterParticles
inline constexpr std::size_t kMaxInstruments = 4;        // app::kMaxInstruments
inline constexpr std::size_t kMaxContacts = 16;          // contact points per frame
inline constexpr std::uint32_t kMaxNodeIndex = 0xFFFF;   // node indices travel as u16
// UDP's largest payload over IPv4; no frame may exceed it (the capacities above keep a
// frame below it).
inline constexpr std::size_t kMaxDatagramBytes = 65507;

// Section types (the section header's first byte).
enum class SectionType : std::uint8_t {
  modal = 1,        // index: scene model index
  tensor = 2,       // index: scene model index
  catheter = 3,     // index: scene model index
  instrument = 16,  // index: instrument index (scene [[instrument]] order)
  contacts = 17,    // index: 0; at most one per frame
  metrics = 18,     // index: 0; at most one per frame (since 1.1)
};

// Frame flags (header offset 60).
enum FrameFlag : std::uint32_t {
  kFlagNonFiniteReplaced = 1U << 0,  // the sender replaced a NaN/inf by 0 somewhere
  kFlagContactsTruncated = 1U << 1,  // more contact points than kMaxContacts: the largest kept
  kFlagRunEnded = 1U << 2,           // the appliance's loop has stopped; the last frame
};

// Modal section flags.
enum ModalFlag : std::uint8_t {
  kModalStaticCorrection = 1U << 0,  // the model adds R·F of `loads` (the image has R)
  kModalLoadsTruncated = 1U << 1,    // more loaded nodes than fit: the largest kept
};

// Instrument flags.
enum InstrumentFlag : std::uint8_t {
  kInstrumentTissueContact = 1U << 0,  // a soft-tissue model holds the tip
  kInstrumentGrasping = 1U << 1,       // the jaws hold a catheter
  kInstrumentWallContact = 1U << 2,    // the shaft or a jaw presses a duct wall
  kInstrumentCatheterContact = 1U << 3,
};

enum class ModelKind : std::uint8_t { modal = 1, tensor = 2, catheter = 3 };

// A nodal force (N, model frame) acting in the last step; with static correction the host
// adds Σ R_{n,l} F_l to Φ q (ModalModel::displacement).
struct NodeLoad {
  std::uint32_t node = 0;  // ≤ kMaxNodeIndex
  std::array<float, 3> force_n{};
};

// A tensor model's imposed displacement (m, model frame, from rest) at one contact node; the
// host gets the field by TensorModel::solve() on these and update_field().
struct TensorDisplacement {
  std::uint32_t node = 0;  // ≤ kMaxNodeIndex
  std::array<float, 3> displacement_m{};
};

struct ModelState {
  ModelKind kind = ModelKind::modal;
  std::uint8_t scene_index = 0;       // the scene's [[model]] order
  std::uint8_t flags = 0;             // ModalFlag (modal models; 0 otherwise)
  std::uint64_t image_checksum = 0;   // the image header's XXH64
  // modal: modal coordinates q (kg^1/2·m) of the active modes, and the last step's loads.
  std::uint32_t mode_count = 0;
  std::array<float, kMaxModes> modal_coordinates{};
  std::uint32_t load_count = 0;
  std::array<NodeLoad, kMaxLoads> loads{};
  // tensor: imposed contact displacements of the last accepted solve.
  std::uint32_t contact_count = 0;
  std::array<TensorDisplacement, kMaxTensorContacts> contacts{};
  // catheter: particle positions (m, trainer frame), proximal end first.
  std::uint32_t particle_count = 0;
  std::array<std::array<float, 3>, kMaxParticles> particles_m{};
};

// Enough to draw shaft and jaws (trainer frame): the shaft runs shaft_start → hinge; with
// L = |tip − hinge| and d = (tip − hinge)/L, jaw k runs from the hinge to
// hinge + L (cos(g/2) d ± sin(g/2) n), g = grip_rad, n = opening_direction, + for jaw 0.
struct InstrumentState {
  std::uint8_t flags = 0;  // InstrumentFlag
  float grip_rad = 0.0F;   // jaw opening, 0 = closed
  std::array<float, 3> tip_m{};          // closed-jaw tip
  std::array<float, 3> hinge_m{};        // jaw hinge, end of the rigid shaft
  std::array<float, 3> shaft_start_m{};  // handle end of the shaft (outside the body)
  std::array<float, 3> opening_direction{};  // unit, ⟂ shaft; jaw 0 opens toward it
  std::array<float, 3> force_n{};        // commanded force on the tool after the safety chain
};

enum class ContactKind : std::uint8_t {
  tip = 0,       // the tip against a soft-tissue model
  shaft = 1,     // a point force on the shaft
  jaw0 = 2,
  jaw1 = 3,
};
inline constexpr std::uint8_t kNoModel = 0xFF;

struct ContactPoint {
  std::uint8_t instrument = 0;
  std::uint8_t model = kNoModel;  // scene model index, kNoModel when not attributed
  ContactKind kind = ContactKind::tip;
  std::array<float, 3> point_m{};  // trainer frame
  std::array<float, 3> force_n{};  // on the tissue (the tool feels the opposite), trainer frame
};

// The session's trainee metrics so far (docs/metrics.md; rt/metrics SessionResult), for the
// graphics host's session panel. Times in s, lengths in m, forces in N.
enum MetricsFlag : std::uint8_t {
  kMetricsTaskStarted = 1U << 0,
  kMetricsTaskCompleted = 1U << 1,
  kMetricsInsertionGoal = 1U << 2,   // the scene has an insertion target (depth fields valid)
  kMetricsTargetReached = 1U << 3,   // time_to_target_s valid
};
struct InstrumentMetrics {
  float path_length_m = 0.0F;
  float idle_time_s = 0.0F;
  float peak_force_n = 0.0F;         // force on tissue
  float mean_contact_force_n = 0.0F;
  float time_above_safe_s = 0.0F;
  std::uint16_t movements = 0;
  std::uint16_t grasps = 0;
  std::uint16_t slips = 0;
};
struct SessionMetrics {
  std::uint8_t flags = 0;  // MetricsFlag
  float session_time_s = 0.0F;
  float task_time_s = 0.0F;
  float time_above_safe_s = 0.0F;
  float damage_impulse_n_s = 0.0F;
  float insertion_depth_m = 0.0F;  // deepest reached
  float time_to_target_s = 0.0F;
  std::uint8_t instrument_count = 0;
  std::array<InstrumentMetrics, kMaxInstruments> instruments{};
};

struct Frame {
  std::uint32_t stream_id = 0;   // chosen by the sender at start; a new id restarts sequencing
  std::uint64_t sequence = 0;    // +1 per frame sent in a stream
  std::uint64_t cycle = 0;       // haptic cycle index of the snapshot
  std::int64_t cycle_time_ns = 0;   // the cycle's wake-up, appliance CLOCK_MONOTONIC
  std::int64_t send_time_ns = 0;    // when the frame was encoded, appliance CLOCK_MONOTONIC
  std::int64_t send_wall_ns = 0;    // the same instant, appliance CLOCK_REALTIME
  std::uint32_t latched_faults = 0; // safety::Fault bits
  std::uint32_t flags = 0;          // FrameFlag
  std::uint32_t model_count = 0;
  std::array<ModelState, kMaxModels> models{};  // ascending scene_index
  std::uint32_t instrument_count = 0;
  std::array<InstrumentState, kMaxInstruments> instruments{};
  std::uint32_t contact_count = 0;
  std::array<ContactPoint, kMaxContacts> contacts{};
  bool has_metrics = false;  // the metrics section is present
  SessionMetrics metrics{};
};

// ---- Encoding ----

struct EncodeResult {
  std::size_t bytes = 0;      // written; 0 on error
  const char* error = "";     // static literal, "" when ok
  bool ok() const noexcept { return bytes != 0; }
};

// Bytes encode() writes for `frame` (0 when a count is beyond its capacity).
std::size_t encoded_size(const Frame& frame) noexcept;

// Writes `frame` into `out`. Refuses (nothing usable written): a count beyond its capacity,
// a node index above kMaxNodeIndex, models not in ascending scene_index order, more than 255
// instruments' index, `out` too small. Non-finite floats are written as 0 and the frame's
// kFlagNonFiniteReplaced set (in the bytes; `frame` is not modified).
EncodeResult encode(const Frame& frame, std::span<std::byte> out) noexcept;

// ---- Decoding ----

enum class DecodeError : std::uint8_t {
  none = 0,
  too_short,            // fewer bytes than a header
  too_long,             // more than kMaxDatagramBytes
  bad_magic,
  unsupported_version,  // another major version
  length_mismatch,      // the header's length is not the datagram's
  bad_checksum,         // CRC-32 mismatch
  truncated_section,    // a section header or body runs past the end
  bad_section,          // a body's size disagrees with its counts, or extra bytes not allowed
  capacity_exceeded,    // a count beyond the fixed capacities
  bad_index,            // duplicate/out-of-order model or instrument, index out of range
  non_finite,           // a NaN or infinity
  bad_value,            // an enumeration or flag value this version does not define
};
const char* to_string(DecodeError error) noexcept;

struct DecodeResult {
  DecodeError error = DecodeError::none;
  std::size_t offset = 0;   // byte where the frame went wrong
  const char* detail = "";  // static literal naming the field
  bool ok() const noexcept { return error == DecodeError::none; }
};

// Decodes one datagram into `out` (overwritten; on error its content is unspecified).
DecodeResult decode(std::span<const std::byte> bytes, Frame& out) noexcept;

// The frame's model with this scene index, or nullptr.
const ModelState* find_model(const Frame& frame, std::uint8_t scene_index) noexcept;

// CRC-32 (IEEE 802.3, reflected, init and final xor 0xFFFFFFFF) as the header uses it.
std::uint32_t crc32(std::span<const std::byte> bytes) noexcept;

}  // namespace trainer::telemetry
