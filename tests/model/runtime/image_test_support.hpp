// Shared fixtures for the model image tests: a small but complete model of each kind (modal
// shell, tet tensor, catheter), an independent raw image builder (so loader checks can be
// exercised with images the writer would refuse to produce), byte patching with an
// independently computed checksum, the damage every image must survive (each header field
// broken, a byte flipped in each section), and temporary files.
#pragma once

#include <xxhash.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model_offline/catheter_image.hpp"
#include "trainer/model_offline/image_writer.hpp"

namespace trainer::model::test {

// A square of 4 nodes split into 2 triangles, node 0 clamped, nodes 1 and 2 contactable,
// 2 modes. Values are arbitrary but distinct, and most are not exactly representable in
// float32, so the round trip also checks the double → float conversion.
struct SmallModalShell {
  static constexpr std::uint32_t kNodeCount = 4;
  static constexpr std::uint32_t kModeCount = 2;
  static constexpr std::uint32_t kSurfaceNodeCount = 2;

  Eigen::MatrixXd rest_positions_m;  // 4 × 3
  Eigen::MatrixXi triangles;         // 2 × 3
  std::vector<std::uint32_t> fixed_nodes{0};
  std::vector<std::uint32_t> surface_nodes{1, 2};
  Eigen::MatrixXd mode_shapes;  // 12 × 2
  std::vector<double> omega_squared{100.5, 2500.25};
  std::vector<double> modal_damping{0.3, 1.2};
  Eigen::MatrixXd residual_compliance;  // 6 × 6, symmetric
  ImageMetadataV1 metadata{};

  SmallModalShell() {
    rest_positions_m.resize(kNodeCount, 3);
    rest_positions_m << 0.0, 0.0, 0.0,  //
        0.01, 0.0, 0.0,                 //
        0.01, 0.01, 0.001,              //
        0.0, 0.01, -0.002;
    triangles.resize(2, 3);
    triangles << 0, 1, 2,  //
        0, 2, 3;
    mode_shapes.resize(3 * kNodeCount, kModeCount);
    for (Eigen::Index row = 0; row < mode_shapes.rows(); ++row) {
      for (Eigen::Index col = 0; col < mode_shapes.cols(); ++col) {
        mode_shapes(row, col) = 0.1 * static_cast<double>(row) - 0.37 * static_cast<double>(col);
      }
    }
    residual_compliance.resize(3 * kSurfaceNodeCount, 3 * kSurfaceNodeCount);
    for (Eigen::Index row = 0; row < residual_compliance.rows(); ++row) {
      for (Eigen::Index col = 0; col < residual_compliance.cols(); ++col) {
        residual_compliance(row, col) =
            1e-4 / static_cast<double>(1 + row + col) + (row == col ? 1e-3 : 0.0);
      }
    }
    metadata = offline::make_metadata();
    metadata.source_mesh_hash = 0x0123456789ABCDEFULL;
    metadata.young_modulus_pa = 1.2e5;
    metadata.poisson_ratio = 0.45;
    metadata.thickness_m = 4e-4;
    metadata.density_kg_per_m3 = 1050.0;
    metadata.element_type = static_cast<std::uint32_t>(FiniteElementType::shell_dkt);
    metadata.mode_count = kModeCount;
    metadata.node_count = kNodeCount;
    metadata.surface_node_count = kSurfaceNodeCount;
    metadata.time_step_s = 1e-3;
    metadata.damping_ratio = 0.05;
    metadata.error_estimate = 0.0123;
    metadata.static_correction = 1;
    metadata.created_unix_s = 1700000000;
    EXPECT_TRUE(offline::set_tool_version(metadata, "modelc test 1.2.3"));
  }

  // A writer holding every modal-shell section; fails the test if any add is refused.
  offline::ImageWriter writer() const {
    offline::ImageWriter image_writer(ModelKind::modal_shell);
    image_writer.set_metadata(metadata);
    expect_ok(image_writer.add_f32(SectionId::rest_positions, rest_positions_m));
    expect_ok(image_writer.add_u32(SectionId::triangles, triangles));
    expect_ok(image_writer.add_u32(SectionId::fixed_nodes, fixed_nodes,
                                   static_cast<std::uint32_t>(fixed_nodes.size()), 1));
    expect_ok(image_writer.add_u32(SectionId::surface_nodes, surface_nodes,
                                   static_cast<std::uint32_t>(surface_nodes.size()), 1));
    expect_ok(image_writer.add_f32(SectionId::mode_shapes, mode_shapes));
    expect_ok(image_writer.add_f32(SectionId::omega_squared, omega_squared, kModeCount, 1));
    expect_ok(image_writer.add_f32(SectionId::modal_damping, modal_damping, kModeCount, 1));
    expect_ok(image_writer.add_f32(SectionId::residual_compliance, residual_compliance));
    return image_writer;
  }

