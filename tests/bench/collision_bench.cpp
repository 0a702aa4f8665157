// Speed of the collision layer (model::BucketGrid, the predicates, model::GodObjectProxy)
// on a deformed tube like the duct (radius 4 mm, 40 mm long), against the mesh size — 640
// triangles (the duct), 2.5k, 10k and 40k — and the number of query spheres (1, 8, 21 = the
// catheter's particles, 64). docs/collision.md reports these numbers.
//
//   BM_Rebuild/<triangles>            rebuild of the hash over a freshly deformed mesh
//   BM_Query/<triangles>/<spheres>    per sphere: grid query + sphere-triangle narrow phase
//   BM_BruteForce/<triangles>/<spheres> the same contacts by testing every triangle
//   BM_CellSize/<triangles>/<cell as % of the mean edge> rebuild + 21 sphere queries
//   BM_ProxyUpdate/<triangles>        one god-object update, tool sliding around the tube
//                                     pressed 0.5 mm into the wall (grid rebuilt outside)
//   BM_ParticleContact/<triangles>/<particles> ParticleSurfaceContact::compute for a catheter
//                                     lying along the wall inside the tube (grid rebuilt outside)
// Issue 19, the hash (with its exact stored-box filter) against the refitted hierarchy
// (model::TriangleBvh), on the duct-sized tube; <kind> 0 = BucketGrid, 1 = TriangleBvh:
//   BM_BroadRefit/<kind>               the upkeep when the wall has moved (0.5 mm between
//                                      shapes): the grid's rebuild, the hierarchy's refit;
//                                      /2: the hierarchy's per-cycle check when nothing moved
//                                      beyond the slack
//   BM_BroadQuery/<kind>/<spheres>     like BM_Query (candidates = after the exact filter)
//   BM_SegmentContact/<kind>           SegmentSurfaceContact::update, shaft (r 2.5 mm) and two
//                                      jaws (r 1 mm) pressed 0.5 mm into the tube from outside,
//                                      sliding round it (the cbd's shaft/jaw vs duct sub-stage)
//   BM_FarParticles/<kind>             21 particles all 10-30 mm outside the tube (most of the
//                                      cbd's catheter, most of the time)
// Counter `allocs` is the heap allocations per iteration in the timed calls (must be 0).
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/geometry.hpp"
#include "trainer/model/particle_contact.hpp"
#include "trainer/model/proxy.hpp"
#include "trainer/model/segment_contact.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace {

using namespace trainer;
using model::Vec3;

constexpr float kTubeRadiusM = 0.004F;
constexpr float kTubeLengthM = 0.04F;
constexpr float kSphereRadiusM = 0.0005F;  // a catheter particle

struct TubeSize {
  std::uint32_t rings;
  std::uint32_t segments;
};
// 2 (rings − 1) segments triangles: 640, 2560, 10240, 40960.
constexpr std::array<TubeSize, 4> kSizes{{{21, 16}, {41, 32}, {81, 64}, {161, 128}}};

TubeSize size_for(std::int64_t triangles) {
  for (const TubeSize& size : kSizes) {
    if (2 * static_cast<std::int64_t>(size.rings - 1) * size.segments == triangles) return size;
  }
  return kSizes[0];
}

struct Tube {
  std::vector<float> rest;
  std::vector<std::vector<float>> shapes;  // deformed copies, cycled through
  std::vector<std::uint32_t> triangles;
  float mean_edge_m = 0.0F;
};

