// Section descriptor table and the checksum of the model image format (image_format.hpp).
#include "trainer/model/image_format.hpp"

#include <array>

// The static-linking API exposes XXH64_state_t's layout so the state can live on the stack
// (the streaming API then never allocates).
#define XXH_STATIC_LINKING_ONLY
#include <xxhash.h>

namespace trainer::model {

namespace {

// clang-format off
constexpr std::uint32_t kModal = owner_bit(ModelKind::modal_shell);
constexpr std::uint32_t kTensor = owner_bit(ModelKind::tet_tensor);
constexpr std::uint32_t kCatheter = owner_bit(ModelKind::catheter);
constexpr std::uint32_t kBoth = kModal | kTensor;  // the two mesh kinds
constexpr std::uint32_t kEvery = kBoth | kCatheter;

constexpr std::array<SectionDescriptor, 14> kSectionDescriptors = {{
  {SectionId::metadata,                "metadata",                ElementType::u8,  kEvery,    1},
  {SectionId::rest_positions,          "rest_positions",          ElementType::f32, kBoth,     3},
  {SectionId::triangles,               "triangles",               ElementType::u32, kBoth,     3},
  {SectionId::fixed_nodes,             "fixed_nodes",             ElementType::u32, kBoth,     1},
  {SectionId::surface_nodes,           "surface_nodes",           ElementType::u32, kBoth,     1},
  {SectionId::mode_shapes,             "mode_shapes",             ElementType::f32, kModal,    0},
  {SectionId::omega_squared,           "omega_squared",           ElementType::f32, kModal,    1},
  {SectionId::modal_damping,           "modal_damping",           ElementType::f32, kModal,    1},
  {SectionId::residual_compliance,     "residual_compliance",     ElementType::f32, kModal,    0},
  {SectionId::tensor_displacement,     "tensor_displacement",     ElementType::f32, kTensor,   9},
  {SectionId::tensor_force,            "tensor_force",            ElementType::f32, kTensor,   9},
  {SectionId::tensor_nodes,            "tensor_nodes",            ElementType::u32, kTensor,   1},
  {SectionId::catheter_parameters,     "catheter_parameters",     ElementType::u8,  kCatheter, 1},
  {SectionId::catheter_rest_positions, "catheter_rest_positions", ElementType::f32, kCatheter, 3},
}};
// clang-format on

}  // namespace

const SectionDescriptor* find_section_descriptor(std::uint32_t id) noexcept {
  for (const SectionDescriptor& descriptor : kSectionDescriptors) {
    if (static_cast<std::uint32_t>(descriptor.id) == id) return &descriptor;
  }
  return nullptr;
}

const char* section_name(SectionId id) noexcept {
  const SectionDescriptor* descriptor = find_section_descriptor(static_cast<std::uint32_t>(id));
  return descriptor != nullptr ? descriptor->name : "unknown";
}

std::string owners_text(const SectionDescriptor& descriptor) {
  std::string text;
  for (const ModelKind kind :
       {ModelKind::modal_shell, ModelKind::tet_tensor, ModelKind::catheter}) {
    if (!section_belongs_to(descriptor, kind)) continue;
    if (!text.empty()) text.append(" and ");
    text.append(model_kind_name(kind));
  }
  return text;
}

const char* model_kind_name(ModelKind kind) noexcept {
  switch (kind) {
    case ModelKind::modal_shell: return "modal_shell";
    case ModelKind::tet_tensor: return "tet_tensor";
    case ModelKind::catheter: return "catheter";
  }
  return "unknown";
}

std::size_t element_type_bytes(std::uint32_t element_type) noexcept {
  switch (static_cast<ElementType>(element_type)) {
    case ElementType::f32: return sizeof(float);
    case ElementType::u32: return sizeof(std::uint32_t);
    case ElementType::i32: return sizeof(std::int32_t);
    case ElementType::u8: return sizeof(std::uint8_t);
  }
  return 0;
}

bool is_known_model_kind(std::uint32_t kind) noexcept {
  return kind == static_cast<std::uint32_t>(ModelKind::modal_shell) ||
         kind == static_cast<std::uint32_t>(ModelKind::tet_tensor) ||
         kind == static_cast<std::uint32_t>(ModelKind::catheter);
}

std::uint64_t compute_image_checksum(std::span<const std::byte> file) noexcept {
  if (file.size() < kImageHeaderBytes) return 0;
  constexpr std::array<std::byte, sizeof(std::uint64_t)> kZeroChecksum{};
  XXH64_state_t state;
  XXH64_reset(&state, 0);
  XXH64_update(&state, file.data(), kImageChecksumOffset);
  XXH64_update(&state, kZeroChecksum.data(), kZeroChecksum.size());
  const std::size_t after = kImageChecksumOffset + kZeroChecksum.size();
  XXH64_update(&state, file.data() + after, file.size() - after);
  return XXH64_digest(&state);
}

}  // namespace trainer::model