  std::vector<std::byte> bytes() const {
    auto serialized = writer().serialize();
    EXPECT_TRUE(serialized) << serialized.error().message;
    return serialized ? serialized.value() : std::vector<std::byte>{};
  }

  static void expect_ok(const core::Expected<void>& result) {
    EXPECT_TRUE(result) << result.error().message;
  }
};

// ---- byte access and patching (little-endian host, as the format) ----

template <class T>
T get(const std::vector<std::byte>& bytes, std::size_t offset) {
  T value{};
  if (offset > bytes.size() || sizeof value > bytes.size() - offset) {
    ADD_FAILURE() << "read of " << sizeof value << " bytes at " << offset << " past the end ("
                  << bytes.size() << " bytes)";
    return value;
  }
  std::memcpy(&value, &bytes[offset], sizeof value);
  return value;
}

template <class T>
void put(std::vector<std::byte>& bytes, std::size_t offset, T value) {
  if (offset > bytes.size() || sizeof value > bytes.size() - offset) {
    ADD_FAILURE() << "write of " << sizeof value << " bytes at " << offset << " past the end ("
                  << bytes.size() << " bytes)";
    return;
  }
  std::memcpy(&bytes[offset], &value, sizeof value);
}

// Recomputes the header checksum the plain way (zero the field, hash everything), which is
// independent of the loader's streaming computation.
inline void recompute_checksum(std::vector<std::byte>& bytes) {
  put<std::uint64_t>(bytes, kImageChecksumOffset, 0);
  put<std::uint64_t>(bytes, kImageChecksumOffset, XXH64(bytes.data(), bytes.size(), 0));
}

// Byte position of the table entry for `id`; fails the test when absent.
inline std::size_t entry_position(const std::vector<std::byte>& bytes, SectionId id) {
  const auto count = get<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_count));
  for (std::uint32_t i = 0; i < count; ++i) {
    const std::size_t position = kImageHeaderBytes + std::size_t{i} * kImageSectionEntryBytes;
    if (get<std::uint32_t>(bytes, position) == static_cast<std::uint32_t>(id)) return position;
  }
  ADD_FAILURE() << "no table entry for section " << section_name(id);
  return kImageHeaderBytes;
}

inline SectionEntryV1 entry_of(const std::vector<std::byte>& bytes, SectionId id) {
  return get<SectionEntryV1>(bytes, entry_position(bytes, id));
}

inline void put_entry(std::vector<std::byte>& bytes, SectionId id, const SectionEntryV1& entry) {
  put(bytes, entry_position(bytes, id), entry);
}