Tube make_tube(TubeSize size) {
  Tube tube;
  for (std::uint32_t r = 0; r < size.rings; ++r) {
    for (std::uint32_t s = 0; s < size.segments; ++s) {
      const float angle = 2.0F * std::numbers::pi_v<float> * static_cast<float>(s) /
                          static_cast<float>(size.segments);
      tube.rest.insert(tube.rest.end(),
                       {kTubeRadiusM * std::cos(angle), kTubeRadiusM * std::sin(angle),
                        kTubeLengthM * static_cast<float>(r) / static_cast<float>(size.rings - 1)});
    }
  }
  for (std::uint32_t r = 0; r + 1 < size.rings; ++r) {
    for (std::uint32_t s = 0; s < size.segments; ++s) {
      const std::uint32_t i = r * size.segments + s;
      const std::uint32_t j = r * size.segments + (s + 1) % size.segments;
      tube.triangles.insert(tube.triangles.end(),
                            {i, j, i + size.segments, j, j + size.segments, i + size.segments});
    }
  }
  double edge_sum = 0.0;
  for (std::size_t t = 0; t < tube.triangles.size(); t += 3) {
    for (std::size_t corner = 0; corner < 3; ++corner) {
      const std::uint32_t a = tube.triangles[t + corner];
      const std::uint32_t b = tube.triangles[t + (corner + 1) % 3];
      const Vec3 pa(tube.rest[3 * a], tube.rest[3 * a + 1], tube.rest[3 * a + 2]);
      const Vec3 pb(tube.rest[3 * b], tube.rest[3 * b + 1], tube.rest[3 * b + 2]);
      edge_sum += static_cast<double>((pa - pb).norm());
    }
  }
  tube.mean_edge_m = static_cast<float>(edge_sum / static_cast<double>(tube.triangles.size()));
  // A peristaltic-like wave, ±0.5 mm radial, in 8 phases.
  for (int phase = 0; phase < 8; ++phase) {
    std::vector<float> shape = tube.rest;
    for (std::size_t v = 0; v < shape.size() / 3; ++v) {
      const float z = shape[3 * v + 2];
      const float scale = 1.0F + 0.125F * std::sin(400.0F * z + 0.785F * static_cast<float>(phase));
      shape[3 * v] *= scale;
      shape[3 * v + 1] *= scale;
    }
    tube.shapes.push_back(std::move(shape));
  }
  return tube;
}

std::uint32_t power_of_two_at_least(std::size_t count) {
  std::uint32_t size = 1024;
  while (size < count) size *= 2;
  return size;
}

struct Broadphase {
  core::Arena arena;
  model::BucketGrid grid;
};

// The table gets about two buckets per (triangle, cell) entry of the rest shape, found by a
// probe rebuild: fewer buckets and distinct cells share buckets (more candidates).
Broadphase make_broadphase(const Tube& tube, float cell_size_m) {
  const auto triangles = static_cast<std::uint32_t>(tube.triangles.size() / 3);
  const auto vertices = static_cast<std::uint32_t>(tube.rest.size() / 3);
  const std::uint32_t max_entries = 128 * triangles;
  std::size_t entries = 0;
  {
    auto probe_arena = core::Arena::create(64U << 20);
    if (!probe_arena) std::abort();
    auto probe = model::BucketGrid::create({triangles, vertices, cell_size_m, 1024, max_entries},
                                           probe_arena.value());
    if (!probe || !probe->rebuild(tube.rest, tube.triangles).is_ok()) std::abort();
    entries = probe->entry_count();
  }
  auto arena = core::Arena::create(96U << 20);
  if (!arena) std::abort();
  core::Arena owned = std::move(arena).value();
  auto grid = model::BucketGrid::create(
      {triangles, vertices, cell_size_m, power_of_two_at_least(2 * entries), max_entries}, owned);
  if (!grid) std::abort();
  return {std::move(owned), std::move(grid).value()};
}

// Sphere centres inside the lumen near the wall, spread along the tube, moving with `step`.
Vec3 sphere_centre(std::size_t index, std::size_t count, std::int64_t step) {
  const float along = (static_cast<float>(index) + 0.5F) / static_cast<float>(count);
  const float angle = 0.37F * static_cast<float>(index) + 0.01F * static_cast<float>(step % 628);
  const float radius = kTubeRadiusM - 0.3F * kSphereRadiusM;
  return {radius * std::cos(angle), radius * std::sin(angle), 0.9F * kTubeLengthM * along + 0.002F};
}

Vec3 vertex_of(const std::vector<float>& positions, std::uint32_t vertex) {
  return {positions[3 * vertex], positions[3 * vertex + 1], positions[3 * vertex + 2]};
}

bool contact_with(const Tube& tube, const std::vector<float>& positions, std::uint32_t triangle,
                  const Vec3& centre) {
  const Vec3 a = vertex_of(positions, tube.triangles[3 * triangle]);
  const Vec3 b = vertex_of(positions, tube.triangles[3 * triangle + 1]);
  const Vec3 c = vertex_of(positions, tube.triangles[3 * triangle + 2]);
  return model::sphere_triangle_contact(centre, kSphereRadiusM, a, b, c).in_contact;
}

