// libFuzzer target: the model image loader (model/runtime image_loader.cpp) over arbitrary
// bytes, every model kind, through parse_model_image — the function load_model_image runs over
// the file once it has read it into its 64-byte-aligned arena block — and then what the
// trainer does next with an image it accepted (rt/app/src/models/*_setup.cpp): the runtime
// model built from the image's views, one step and one contact query on it, and for the two
// mesh kinds the contact surface's bucket grid over the rest shape.
//
// Input: byte 0 is the harness's control byte, the rest is the image file.
//   bits 0..1  the kind the "scene" expects: 0 = the one the header names (bytes 20..23,
//              1..3, modal_shell otherwise), 1 = modal_shell, 2 = tet_tensor, 3 = catheter
//   bit 2      keep the image's checksum as it is; otherwise the harness writes the XXH64 of
//              the mutated bytes into the header (bytes 40..47) first, so mutations get past
//              the integrity check to the parser behind it (the seeds carry control byte 0)
// Invariants besides ASan/UBSan and no hang (-timeout): a refused image has a message that
// starts with the file label and says more; an accepted one has the expected kind, a
// metadata section and views inside the image; the runtime model built from it either is
// created or refused with a message (the trainer would not arm), never crashes; its RT calls
// return a status. Counters of how far inputs get are printed at exit (TRAINER_FUZZ_STATS=1 or
// always at the end of a -runs run), so a run shows the parser is reached, not the checksum.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <span>
#include <string>
#include <string_view>

#include "fuzz_input.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/catheter_image.hpp"
#include "trainer/model/image_format.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/modal_image.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace {

using namespace trainer::model;  // NOLINT: a fuzz target, one file
using trainer::core::Arena;

constexpr std::string_view kLabel = "fuzz.img";
// Larger inputs are skipped (the ctest and tools/fuzz.sh pass -max_len below this).
constexpr std::size_t kMaxImageBytes = 1U << 20U;
constexpr float kPeriodS = 1e-3F;  // the scenes' 1 kHz loop
// A catheter step costs substeps × particles; the harness steps only cheap ones (the repo's
// catheter: 43 × 21 = 903), so fuzzer-made chains with thousands of substeps (which the corpus
// fills with: 20,000 here cut the rate ninefold) do not slow every run.
constexpr std::uint64_t kMaxCatheterStepWork = 2000;

alignas(kImageSectionAlignment) std::array<std::byte, kMaxImageBytes> g_image;

// How far the inputs got: printed at exit.
struct Counters {
  std::uint64_t runs = 0;
  std::uint64_t checksum_kept = 0;
  std::uint64_t checksum_refused = 0;  // refused at the checksum (step 4)
  std::uint64_t parser_refused = 0;    // refused with a matching checksum (header or steps 5..13)
  std::array<std::uint64_t, 4> loaded{};         // by kind
  std::array<std::uint64_t, 4> model_created{};  // by kind
  std::array<std::uint64_t, 4> model_refused{};  // by kind: refused with a message after loading
  std::array<std::uint64_t, 4> stepped{};        // by kind
  std::array<std::string, 4> first_model_refusal;
  std::uint64_t surfaces = 0;  // contact grids built, rebuilt and queried
  ~Counters() {
    std::fprintf(stderr,
                 "fuzz_model_image: %llu inputs, %llu with the checksum kept, %llu refused at "
                 "the checksum, %llu refused with a matching checksum\n",
                 static_cast<unsigned long long>(runs),
                 static_cast<unsigned long long>(checksum_kept),
                 static_cast<unsigned long long>(checksum_refused),
                 static_cast<unsigned long long>(parser_refused));
    const char* names[] = {"", "modal_shell", "tet_tensor", "catheter"};
    for (std::size_t kind = 1; kind < 4; ++kind) {
      std::fprintf(stderr,
                   "fuzz_model_image: %s: %llu loaded, %llu models created, %llu refused by the "
                   "model, %llu stepped%s%s\n",
                   names[kind], static_cast<unsigned long long>(loaded[kind]),
                   static_cast<unsigned long long>(model_created[kind]),
                   static_cast<unsigned long long>(model_refused[kind]),
                   static_cast<unsigned long long>(stepped[kind]),
                   first_model_refusal[kind].empty() ? "" : "; first refusal: ",
                   first_model_refusal[kind].c_str());
    }
    std::fprintf(stderr, "fuzz_model_image: %llu contact surface grids built and queried\n",
                 static_cast<unsigned long long>(surfaces));
  }
};
Counters g_counters;

