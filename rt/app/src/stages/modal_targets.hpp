// The imposed displacements one modal model takes from the instruments this cycle: each tip's
// material point (DisplacementContact) and each shaft/jaw wall contact (SegmentSurfaceContact,
// ray-based), gathered by the modal stage before its contact solve. Model frame throughout.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "trainer/app/cycle_frame.hpp"
#include "trainer/app/scene_models.hpp"

namespace trainer::app {

// Shaft and jaws against a duct wall: the touched wall point is imposed this far inside the
// capsule's reach (not at its edge), so the contact persists from one cycle to the next instead
// of ending the moment the wall sits exactly at the reach and springing back the next.
inline constexpr float kSegmentSkinM = 5e-4F;
// The shaft is tested only inside the surface's rest box grown by this much.
inline constexpr float kSegmentClipMarginM = 0.01F;

// One shaft/jaw contact on a modal model this cycle, imposed with the tips' targets.
struct SegmentTarget {
  std::size_t instrument = 0;
  model::ToolSegment segment = model::ToolSegment::shaft;
  float along_m = 0.0F;
  float depth_m = 0.0F;
  Eigen::Vector3f normal = Eigen::Vector3f::UnitZ();      // towards the tool
  Eigen::Vector3f on_tissue_n = Eigen::Vector3f::Zero();  // from the solve
  bool active = true;
};

struct ModalTargets {
  static constexpr std::size_t kCapacity = model::ModalModel::kMaxContacts;
  std::array<model::ImposedDisplacement, kCapacity> targets{};
  std::array<std::size_t, kCapacity> owner{};        // the instrument imposing each
  std::array<std::int32_t, kCapacity> segment_of{};  // −1 for a tip, else its index in segments
  std::size_t count = 0;
  std::array<SegmentTarget, kMaxInstruments * model::SegmentSurfaceContact::kMaxSegments>
      segments{};
  std::size_t segment_count = 0;

  // Keeps the targets whose contact still holds (tips: their contact, segments: active).
  void keep_holding(const ContactSurface& surface) noexcept;
};

// Every touching tip's imposed displacements; a contact that would need more than the
// model's capacity is released (its tool feels nothing rather than a wrong force). Raises the
// instruments' model_indentation_m.
void gather_tip_targets(ModalModelState& state, std::span<InstrumentFrame> instruments,
                        ModalTargets& out, std::uint64_t& errors) noexcept;

// The shaft and jaw contacts of the instruments touching the model, appended after the tips'
// (nodes already imposed keep their target; a contact with no node left, or beyond the
// capacity, is left out this cycle).
void gather_segment_targets(ModalModelState& state, std::span<const InstrumentFrame> instruments,
                            ModalTargets& out, std::uint64_t& errors) noexcept;

}  // namespace trainer::app