void BM_Rebuild(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  Broadphase broadphase = make_broadphase(tube, tube.mean_edge_m);
  std::size_t cycle = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    const core::Status status = broadphase.grid.rebuild(tube.shapes[cycle++ % 8], tube.triangles);
    if (!status.is_ok()) state.SkipWithError(status.detail());
  }
  core::alloc::end_counting_this_thread();
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
  state.counters["entries"] = static_cast<double>(broadphase.grid.entry_count());
  state.counters["buckets"] = static_cast<double>(broadphase.grid.table_size());
  state.counters["cell_mm"] = static_cast<double>(tube.mean_edge_m) * 1e3;
}

void run_queries(benchmark::State& state, const Tube& tube, Broadphase& broadphase,
                 std::size_t spheres, bool rebuild) {
  std::vector<std::uint32_t> candidates(tube.triangles.size() / 3);
  const std::vector<float>& fixed_shape = tube.shapes[3];
  if (!rebuild && !broadphase.grid.rebuild(fixed_shape, tube.triangles).is_ok()) std::abort();
  std::int64_t step = 0;
  double candidate_total = 0.0;
  double contact_total = 0.0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    const std::vector<float>& positions = rebuild ? tube.shapes[static_cast<std::size_t>(step) % 8] : fixed_shape;
    if (rebuild && !broadphase.grid.rebuild(positions, tube.triangles).is_ok()) {
      state.SkipWithError("rebuild");
      break;
    }
    for (std::size_t s = 0; s < spheres; ++s) {
      const Vec3 centre = sphere_centre(s, spheres, step);
      std::size_t count = 0;
      if (!broadphase.grid.query(model::Aabb::around_point(centre, kSphereRadiusM), candidates, count).is_ok()) {
        state.SkipWithError("query");
        break;
      }
      candidate_total += static_cast<double>(count);
      for (std::size_t k = 0; k < count; ++k) {
        if (contact_with(tube, positions, candidates[k], centre)) contact_total += 1.0;
      }
    }
    ++step;
  }
  core::alloc::end_counting_this_thread();
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
  const double queries = static_cast<double>(step) * static_cast<double>(spheres);
  state.counters["candidates"] = queries > 0 ? candidate_total / queries : 0.0;
  state.counters["contacts"] = queries > 0 ? contact_total / queries : 0.0;
}

void BM_Query(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  Broadphase broadphase = make_broadphase(tube, tube.mean_edge_m);
  run_queries(state, tube, broadphase, static_cast<std::size_t>(state.range(1)), false);
}

void BM_CellSize(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  const float cell = tube.mean_edge_m * static_cast<float>(state.range(1)) / 100.0F;
  Broadphase broadphase = make_broadphase(tube, cell);
  run_queries(state, tube, broadphase, 21, true);
  state.counters["cell_mm"] = static_cast<double>(cell) * 1e3;
}

void BM_BruteForce(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  const auto spheres = static_cast<std::size_t>(state.range(1));
  const std::vector<float>& positions = tube.shapes[3];
  const auto triangle_count = static_cast<std::uint32_t>(tube.triangles.size() / 3);
  std::int64_t step = 0;
  double contact_total = 0.0;
  for (auto _ : state) {
    for (std::size_t s = 0; s < spheres; ++s) {
      const Vec3 centre = sphere_centre(s, spheres, step);
      for (std::uint32_t t = 0; t < triangle_count; ++t) {
        if (contact_with(tube, positions, t, centre)) contact_total += 1.0;
      }
    }
    ++step;
  }
  state.counters["contacts"] =
      step > 0 ? contact_total / (static_cast<double>(step) * static_cast<double>(spheres)) : 0.0;
}

