// The model image format, version 1: the on-disk layout shared by the offline writer
// (trainer::model::offline::ImageWriter) and the runtime loader (load_model_image). Owns the
// magic, version, header and section-table records, the section ids with their element types,
// the metadata record, the catheter's parameter record and the checksum definition.
// docs/model-image.md is the prose spec; this header is its single source of truth in code.
//
// Layout: [128-byte header][section table: section_count × 32 bytes][sections, each starting
// at a multiple of 64 bytes, zero padding between]. All integers and floats little-endian;
// the runtime views sections in place, so this build only targets little-endian hosts.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace trainer::model {

static_assert(std::endian::native == std::endian::little,
              "model images are little-endian and viewed in place: port the loader first");

inline constexpr char kImageMagic[8] = {'H', 'T', 'R', 'M', 'O', 'D', 'E', 'L'};
inline constexpr std::uint32_t kImageFormatVersion = 1;
inline constexpr std::uint32_t kImageHeaderBytes = 128;
// Read back as this value only when writer and reader agree on byte order.
inline constexpr std::uint32_t kImageByteOrderMark = 0x01020304U;
inline constexpr std::uint32_t kImageMaxSections = 32;
inline constexpr std::uint32_t kImageSectionEntryBytes = 32;
// Every section starts at a multiple of this (cache line; also core::Arena::kAlignment).
inline constexpr std::uint32_t kImageSectionAlignment = 64;

enum class ModelKind : std::uint32_t {
  modal_shell = 1,  // reduced-modal shell FEM (the duct), METHODS.md §1
  tet_tensor = 2,   // precomputed tetrahedral tensor model (the liver), METHODS.md §3
  catheter = 3,     // particle catheter (chain of springs), METHODS.md §2, docs/catheter.md
};

// Scalar type of a section's elements.
enum class ElementType : std::uint32_t {
  f32 = 1,
  u32 = 2,
  i32 = 3,
  u8 = 4,
};

// Finite element the model was built from (metadata field, informational).
enum class FiniteElementType : std::uint32_t {
  none = 0,
  shell_rao = 1,  // membrane + Rao 9-term cubic plate (the paper's element)
  shell_dkt = 2,  // membrane + discrete Kirchhoff triangle
  tet4 = 3,       // linear tetrahedron
};

// Section ids. Values are part of the format: never renumber, only add.
enum class SectionId : std::uint32_t {
  metadata = 1,  // u8, exactly sizeof(ImageMetadataV1) bytes

  // Modal shell (10-29).
  rest_positions = 10,       // f32, n × 3, m, one row per node
  triangles = 11,            // u32, m × 3, node indices, three distinct per row
  fixed_nodes = 12,          // u32, k × 1, strictly increasing node indices (clamped nodes)
  surface_nodes = 13,        // u32, s × 1, strictly increasing node indices (contactable)
  mode_shapes = 20,          // f32, 3n × r, row-major, row = node*3 + axis, M-orthonormal
  omega_squared = 21,        // f32, r × 1, rad²/s², ascending, >= 0
  modal_damping = 22,        // f32, r × 1, 1/s: α_i in ẍ + α_i ẋ + ω_i² x = f, >= 0
  residual_compliance = 23,  // f32, 3s × 3s, m/N, symmetric, full storage, surface-node order

  // Tetrahedral tensor model (30-49). It also uses rest_positions, triangles (its boundary
  // faces), fixed_nodes and surface_nodes (the nodes a tool may displace: s "contact nodes").
  // r = rows of tensor_nodes.
  tensor_displacement = 30,  // f32, (s·r) × 9: row k·r + j = T(node tensor_nodes[j], contact k),
                             // a 3×3 row-major, m/m: displacement of that node per unit
                             // displacement imposed at contact node k (T(k, k) = I)
  tensor_force = 31,         // f32, s × 9: F(k), 3×3 row-major, symmetric, N/m: force at contact
                             // node k per unit displacement imposed there
  tensor_nodes = 32,         // u32, r × 1, strictly increasing: the nodes whose response is stored
                             // (the boundary, or every node); contains every surface node

  // Particle catheter (50-69). Only these two and the metadata.
  catheter_parameters = 50,      // u8, exactly sizeof(CatheterParametersV1) bytes: the record
  catheter_rest_positions = 51,  // f32, N × 3, m: particle i at rest, trainer frame
};

