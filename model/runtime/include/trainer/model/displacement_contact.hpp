// Displacement-driven contact of a tool tip on a deformable triangle surface (the modal duct,
// Basdogan §VII; METHODS.md §4): when the tip reaches the surface, the material point it
// touched is made to follow the tip, the model computes the forces that impose that
// displacement (ModalModel::solve_imposed), and the tool feels their opposite.
//
// One instance per (tool, surface). Per cycle, in the surface model's frame:
//   1. update(): free → contact when the tip's path since the last cycle crosses a triangle
//      from its outward side, or the tip sphere (radius r) touches a triangle on its outward
//      side. The contact point is kept as a triangle and barycentric coordinates: a material
//      point, which moves with the deforming mesh. A contact holds (sticking: the material
//      point does not slide) until released.
//   2. targets(): the imposed displacement of the material point, u* = tip − r n − X_rest(b)
//      (its surface touches the tip sphere; n is the triangle's current outward normal),
//      given to every free node of the contact triangle (Cotin's split of an imposed
//      displacement to the triangle's vertices: equal shares keep the material point exactly
//      on u*). Fixed nodes are left out; a triangle whose nodes are all fixed is no contact.
//   3. observe_force(): with the forces the model solved, release the contact when the
//      tissue would be pulled outward (adhesion is not modelled): a withdrawing tool lets go
//      the first cycle its imposed displacement would lift the surface off its equilibrium.
// Runtime code: float, noexcept, no heap after create(); positions are 3n float spans.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"
#include "trainer/model/bucket_grid.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model/proxy.hpp"

namespace trainer::model {

struct DisplacementContactSettings {
  float tip_radius_m = 0.0F;           // ≥ 0: the tool tip's sphere
  std::uint32_t max_candidates = 256;  // triangles one grid query may return
};

class DisplacementContact {
 public:
  static constexpr std::size_t kMaxTargets = 3;

  // `fixed_nodes`: strictly increasing node indices that cannot be displaced (the image's
  // fixed_nodes); the span must outlive the contact.
  static core::Expected<DisplacementContact> create(const DisplacementContactSettings& settings,
                                                    std::span<const std::uint32_t> fixed_nodes,
                                                    core::Arena& arena);

  // ---- RT path ----

  // Starts a contact (see above) or keeps the current one. `deformed` is the surface now, the
  // grid rebuilt over it. Refuses non-finite tips (numeric_error, contact released).
  core::Status update(const TriangleMeshView& deformed, TriangleBroadPhase& grid,
                      const Vec3& previous_tip_m, const Vec3& tip_m) noexcept;

  // Imposed displacements for the contact's free nodes into `out` (≥ kMaxTargets entries);
  // returns how many (0 without contact).
  std::size_t targets(const TriangleMeshView& deformed, std::span<const float> rest_positions_m,
                      const Vec3& tip_m, std::span<ImposedDisplacement> out) const noexcept;

  // The summed force the model applies to the tissue for this contact's targets (N); releases
  // the contact when it pulls the surface outward.
  void observe_force(const TriangleMeshView& deformed, const Vec3& force_on_tissue_n) noexcept;

  void release() noexcept { in_contact_ = false; }

  bool in_contact() const noexcept { return in_contact_; }
  std::uint32_t triangle() const noexcept { return triangle_; }
  const Vec3& barycentric() const noexcept { return barycentric_; }
  std::uint64_t onsets() const noexcept { return onsets_; }

 private:
  bool is_fixed(std::uint32_t node) const noexcept;

  DisplacementContactSettings settings_;
  std::span<const std::uint32_t> fixed_nodes_;
  std::span<std::uint32_t> candidates_;
  bool in_contact_ = false;
  std::uint32_t triangle_ = 0;
  Vec3 barycentric_ = Vec3::Zero();
  std::uint64_t onsets_ = 0;
};

}  // namespace trainer::model