void model_refused(std::size_t kind, const std::string& message) {
  FUZZ_CHECK(!message.empty());
  ++g_counters.model_refused[kind];
  if (g_counters.first_model_refusal[kind].empty()) {
    g_counters.first_model_refusal[kind] = message.substr(0, 160);
  }
}

// The contact surface the trainer builds over a mesh image's rest positions and triangles
// (rt/app/src/contact_surface.cpp, make_surface_grid: the same data): the triangle BVH the
// trainer uses, created (untrusted indices and positions refused with a message), refitted with
// a slack and queried around a vertex; and the bucket grid, created, rebuilt and queried.
void exercise_surface(const ModelImage& image, Arena& arena) {
  const std::span<const float> rest = image.floats(SectionId::rest_positions);
  const std::span<const std::uint32_t> triangles = image.u32s(SectionId::triangles);
  const std::size_t vertex_count = rest.size() / 3;
  const std::size_t triangle_count = triangles.size() / 3;
  if (vertex_count == 0 || triangle_count == 0) return;
  const auto vertex = [&](std::uint32_t node) {
    const std::size_t base = 3 * static_cast<std::size_t>(node);
    return Vec3(rest[base], rest[base + 1], rest[base + 2]);
  };
  float longest_edge = 0.0F;
  for (std::size_t t = 0; t < triangle_count; ++t) {
    for (std::size_t e = 0; e < 3; ++e) {
      longest_edge = std::max(longest_edge, (vertex(triangles[3 * t + e]) -
                                             vertex(triangles[3 * t + (e + 1) % 3]))
                                                .norm());
    }
  }
  auto bvh = TriangleBvh::create(rest, triangles, arena);
  if (!bvh) {
    FUZZ_CHECK(!bvh.error().message.empty());
    return;
  }
  {
    auto bvh_ids = arena.allocate_array<std::uint32_t>(triangle_count, "fuzz bvh query");
    if (!bvh_ids) return;
    FUZZ_CHECK(bvh->refit(rest, 0.375F * longest_edge).is_ok() || !std::isfinite(longest_edge));
    std::size_t bvh_found = 0;
    (void)bvh->query(Aabb::around_point(vertex(triangles[0]), 1e-3F), *bvh_ids, bvh_found);
    FUZZ_CHECK(bvh_found <= triangle_count);
  }
  BucketGridSettings settings;
  settings.max_triangles = static_cast<std::uint32_t>(triangle_count);
  settings.max_vertices = static_cast<std::uint32_t>(vertex_count);
  settings.cell_size_m = 1.5F * longest_edge;
  settings.max_entries = static_cast<std::uint32_t>(27 * triangle_count);
  settings.table_size = std::bit_ceil(2U * settings.max_entries / 8U + 1U);
  auto grid = BucketGrid::create(settings, arena);
  if (!grid) {
    FUZZ_CHECK(!grid.error().message.empty());
    return;
  }
  auto ids = arena.allocate_array<std::uint32_t>(triangle_count, "fuzz grid query");
  if (!ids) return;
  if (!grid->rebuild(rest, triangles).is_ok()) return;
  std::size_t found = 0;
  (void)grid->query(Aabb::around_point(vertex(triangles[0]), 1e-3F), *ids, found);
  FUZZ_CHECK(found <= triangle_count);
  ++g_counters.surfaces;
}

void exercise_modal(const ModelImage& image, Arena& arena) {
  ModalSettings settings;
  settings.time_step_s = kPeriodS;
  settings.static_correction = image.metadata().static_correction != 0;
  auto model = ModalModel::create(modal_model_data(image), arena, settings);
  if (!model) return model_refused(1, model.error().message);
  ++g_counters.model_created[1];
  exercise_surface(image, arena);
  const std::span<const std::uint32_t> surface = image.u32s(SectionId::surface_nodes);
  const std::uint32_t node = surface.empty() ? 0 : surface.back();
  (void)model->add_node_force(node, Eigen::Vector3f(0.1F, -0.2F, 0.3F));
  (void)model->step();
  (void)model->displacement(node);
  const std::array<ImposedDisplacement, 1> targets{
      ImposedDisplacement{node, Eigen::Vector3f(0.0F, 0.0F, -1e-3F)}};
  std::array<Eigen::Vector3f, 1> forces{};
  if (model->solve_imposed(targets, forces).is_ok()) (void)model->step();
  ++g_counters.stepped[1];
}

