// Speed and size of Cotin's tensor model (METHODS.md §3): the offline precompute (assembly,
// one sparse Cholesky factorisation, the block solves and tensor products) and the image size
// against node count, up to a liver-sized mesh of ~2,000 nodes (Cotin's liver: 1,500–2,000
// nodes); and the runtime cost of one haptic update (the mutual-influence solve and contact
// forces) against the contact count up to the maximum, with the graphics-rate field update.
// docs/performance.md reports these numbers.
//
// Meshes: boxes of soft tissue (E 15 kPa, ν 0.45) clamped on their base, contacts on every
// free boundary node, responses stored for the boundary (what a scene's default image holds)
// — "all" variants store every node. Node counts run 252 → 3,718.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "trainer/core/arena.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model/tensor_model.hpp"
#include "trainer/model_offline/image_writer.hpp"
#include "trainer/model_offline/tensor_build.hpp"
#include "trainer/model_offline/tet_elasticity.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace {

using namespace trainer;
namespace offline = model::offline;

struct BoxSize {
  int nx, ny, nz;
};
// Node counts (nx+1)(ny+1)(nz+1): 252, 585, 1,053, 1,989, 3,718.
constexpr BoxSize kSizes[] = {{8, 6, 3}, {12, 8, 4}, {12, 8, 8}, {16, 12, 8}, {21, 12, 12}};
constexpr int kLiverSize = 3;  // 1,989 nodes