void BM_ProxyUpdate(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  Broadphase broadphase = make_broadphase(tube, tube.mean_edge_m);
  const std::vector<float>& positions = tube.shapes[3];
  if (!broadphase.grid.rebuild(positions, tube.triangles).is_ok()) std::abort();
  model::ProxySettings settings;
  settings.stiffness_n_per_m = 500.0F;
  settings.max_travel_per_update_m = 0.0005F;
  auto proxy = model::GodObjectProxy::create(settings, broadphase.arena);
  if (!proxy) std::abort();
  const model::TriangleMeshView mesh{positions, tube.triangles};
  // The outward normals face away from the axis: the tool presses from outside, 0.5 mm deep
  // into the rest radius, circling the tube at 0.2 m/s at 1 kHz (0.2 mm per update).
  const auto tool_at = [](std::int64_t step, float radius) {
    const float angle = 0.05F * static_cast<float>(step);
    return Vec3(radius * std::cos(angle), radius * std::sin(angle), 0.02F);
  };
  proxy->reset(tool_at(0, 2.0F * kTubeRadiusM));
  std::int64_t step = 0;
  double in_contact = 0.0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    const Vec3 tool = tool_at(step, step == 0 ? 2.0F * kTubeRadiusM : kTubeRadiusM - 0.0005F);
    if (!proxy->update(tool, Vec3::Zero(), mesh, broadphase.grid).is_ok()) {
      state.SkipWithError("proxy update");
      break;
    }
    in_contact += proxy->contact().in_contact ? 1.0 : 0.0;
    ++step;
  }
  core::alloc::end_counting_this_thread();
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
  state.counters["in_contact"] = step > 0 ? in_contact / static_cast<double>(step) : 0.0;
}

// A catheter of N particles (radius 0.5 mm) lying in the lumen along a helix near the wall,
// a third of them pressed up to 0.3 mm into it, sliding round 0.2 mm per cycle; the duct wall
// 0.2 mm thick (offset 0.1 mm), inner side. Grid rebuilt outside the timed call (BM_Rebuild).
void BM_ParticleContact(benchmark::State& state) {
  const Tube tube = make_tube(size_for(state.range(0)));
  const auto particles = static_cast<std::size_t>(state.range(1));
  Broadphase broadphase = make_broadphase(tube, tube.mean_edge_m);
  const std::vector<float>& positions = tube.shapes[3];
  if (!broadphase.grid.rebuild(positions, tube.triangles).is_ok()) std::abort();
  model::ParticleContactSettings settings;
  settings.max_particles = static_cast<std::uint32_t>(particles);
  settings.max_contacts = static_cast<std::uint32_t>(4 * particles);
  settings.max_nodes = static_cast<std::uint32_t>(tube.rest.size() / 3);
  settings.stiffness_n_per_m = 200.0F;
  settings.damping_n_s_per_m = 0.01F;
  settings.surface_offset_m = 1e-4F;
  settings.max_force_n = 1.0F;
  settings.side = model::ContactSide::inner;
  auto contact = model::ParticleSurfaceContact::create(settings, broadphase.arena);
  if (!contact) std::abort();
  const model::TriangleMeshView mesh{positions, tube.triangles};
  std::vector<Vec3> centres(particles);
  const std::vector<Vec3> velocities(particles, Vec3(0.0F, 0.0F, 0.01F));
  model::ParticleContactOutput out;
  std::int64_t step = 0;
  double contacts = 0.0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    for (std::size_t i = 0; i < particles; ++i) {
      const float along = (static_cast<float>(i) + 0.5F) / static_cast<float>(particles);
      const float angle = 1.5F * along + 0.05F * static_cast<float>(step % 126);
      const float radius = kTubeRadiusM - 0.4e-3F - 0.3e-3F * static_cast<float>(i % 3);
      centres[i] = Vec3(radius * std::cos(angle), radius * std::sin(angle), 0.9F * kTubeLengthM * along + 0.002F);
    }
    if (!contact->compute(centres, velocities, kSphereRadiusM, mesh, {}, broadphase.grid, out).is_ok()) {
      state.SkipWithError("particle contact");
      break;
    }
    contacts += out.contact_count;
    ++step;
  }
  core::alloc::end_counting_this_thread();
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
  state.counters["contacts"] = step > 0 ? contacts / static_cast<double>(step) : 0.0;
}

// ---- issue 19: hash vs hierarchy on the duct-sized tube ----

struct BothBroadphases {
  Broadphase hash;
  model::TriangleBvh bvh;
  model::TriangleBroadPhase& pick(std::int64_t kind) {
    if (kind == 0) return hash.grid;
    return bvh;
  }
  void fit(std::int64_t kind, const std::vector<float>& positions, const std::vector<std::uint32_t>& triangles) {
    const bool ok = kind == 0 ? hash.grid.rebuild(positions, triangles).is_ok() : bvh.refit(positions).is_ok();
    if (!ok) std::abort();
  }
};