// The fixed 128-byte header at offset 0. Plain little-endian record, read with memcpy.
struct ImageHeaderV1 {
  char magic[8];                       // kImageMagic, not NUL-terminated
  std::uint32_t format_version;        // kImageFormatVersion
  std::uint32_t header_bytes;          // kImageHeaderBytes
  std::uint32_t byte_order_mark;       // kImageByteOrderMark
  std::uint32_t model_kind;            // ModelKind
  std::uint64_t file_bytes;            // total file length
  std::uint32_t section_count;         // <= kImageMaxSections
  std::uint32_t section_table_offset;  // == kImageHeaderBytes
  std::uint64_t checksum;              // XXH64, seed 0, of the file with these 8 bytes zeroed
  std::uint8_t reserved[80];           // zero
};
static_assert(sizeof(ImageHeaderV1) == kImageHeaderBytes);
static_assert(offsetof(ImageHeaderV1, format_version) == 8);
static_assert(offsetof(ImageHeaderV1, byte_order_mark) == 16);
static_assert(offsetof(ImageHeaderV1, model_kind) == 20);
static_assert(offsetof(ImageHeaderV1, file_bytes) == 24);
static_assert(offsetof(ImageHeaderV1, section_count) == 32);
static_assert(offsetof(ImageHeaderV1, section_table_offset) == 36);
static_assert(offsetof(ImageHeaderV1, checksum) == 40);
inline constexpr std::size_t kImageChecksumOffset = offsetof(ImageHeaderV1, checksum);

// One 32-byte section-table entry.
struct SectionEntryV1 {
  std::uint32_t id;             // SectionId, unique in the table
  std::uint32_t element_type;   // ElementType, must match section_element_type(id)
  std::uint64_t offset;         // bytes from file start, multiple of 64, after the table
  std::uint64_t element_count;  // == rows * cols
  std::uint32_t rows;
  std::uint32_t cols;  // lists are rows = count, cols = 1
};
static_assert(sizeof(SectionEntryV1) == kImageSectionEntryBytes);
static_assert(offsetof(SectionEntryV1, offset) == 8);
static_assert(offsetof(SectionEntryV1, element_count) == 16);
static_assert(offsetof(SectionEntryV1, rows) == 24);

// Content of SectionId::metadata: what the model was built from and for. Explicit padding so
// the layout has no compiler-dependent holes; reserved bytes must be zero.
struct ImageMetadataV1 {
  std::uint64_t source_mesh_hash;  // XXH64 of the source mesh (file or generator parameters)
  double young_modulus_pa;
  double poisson_ratio;
  double thickness_m;  // shell thickness; 0 for solid models
  double density_kg_per_m3;
  std::uint32_t element_type;        // FiniteElementType
  std::uint32_t mode_count;          // r (0 for non-modal models)
  std::uint32_t node_count;          // n
  std::uint32_t surface_node_count;  // s
  double time_step_s;                // the haptic step the image was prepared for (0 = any)
  double damping_ratio;              // modal ζ used to derive modal_damping
  double error_estimate;             // relative error of the reduction; NaN = not measured
  double error_budget;               // the budget it was built against; NaN = none
  std::uint32_t static_correction;   // 1 = residual_compliance present, 0 = absent
  std::uint32_t padding0;            // zero
  std::uint64_t created_unix_s;
  char tool_version[32];       // NUL-terminated, e.g. "modelc 0.1.0"
  std::uint8_t reserved[120];  // zero
};
static_assert(sizeof(ImageMetadataV1) == 256);
static_assert(offsetof(ImageMetadataV1, element_type) == 40);
static_assert(offsetof(ImageMetadataV1, time_step_s) == 56);
static_assert(offsetof(ImageMetadataV1, static_correction) == 88);
static_assert(offsetof(ImageMetadataV1, created_unix_s) == 96);
static_assert(offsetof(ImageMetadataV1, tool_version) == 104);
static_assert(offsetof(ImageMetadataV1, reserved) == 136);