std::vector<int> unique_sorted(std::vector<int> nodes) {
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

struct Built {
  offline::TetMesh mesh;
  offline::AssembledTet assembled;
  offline::TensorPrecompute tensors;
  std::vector<std::byte> image_bytes;
  double assembly_s = 0.0;
  double factorization_s = 0.0;
  double total_s = 0.0;
};

core::Expected<Built> build(const BoxSize& size, bool store_all) {
  const auto start = std::chrono::steady_clock::now();
  Built built;
  // 0.15 × 0.10 × 0.07 m: a liver lobe's bounding box.
  auto mesh = offline::make_tet_box(0.15, 0.10, 0.07, size.nx, size.ny, size.nz);
  if (!mesh) return std::move(mesh).error();
  built.mesh = std::move(mesh).value();
  const offline::TetMaterial material{15e3, 0.45, 1000.0};
  const std::vector<offline::TetNodeFix> fixes{
      {unique_sorted(built.mesh.node_sets.at("z0")), {true, true, true}}};
  auto assembled = offline::assemble_tet(built.mesh, material, fixes);
  if (!assembled) return std::move(assembled).error();
  built.assembled = std::move(assembled).value();
  built.assembly_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  auto solver = offline::TetStaticSolver::create(built.assembled);
  if (!solver) return std::move(solver).error();
  built.factorization_s = solver.value().factorization_time_s();
  const std::vector<int> fixed = offline::partly_fixed_nodes(built.assembled.dofs);
  offline::TensorPrecomputeOptions options;
  std::set_difference(built.mesh.node_sets.at("surface").begin(),
                      built.mesh.node_sets.at("surface").end(), fixed.begin(), fixed.end(),
                      std::back_inserter(options.contact_nodes));
  options.contact_nodes = unique_sorted(options.contact_nodes);
  options.response_nodes = unique_sorted(
      store_all ? built.mesh.node_sets.at("all") : built.mesh.node_sets.at("surface"));
  auto tensors = offline::precompute_tensors(built.assembled, solver.value(), options);
  if (!tensors) return std::move(tensors).error();
  built.tensors = std::move(tensors).value();
  offline::TensorImageInputs inputs;
  inputs.mesh = &built.mesh;
  inputs.boundary_triangles = offline::boundary_triangles(built.mesh);
  inputs.material = material;
  inputs.fixed_nodes = fixed;
  auto bytes = offline::serialize_tensor_image(inputs, built.tensors);
  if (!bytes) return std::move(bytes).error();
  built.image_bytes = std::move(bytes).value();
  built.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return built;
}

// Precompute: assembly + factorisation + tensors + image serialisation, timed per iteration.
void BM_TensorPrecompute(benchmark::State& state) {
  const BoxSize size = kSizes[state.range(0)];
  const bool store_all = state.range(1) != 0;
  Built last;
  for (auto _ : state) {
    auto built = build(size, store_all);
    if (!built) {
      state.SkipWithError(built.error().message.c_str());
      return;
    }
    last = std::move(built).value();
    state.SetIterationTime(last.total_s);
  }
  state.counters["nodes"] = static_cast<double>(last.mesh.nodes.rows());
  state.counters["tets"] = static_cast<double>(last.mesh.tetrahedra.rows());
  state.counters["contacts"] = static_cast<double>(last.tensors.contact_nodes.size());
  state.counters["stored"] = static_cast<double>(last.tensors.response_nodes.size());
  state.counters["image_MB"] = static_cast<double>(last.image_bytes.size()) / 1e6;
  state.counters["assembly_s"] = last.assembly_s;
  state.counters["factor_s"] = last.factorization_s;
  state.counters["tensors_s"] = last.tensors.solve_time_s;
}
BENCHMARK(BM_TensorPrecompute)
    ->ArgsProduct({{0, 1, 2, 3, 4}, {0}})
    ->Args({kLiverSize, 1})
    ->ArgNames({"size", "all_nodes"})
    ->UseManualTime()
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// The liver-sized model, built once, loaded as the trainer would (parse into an arena).
struct Runtime {
  Built built;
  core::Arena arena = core::Arena::create(std::size_t{128} << 20).value();
  model::ModelImage image;
};

Runtime& liver_runtime() {
  static const std::unique_ptr<Runtime> runtime = [] {
    auto made = std::make_unique<Runtime>();
    auto built = build(kSizes[kLiverSize], false);
    if (!built) std::abort();
    made->built = std::move(built).value();
    auto block =
        made->arena.allocate_array<std::byte>(made->built.image_bytes.size(), "image").value();
    std::copy(made->built.image_bytes.begin(), made->built.image_bytes.end(), block.begin());
    auto image = model::parse_model_image(block, "liver", model::ModelKind::tet_tensor,
                                          offline::ImageWriter::permissive_limits());
    if (!image) std::abort();
    made->image = std::move(image).value();
    return made;
  }();
  return *runtime;
}

// Contacts: the free top-face nodes nearest the centre, so a jaw-sized patch of neighbours (the
// worst conditioning a tool produces), pressed with a depth that varies cycle to cycle.
std::vector<std::uint32_t> patch_nodes(const Runtime& runtime, std::size_t count) {
  const offline::TetMesh& mesh = runtime.built.mesh;
  std::vector<int> top = unique_sorted(mesh.node_sets.at("z1"));
  const Eigen::RowVector3d centre(0.075, 0.05, 0.07);
  std::sort(top.begin(), top.end(), [&](int a, int b) {
    return (mesh.nodes.row(a) - centre).squaredNorm() < (mesh.nodes.row(b) - centre).squaredNorm();
  });
  std::vector<std::uint32_t> nodes;
  for (std::size_t i = 0; i < count; ++i) nodes.push_back(static_cast<std::uint32_t>(top[i]));
  return nodes;
}

void run_contacts(benchmark::State& state, bool with_field) {
  Runtime& runtime = liver_runtime();
  const auto count = static_cast<std::size_t>(state.range(0));
  core::Arena arena = core::Arena::create(std::size_t{1} << 20).value();
  model::TensorSettings settings;
  settings.max_contacts = static_cast<std::uint32_t>(std::max<std::size_t>(count, 1));
  auto created = model::TensorModel::create(model::tensor_model_data(runtime.image), settings, arena);
  if (!created) {
    state.SkipWithError(created.error().message.c_str());
    return;
  }
  model::TensorModel tensor_model = std::move(created).value();
  const std::vector<std::uint32_t> nodes = patch_nodes(runtime, count);
  std::vector<model::TensorContact> contacts(count);
  std::size_t cycle = 0;
  for (auto _ : state) {
    const float depth = -0.001F - 0.001F * static_cast<float>(cycle % 1000) / 1000.0F;
    for (std::size_t i = 0; i < count; ++i) {
      contacts[i] = {nodes[i], {0.0F, 0.0001F * static_cast<float>(i), depth}};
    }
    const core::Status status = tensor_model.solve(contacts);
    if (!status.is_ok()) {
      state.SkipWithError("solve refused");
      return;
    }
    benchmark::DoNotOptimize(tensor_model.total_force());
    if (with_field) {
      tensor_model.update_field();
      benchmark::DoNotOptimize(tensor_model.displacements().data());
    }
    ++cycle;
  }
  state.counters["stored"] = static_cast<double>(tensor_model.response_nodes().size());
}

// Haptic update: the contact forces for m contacts (what the force loop needs every cycle).
void BM_TensorContactForces(benchmark::State& state) { run_contacts(state, false); }
BENCHMARK(BM_TensorContactForces)->Arg(1)->Arg(2)->Arg(4)->Arg(8)->Arg(16)->Unit(benchmark::kMicrosecond);

// Plus the displacement field of every stored node (graphics / collision rate).
void BM_TensorContactsAndField(benchmark::State& state) { run_contacts(state, true); }
BENCHMARK(BM_TensorContactsAndField)->Arg(1)->Arg(2)->Arg(4)->Arg(8)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