// The smallest consistent tet_tensor image: one tetrahedron (nodes 0..3), node 0 fixed, node 3
// the only contact node, responses stored for nodes 1..3. T(1,3) and T(2,3) are arbitrary,
// T(3,3) = I as the format requires, F(3) symmetric positive.
struct SmallTetTensor {
  Eigen::MatrixXd rest_positions_m{{0.0, 0.0, 0.0}, {0.01, 0.0, 0.0}, {0.0, 0.01, 0.0},
                                   {0.0, 0.0, 0.01}};
  Eigen::MatrixXi triangles{{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  std::vector<std::uint32_t> fixed_nodes{0};
  std::vector<std::uint32_t> contact_nodes{3};
  std::vector<std::uint32_t> stored_nodes{1, 2, 3};
  // 3 × 9: one row per stored node, T row-major.
  Eigen::MatrixXd displacement_tensors{{0.11, 0.02, 0.03, 0.04, 0.15, 0.06, 0.07, 0.08, 0.19},
                                       {0.21, 0.01, 0.0, 0.0, 0.22, 0.01, 0.02, 0.0, 0.23},
                                       {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}};
  std::vector<double> force_tensor{120.0, 3.0, 1.0, 3.0, 110.0, 2.0, 1.0, 2.0, 130.0};
  ImageMetadataV1 metadata{};

  SmallTetTensor() {
    metadata = offline::make_metadata();
    metadata.young_modulus_pa = 1.5e4;
    metadata.poisson_ratio = 0.45;
    metadata.density_kg_per_m3 = 1060.0;
    metadata.element_type = static_cast<std::uint32_t>(FiniteElementType::tet4);
    metadata.node_count = 4;
    metadata.surface_node_count = 1;
  }

  std::vector<std::byte> bytes() const {
    offline::ImageWriter writer(ModelKind::tet_tensor);
    writer.set_metadata(metadata);
    SmallModalShell::expect_ok(writer.add_f32(SectionId::rest_positions, rest_positions_m));
    SmallModalShell::expect_ok(writer.add_u32(SectionId::triangles, triangles));
    SmallModalShell::expect_ok(writer.add_u32(SectionId::fixed_nodes, fixed_nodes, 1, 1));
    SmallModalShell::expect_ok(writer.add_u32(SectionId::surface_nodes, contact_nodes, 1, 1));
    SmallModalShell::expect_ok(writer.add_u32(SectionId::tensor_nodes, stored_nodes, 3, 1));
    SmallModalShell::expect_ok(
        writer.add_f32(SectionId::tensor_displacement, displacement_tensors));
    SmallModalShell::expect_ok(writer.add_f32(SectionId::tensor_force, force_tensor, 1, 9));
    auto serialized = writer.serialize();
    EXPECT_TRUE(serialized) << serialized.error().message;
    return serialized ? serialized.value() : std::vector<std::byte>{};
  }
};

// A 5-particle catheter (6 cm of the default polymer catheter), placed off the axes along
// (0, 0.6, 0.8), clamped at its start, with gravity and every contact setting distinct.
struct SmallCatheter {
  static constexpr std::uint32_t kParticleCount = 5;
  offline::CatheterImageInputs inputs;

  SmallCatheter() {
    inputs.params.length_m = 0.06F;
    inputs.params.outer_radius_m = 1e-3F;
    inputs.params.bending_stiffness_n_m2 = 3.9e-5F;
    inputs.params.axial_stiffness_n = 157.0F;
    inputs.params.linear_density_kg_per_m = 1.65e-3F;
    inputs.params.damping_n_s_per_m = 5e-4F;
    inputs.params.particle_count = kParticleCount;
    inputs.start_m = Eigen::Vector3f(0.01F, -0.02F, 0.03F);
    inputs.direction = Eigen::Vector3f(0.0F, 3.0F, 4.0F);
    inputs.max_substeps = 64;
    inputs.hold_start = true;
    inputs.gravity_m_per_s2 = Eigen::Vector3f(0.0F, 0.0F, -9.81F);
    inputs.contact = {500.0F, 0.02F, 300.0F, 3000.0F, 0.6F, 4.0F};
    inputs.params.contact_stiffness_n_per_m = 500.0F;  // max(wall, tool): what modelc derives with
  }

  CatheterParametersV1 record() const {
    auto made = offline::make_catheter_record(inputs);
    EXPECT_TRUE(made) << made.error().message;
    return made ? made.value() : CatheterParametersV1{};
  }

  std::vector<std::byte> bytes() const {
    auto serialized = offline::serialize_catheter_image(inputs);
    EXPECT_TRUE(serialized) << serialized.error().message;
    return serialized ? serialized.value() : std::vector<std::byte>{};
  }
};

// ---- independent raw image builder ----

struct RawSection {
  std::uint32_t id = 0;
  std::uint32_t element_type = 0;
  std::uint32_t rows = 0;
  std::uint32_t cols = 0;
  std::vector<std::byte> payload;
};

template <class T>
RawSection raw_section(SectionId id, ElementType type, std::uint32_t rows, std::uint32_t cols,
                       const std::vector<T>& values) {
  RawSection section;
  section.id = static_cast<std::uint32_t>(id);
  section.element_type = static_cast<std::uint32_t>(type);
  section.rows = rows;
  section.cols = cols;
  section.payload.resize(values.size() * sizeof(T));
  if (!values.empty()) std::memcpy(section.payload.data(), values.data(), section.payload.size());
  return section;
}

inline RawSection raw_metadata(const ImageMetadataV1& metadata) {
  RawSection section;
  section.id = static_cast<std::uint32_t>(SectionId::metadata);
  section.element_type = static_cast<std::uint32_t>(ElementType::u8);
  section.rows = sizeof(ImageMetadataV1);
  section.cols = 1;
  section.payload.resize(sizeof(ImageMetadataV1));
  std::memcpy(section.payload.data(), &metadata, sizeof metadata);
  return section;
}

// Header, table in the given order, sections at the next 64-byte boundary, checksum.
inline std::vector<std::byte> build_raw_image(ModelKind kind,
                                              const std::vector<RawSection>& sections) {
  const std::size_t table_end = kImageHeaderBytes + sections.size() * kImageSectionEntryBytes;
  std::vector<std::size_t> offsets;
  std::size_t cursor = table_end;
  for (const RawSection& section : sections) {
    cursor = (cursor + 63) / 64 * 64;
    offsets.push_back(cursor);
    cursor += section.payload.size();
  }
  std::vector<std::byte> bytes(cursor, std::byte{0});
  std::memcpy(bytes.data(), "HTRMODEL", 8);
  put<std::uint32_t>(bytes, 8, 1);
  put<std::uint32_t>(bytes, 12, 128);
  put<std::uint32_t>(bytes, 16, 0x01020304U);
  put<std::uint32_t>(bytes, 20, static_cast<std::uint32_t>(kind));
  put<std::uint64_t>(bytes, 24, bytes.size());
  put<std::uint32_t>(bytes, 32, static_cast<std::uint32_t>(sections.size()));
  put<std::uint32_t>(bytes, 36, 128);
  for (std::size_t i = 0; i < sections.size(); ++i) {
    const std::size_t position = kImageHeaderBytes + i * kImageSectionEntryBytes;
    put<std::uint32_t>(bytes, position, sections[i].id);
    put<std::uint32_t>(bytes, position + 4, sections[i].element_type);
    put<std::uint64_t>(bytes, position + 8, offsets[i]);
    put<std::uint64_t>(bytes, position + 16,
                       std::uint64_t{sections[i].rows} * std::uint64_t{sections[i].cols});
    put<std::uint32_t>(bytes, position + 24, sections[i].rows);
    put<std::uint32_t>(bytes, position + 28, sections[i].cols);
    if (!sections[i].payload.empty()) {
      std::memcpy(bytes.data() + offsets[i], sections[i].payload.data(),
                  sections[i].payload.size());
    }
  }
  recompute_checksum(bytes);
  return bytes;
}

// ---- damage every image must survive ----

// One header field set to a value the loader must refuse, with a fragment of the refusal.
struct HeaderMutation {
  std::string field;
  std::function<void(std::vector<std::byte>&)> patch;
  std::string fragment;
  bool recompute_checksum = true;  // so the field's own check fires, not the checksum's
};

// Every field of the 128-byte header of a `file_bytes`-long image of `kind`, broken on its
// own: magic, format_version (older and newer), header_bytes, byte_order_mark (big-endian and
// garbage), model_kind (another known kind and an unknown one), file_bytes, section_count (0
// and above the maximum), section_table_offset, the checksum itself, a reserved byte.
inline std::vector<HeaderMutation> header_mutations(ModelKind kind, std::size_t file_bytes) {
  const auto set_u32 = [](std::size_t offset, std::uint32_t value) {
    return [offset, value](std::vector<std::byte>& bytes) {
      put<std::uint32_t>(bytes, offset, value);
    };
  };
  const ModelKind other =
      kind == ModelKind::modal_shell ? ModelKind::catheter : ModelKind::modal_shell;
  std::vector<HeaderMutation> mutations = {
      {"magic", [](std::vector<std::byte>& bytes) { std::memcpy(bytes.data(), "HTRMODEM", 8); },
       "not \"HTRMODEL\": not a model image"},
      {"format_version", set_u32(offsetof(ImageHeaderV1, format_version), 0),
       "image format version 0, this build reads 1: rebuild it with modelc"},
      {"format_version", set_u32(offsetof(ImageHeaderV1, format_version), 2),
       "image format version 2, this build reads 1: rebuild it with modelc"},
      {"header_bytes", set_u32(offsetof(ImageHeaderV1, header_bytes), 256),
       "header_bytes is 256, format version 1 has 128"},
      {"byte_order_mark", set_u32(offsetof(ImageHeaderV1, byte_order_mark), 0x04030201U),
       "the image was written big-endian"},
      {"byte_order_mark", set_u32(offsetof(ImageHeaderV1, byte_order_mark), 0xDEADBEEFU),
       "not a valid byte order mark"},
      {"model_kind",
       set_u32(offsetof(ImageHeaderV1, model_kind), static_cast<std::uint32_t>(other)),
       std::string("model_kind is ") + model_kind_name(other) + ", the scene expects " +
           model_kind_name(kind)},
      {"model_kind", set_u32(offsetof(ImageHeaderV1, model_kind), 7), "model_kind 7 is unknown"},
      {"file_bytes",
       [file_bytes](std::vector<std::byte>& bytes) {
         put<std::uint64_t>(bytes, offsetof(ImageHeaderV1, file_bytes), file_bytes - 64);
       },
       "header file_bytes is " + std::to_string(file_bytes - 64) + " but the file is " +
           std::to_string(file_bytes) + " bytes"},
      {"section_count", set_u32(offsetof(ImageHeaderV1, section_count), 0), "section_count is 0"},
      {"section_count", set_u32(offsetof(ImageHeaderV1, section_count), 33),
       "section_count 33 exceeds the format maximum of 32"},
      {"section_table_offset", set_u32(offsetof(ImageHeaderV1, section_table_offset), 192),
       "section_table_offset is 192"},
      {"checksum",
       [](std::vector<std::byte>& bytes) {
         put<std::uint64_t>(bytes, kImageChecksumOffset,
                            get<std::uint64_t>(bytes, kImageChecksumOffset) + 1);
       },
       "checksum mismatch: header says 0x", false},
      {"reserved",
       [](std::vector<std::byte>& bytes) {
         bytes[offsetof(ImageHeaderV1, reserved) + 7] = std::byte{1};
       },
       "header reserved byte " + std::to_string(offsetof(ImageHeaderV1, reserved) + 7) +
           " is not zero"},
  };
  return mutations;
}

// The image with `mutation` applied (and the checksum recomputed unless it is the mutation).
inline std::vector<std::byte> mutated(std::vector<std::byte> bytes,
                                      const HeaderMutation& mutation) {
  mutation.patch(bytes);
  if (mutation.recompute_checksum) recompute_checksum(bytes);
  return bytes;
}

// Every non-empty section of an image: its id and the position of the byte in its middle.
inline std::vector<std::pair<SectionId, std::size_t>> section_middle_bytes(
    const std::vector<std::byte>& bytes) {
  std::vector<std::pair<SectionId, std::size_t>> middles;
  const auto count = get<std::uint32_t>(bytes, offsetof(ImageHeaderV1, section_count));
  for (std::uint32_t i = 0; i < count; ++i) {
    const auto entry =
        get<SectionEntryV1>(bytes, kImageHeaderBytes + std::size_t{i} * kImageSectionEntryBytes);
    const std::size_t size = entry.element_count * element_type_bytes(entry.element_type);
    if (size > 0) middles.emplace_back(static_cast<SectionId>(entry.id), entry.offset + size / 2);
  }
  return middles;
}

// ---- files ----

// A fresh directory per test, removed afterwards.
class TemporaryDirectory {
 public:
  TemporaryDirectory() {
    std::string pattern = (std::filesystem::temp_directory_path() / "model_image_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) ADD_FAILURE() << "mkdtemp failed for " << pattern;
    path_ = pattern;
  }
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;
  ~TemporaryDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline void write_file(const std::filesystem::path& path, const std::vector<std::byte>& bytes,
                       std::size_t length) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(length));
  ASSERT_TRUE(out.good()) << "cannot write " << path;
}

inline void write_file(const std::filesystem::path& path, const std::vector<std::byte>& bytes) {
  write_file(path, bytes, bytes.size());
}

inline std::vector<std::byte> read_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> chars((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> bytes(chars.size());
  if (!chars.empty()) std::memcpy(bytes.data(), chars.data(), chars.size());
  return bytes;
}

// Passes when `result` failed with a message that starts with "<label>: " and contains
// `fragment`.
template <class T>
::testing::AssertionResult failed_with(const core::Expected<T>& result, std::string_view label,
                                       std::string_view fragment) {
  if (result) return ::testing::AssertionFailure() << "succeeded, expected \"" << fragment << "\"";
  const std::string& message = result.error().message;
  const std::string prefix = std::string(label) + ": ";
  if (message.rfind(prefix, 0) != 0) {
    return ::testing::AssertionFailure()
           << "message does not start with \"" << prefix << "\": " << message;
  }
  if (message.find(fragment) == std::string::npos) {
    return ::testing::AssertionFailure() << "message lacks \"" << fragment << "\": " << message;
  }
  return ::testing::AssertionSuccess() << message;
}

}  // namespace trainer::model::test