BothBroadphases make_both(const Tube& tube) {
  Broadphase hash = make_broadphase(tube, tube.mean_edge_m);
  auto bvh = model::TriangleBvh::create(tube.rest, tube.triangles, hash.arena);
  if (!bvh) std::abort();
  return {std::move(hash), std::move(bvh).value()};
}

void BM_BroadRefit(benchmark::State& state) {
  const Tube tube = make_tube(kSizes[0]);
  BothBroadphases both = make_both(tube);
  const std::int64_t kind = state.range(0);
  std::size_t cycle = 0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    if (kind == 2) {  // the hierarchy's check alone: nothing moved beyond the slack
      if (!both.bvh.refit(tube.shapes[3], 0.001F).is_ok()) std::abort();
    } else {
      both.fit(kind, tube.shapes[cycle++ % 8], tube.triangles);
    }
  }
  core::alloc::end_counting_this_thread();
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
}

void BM_BroadQuery(benchmark::State& state) {
  const Tube tube = make_tube(kSizes[0]);
  BothBroadphases both = make_both(tube);
  const std::int64_t kind = state.range(0);
  const auto spheres = static_cast<std::size_t>(state.range(1));
  const std::vector<float>& positions = tube.shapes[3];
  both.fit(kind, positions, tube.triangles);
  model::TriangleBroadPhase& broad = both.pick(kind);
  std::vector<std::uint32_t> candidates(tube.triangles.size() / 3);
  std::int64_t step = 0;
  double candidate_total = 0.0;
  double contact_total = 0.0;
  for (auto _ : state) {
    for (std::size_t s = 0; s < spheres; ++s) {
      const Vec3 centre = sphere_centre(s, spheres, step);
      std::size_t count = 0;
      if (!broad.query(model::Aabb::around_point(centre, kSphereRadiusM), candidates, count).is_ok()) std::abort();
      candidate_total += static_cast<double>(count);
      for (std::size_t k = 0; k < count; ++k) {
        if (contact_with(tube, positions, candidates[k], centre)) contact_total += 1.0;
      }
    }
    ++step;
  }
  const double queries = static_cast<double>(step) * static_cast<double>(spheres);
  state.counters["candidates"] = queries > 0 ? candidate_total / queries : 0.0;
  state.counters["contacts"] = queries > 0 ? contact_total / queries : 0.0;
}

// The shaft (from outside, axis tangent-ish to the tube) and the two jaws, pressed 0.5 mm into
// the wall (reach = radius + 0.1 mm half thickness), circling the tube 0.2 mm per cycle.
std::array<model::ToolCapsule, 3> pressing_capsules(std::int64_t step) {
  const float angle = 0.05F * static_cast<float>(step % 126);
  const Vec3 radial(std::cos(angle), std::sin(angle), 0.0F);
  const Vec3 tangent(-std::sin(angle), std::cos(angle), 0.0F);
  const Vec3 hinge = (kTubeRadiusM + 0.0011F) * radial + Vec3(0, 0, 0.02F);
  std::array<model::ToolCapsule, 3> capsules{};
  capsules[0].segment = model::ToolSegment::shaft;
  capsules[0].start_m = hinge + 0.03F * (radial + Vec3(0, 0, 1.0F)).normalized() + 0.0025F * radial;
  capsules[0].end_m = hinge + 0.0025F * radial;
  capsules[0].radius_m = 0.0025F;
  for (int jaw = 1; jaw <= 2; ++jaw) {
    capsules[static_cast<std::size_t>(jaw)].segment = jaw == 1 ? model::ToolSegment::jaw0 : model::ToolSegment::jaw1;
    capsules[static_cast<std::size_t>(jaw)].start_m = hinge;
    capsules[static_cast<std::size_t>(jaw)].end_m =
        hinge + 0.008F * Vec3(0, 0, -1.0F) + (jaw == 1 ? 0.001F : -0.001F) * tangent;
    capsules[static_cast<std::size_t>(jaw)].radius_m = 0.001F;
  }
  return capsules;
}

