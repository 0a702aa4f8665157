// A modal surface's broad phase as the contact stages hand it to the narrow phases: every query
// as ContactSurface::broad_phase() answers it, and the repeated ones (a tool capsule's segment,
// a catheter particle's sphere, cycle after cycle) from the caller's QueryCache through
// TriangleBvh's cached queries with the lazy surface's stated deviation, that surface then
// making the vertices of the triangles returned this step's, as its own queries do
// (docs/collision.md "Cached queries"). Built on the stack per stage call; RT path.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>

#include "trainer/app/contact_surface.hpp"
#include "trainer/app/lazy_modal_surface.hpp"
#include "trainer/model/broad_phase.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace trainer::app {

class CachedQueries final : public model::TriangleBroadPhase {
 public:
  explicit CachedQueries(ContactSurface& surface) noexcept : surface_(surface) {}

  core::Status query(const model::Aabb& box, std::span<std::uint32_t> out_ids,
                     std::size_t& out_count) noexcept override {
    return surface_.broad_phase().query(box, out_ids, out_count);
  }
  core::Status query_segment(const model::Vec3& p0, const model::Vec3& p1, float margin_m,
                             std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept override {
    return surface_.broad_phase().query_segment(p0, p1, margin_m, out_ids, out_count);
  }
  core::Status query_segment_cached(const model::Vec3& p0, const model::Vec3& p1, float margin_m,
                                    model::QueryCache& cache, std::span<std::uint32_t> out_ids,
                                    std::size_t& out_count) noexcept override {
    out_count = 0;
    if (!surface_.grid) return core::Status::ok();
    LazyModalSurface* const lazy = surface_.lazy;
    const core::Status status = surface_.grid->query_segment_cached_within(
        p0, p1, margin_m, lazy != nullptr ? lazy->stated_deviation_m() : -1.0F, cache, out_ids, out_count);
    if (lazy != nullptr) lazy->make_current(out_ids.first(std::min(out_count, out_ids.size())));
    return status;
  }
  core::Status query_sphere_cached(const model::Vec3& centre, float radius_m, model::QueryCache& cache,
                                   std::span<std::uint32_t> out_ids, std::size_t& out_count) noexcept override {
    out_count = 0;
    if (!surface_.grid) return core::Status::ok();
    LazyModalSurface* const lazy = surface_.lazy;
    const core::Status status = surface_.grid->query_sphere_cached_within(
        centre, radius_m, lazy != nullptr ? lazy->stated_deviation_m() : -1.0F, cache, out_ids, out_count);
    if (lazy != nullptr) lazy->make_current(out_ids.first(std::min(out_count, out_ids.size())));
    return status;
  }

 private:
  ContactSurface& surface_;
};

}  // namespace trainer::app