void exercise_tensor(const ModelImage& image, Arena& arena) {
  auto model = TensorModel::create(tensor_model_data(image), TensorSettings{}, arena);
  if (!model) return model_refused(2, model.error().message);
  ++g_counters.model_created[2];
  exercise_surface(image, arena);
  const std::span<const std::uint32_t> contacts = model->contact_nodes();
  if (!contacts.empty()) {
    const std::array<TensorContact, 1> contact{
        TensorContact{contacts.front(), Vec3(0.0F, 0.0F, -1e-3F)}};
    if (model->solve(contact).is_ok()) {
      (void)model->total_force();
      model->update_field();
    }
  }
  ++g_counters.stepped[2];
}

void exercise_catheter(const ModelImage& image, Arena& arena) {
  const CatheterModelData data = catheter_model_data(image);
  FUZZ_CHECK(data.rest_positions_m.size() == 3 * std::size_t{data.params.particle_count} ||
             data.params.particle_count == 0);
  auto created = Catheter::create(data, kPeriodS, 8, arena);
  if (!created) return model_refused(3, created.error().message);
  ++g_counters.model_created[3];
  Catheter& catheter = *created;
  FUZZ_CHECK(catheter.particle_count() == data.params.particle_count);
  FUZZ_CHECK(catheter.substeps_per_period() >= 1 &&
             catheter.substeps_per_period() <= data.max_substeps);
  if (std::uint64_t{catheter.substeps_per_period()} * catheter.particle_count() >
      kMaxCatheterStepWork) {
    return;
  }
  catheter.clamp_start(data.hold_start);
  (void)catheter.add_force(catheter.particle_count() - 1, Vec3(0.0F, 0.01F, 0.0F));
  (void)catheter.step(kPeriodS);
  ++g_counters.stepped[3];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0 || size - 1 > kMaxImageBytes) return 0;
  ++g_counters.runs;
  const std::uint8_t control = data[0];
  const std::size_t file_size = size - 1;
  std::memcpy(g_image.data(), data + 1, file_size);
  const std::span<std::byte> file(g_image.data(), file_size);

  std::uint32_t header_kind = 0;
  if (file_size >= offsetof(ImageHeaderV1, model_kind) + 4) {
    std::memcpy(&header_kind, file.data() + offsetof(ImageHeaderV1, model_kind), 4);
  }
  std::uint32_t kind = control & 3U;
  if (kind == 0) kind = header_kind >= 1 && header_kind <= 3 ? header_kind : 1;
  const auto expected = static_cast<ModelKind>(kind);

  if ((control & 4U) == 0 && file_size >= kImageChecksumOffset + 8) {
    const std::uint64_t checksum = compute_image_checksum(file);
    std::memcpy(file.data() + kImageChecksumOffset, &checksum, sizeof checksum);
  } else {
    ++g_counters.checksum_kept;
  }

  // Whether the checksum matches, to count refusals that got past it (with the header checks
  // before it, which the counter does not tell apart).
  bool checksum_matches = false;
  if (file_size >= kImageChecksumOffset + 8) {
    std::uint64_t stored = 0;
    std::memcpy(&stored, file.data() + kImageChecksumOffset, sizeof stored);
    checksum_matches = stored == compute_image_checksum(file);
  }
  auto image = parse_model_image(file, kLabel, expected, ImageLimits{});
  if (!image) {
    const std::string& message = image.error().message;
    // "<label>: <what>"
    FUZZ_CHECK(message.size() > kLabel.size() + 2 && message.starts_with(kLabel) &&
               message.compare(kLabel.size(), 2, ": ") == 0);
    if (message.find("checksum mismatch") != std::string::npos) {
      ++g_counters.checksum_refused;
    } else if (checksum_matches) {
      ++g_counters.parser_refused;
    }
    return 0;
  }
  ++g_counters.loaded[kind];
  FUZZ_CHECK(!image->empty() && image->model_kind() == expected);
  FUZZ_CHECK(image->has(SectionId::metadata));
  for (const SectionView& view : image->sections()) {
    FUZZ_CHECK(view.element_count == std::uint64_t{view.rows} * view.cols);
    if (view.element_count == 0) continue;
    FUZZ_CHECK(view.data >= file.data() && view.data < file.data() + file.size());
  }

  auto arena = Arena::create(128 * 1024 + 48 * file_size);  // model state and contact grid
  FUZZ_CHECK(static_cast<bool>(arena));
  switch (expected) {
    case ModelKind::modal_shell: exercise_modal(*image, *arena); break;
    case ModelKind::tet_tensor: exercise_tensor(*image, *arena); break;
    case ModelKind::catheter: exercise_catheter(*image, *arena); break;
  }
  return 0;
}