// Content of SectionId::catheter_parameters: everything model::Catheter needs besides its
// rest positions, in the precision the runtime stores it (float), so the trainer runs exactly
// the constants modelc derived (model::derive_catheter_chain, docs/catheter.md). The record has
// its own version, checked before anything else in it: a change to this record is a new
// record_version (the container's format_version stays), and a loader refuses every version
// but its own. Reserved bytes must be zero. Version 3 (same layout): stable_substep_s is the
// largest substep of the integrator with implicit bending and contacts (2/ω_r, docs/catheter.md);
// version 2's was the explicit bending's and contacts', version 1's the explicit axial springs'.
inline constexpr std::uint32_t kCatheterRecordVersion = 3;
struct CatheterParametersV1 {
  std::uint32_t record_version;  // kCatheterRecordVersion
  std::uint32_t particle_count;  // N, 3..Catheter::kMaxParticles
  std::uint32_t max_substeps;    // substep budget of one haptic period, 1..kMaxCatheterSubsteps
  std::uint32_t hold_start;      // 1 = clamped start (particle 0 and root tangent held), 0 = free
  // The chain (model::CatheterChain).
  float rest_length_m;                  // l0 = L/(N−1)
  float particle_mass_kg;               // m = ρ_l L / N
  float axial_stiffness_n_per_m;        // k_s = EA / l0
  float bending_stiffness_n_m_per_rad;  // k_b = EI / l0
  float radius_m;                       // outer radius: each particle's sphere in contact
  float damping_n_s_per_m;              // b per particle, >= 0
  float stable_substep_s;               // largest substep (the period is the scene's)
  // Placement (the definition's [pose]).
  float rest_direction[3];   // unit rest tangent: the clamped root's hinge direction
  float gravity_m_per_s2[3];  // applied by the trainer as m·g on every particle
  // The physical parameters the chain was derived from (provenance and messages).
  float length_m;                 // L
  float bending_stiffness_n_m2;   // EI
  float axial_stiffness_n;        // EA
  float linear_density_kg_per_m;  // ρ_l
  // The definition's [contact]: the catheter against walls and forceps (used by the trainer).
  float wall_stiffness_n_per_m;
  float wall_damping_n_s_per_m;
  float tool_stiffness_n_per_m;
  float grasp_stiffness_n_per_m;
  float grasp_friction;
  float max_contact_force_n;
  std::uint8_t reserved[20];  // zero
};
static_assert(sizeof(CatheterParametersV1) == 128);
static_assert(offsetof(CatheterParametersV1, rest_length_m) == 16);  // the groups' starts
static_assert(offsetof(CatheterParametersV1, rest_direction) == 44);
static_assert(offsetof(CatheterParametersV1, length_m) == 68);
static_assert(offsetof(CatheterParametersV1, reserved) == 108);

// What the format says about one section id.
struct SectionDescriptor {
  SectionId id;
  const char* name;          // snake_case, used in every message
  ElementType element_type;  // the only element type allowed for this id
  // Model kinds the section may appear in: bit (1 << kind) per kind (owner_bit()). The
  // metadata belongs to every kind; geometry and node lists are shared by the two mesh kinds.
  std::uint32_t owners;
  // Column count the id fixes (lists have 1, positions and triangles 3); 0 = set by the model.
  std::uint32_t required_cols;
};

constexpr std::uint32_t owner_bit(ModelKind kind) noexcept {
  return 1U << static_cast<std::uint32_t>(kind);
}
constexpr bool section_belongs_to(const SectionDescriptor& descriptor, ModelKind kind) noexcept {
  return (descriptor.owners & owner_bit(kind)) != 0U;
}

// nullptr for an id this build does not know.
const SectionDescriptor* find_section_descriptor(std::uint32_t id) noexcept;
// "unknown" for an id this build does not know.
const char* section_name(SectionId id) noexcept;
const char* model_kind_name(ModelKind kind) noexcept;
// The kinds a section belongs to, e.g. "modal_shell" or "modal_shell and tet_tensor" (for
// error messages; allocates).
std::string owners_text(const SectionDescriptor& descriptor);
// Bytes per element; 0 for an unknown type.
std::size_t element_type_bytes(std::uint32_t element_type) noexcept;
bool is_known_model_kind(std::uint32_t kind) noexcept;

// XXH64 (seed 0) of `file` with the 8 checksum bytes at kImageChecksumOffset taken as zero,
// without modifying `file`. `file` must be at least kImageHeaderBytes long (else returns 0).
std::uint64_t compute_image_checksum(std::span<const std::byte> file) noexcept;

}  // namespace trainer::model