void BM_SegmentContact(benchmark::State& state) {
  const Tube tube = make_tube(kSizes[0]);
  BothBroadphases both = make_both(tube);
  const std::int64_t kind = state.range(0);
  const std::vector<float>& positions = tube.shapes[3];
  both.fit(kind, positions, tube.triangles);
  model::TriangleBroadPhase& broad = both.pick(kind);
  model::SegmentContactSettings settings;
  settings.surface_half_thickness_m = 1e-4F;
  settings.stiffness_n_per_m = 500.0F;
  settings.damping_n_s_per_m = 0.5F;
  settings.max_force_n = 5.0F;
  settings.max_candidates = 640;
  auto contact = model::SegmentSurfaceContact::create(settings, both.hash.arena);
  if (!contact) std::abort();
  const model::TriangleMeshView mesh{positions, tube.triangles};
  std::int64_t step = 0;
  double contacts = 0.0;
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  for (auto _ : state) {
    const auto capsules = pressing_capsules(step);
    if (!contact->update(capsules, mesh, {}, broad).is_ok()) {
      state.SkipWithError("segment contact");
      break;
    }
    contacts += static_cast<double>(contact->contact_count());
    ++step;
  }
  core::alloc::end_counting_this_thread();
  // Candidates per capsule query, counted apart over the same 126 poses.
  std::vector<std::uint32_t> ids(640);
  double candidates = 0.0;
  for (std::int64_t pose = 0; pose < 126; ++pose) {
    for (const model::ToolCapsule& capsule : pressing_capsules(pose)) {
      std::size_t count = 0;
      (void)broad.query_segment(capsule.start_m, capsule.end_m, capsule.radius_m + 1e-4F, ids, count);
      candidates += static_cast<double>(count);
    }
  }
  state.counters["allocs"] = static_cast<double>(core::alloc::counted_allocations() - before);
  state.counters["contacts"] = step > 0 ? contacts / static_cast<double>(step) : 0.0;
  state.counters["candidates"] = candidates / (3.0 * 126.0);
}

void BM_FarParticles(benchmark::State& state) {
  const Tube tube = make_tube(kSizes[0]);
  BothBroadphases both = make_both(tube);
  const std::int64_t kind = state.range(0);
  const std::vector<float>& positions = tube.shapes[3];
  both.fit(kind, positions, tube.triangles);
  model::TriangleBroadPhase& broad = both.pick(kind);
  model::ParticleContactSettings settings;
  settings.max_particles = 21;
  settings.max_contacts = 84;
  settings.max_nodes = static_cast<std::uint32_t>(tube.rest.size() / 3);
  settings.stiffness_n_per_m = 200.0F;
  settings.damping_n_s_per_m = 0.01F;
  settings.surface_offset_m = 1e-4F;
  settings.max_force_n = 1.0F;
  settings.side = model::ContactSide::both;
  auto contact = model::ParticleSurfaceContact::create(settings, both.hash.arena);
  if (!contact) std::abort();
  const model::TriangleMeshView mesh{positions, tube.triangles};
  std::vector<Vec3> centres(21);
  for (std::size_t i = 0; i < centres.size(); ++i) {
    centres[i] = Vec3(0.015F + 0.001F * static_cast<float>(i), 0.002F, 0.03F);
  }
  model::ParticleContactOutput out;
  for (auto _ : state) {
    if (!contact->compute(centres, {}, kSphereRadiusM, mesh, {}, broad, out).is_ok()) std::abort();
    benchmark::DoNotOptimize(out.contact_count);
  }
}

BENCHMARK(BM_BroadRefit)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK(BM_BroadQuery)->ArgsProduct({{0, 1}, {1, 21}});
BENCHMARK(BM_SegmentContact)->Arg(0)->Arg(1);
BENCHMARK(BM_FarParticles)->Arg(0)->Arg(1);

BENCHMARK(BM_Rebuild)->Arg(640)->Arg(2560)->Arg(10240)->Arg(40960);
BENCHMARK(BM_Query)->ArgsProduct({{640, 2560, 10240, 40960}, {1, 8, 21, 64}});
BENCHMARK(BM_BruteForce)->ArgsProduct({{640, 2560}, {1, 21}});
BENCHMARK(BM_CellSize)->ArgsProduct({{640, 10240}, {25, 50, 100, 200, 400}});
BENCHMARK(BM_ProxyUpdate)->Arg(640)->Arg(10240)->Arg(40960);
BENCHMARK(BM_ParticleContact)->ArgsProduct({{640}, {21, 41}});

}  // namespace

BENCHMARK_MAIN();
