// What one haptic cycle contributes to the trainee metrics (docs/metrics.md): the shared
// per-cycle sample of issue 18. The RT cycle (or a recording's "derived" block, or a replay)
// fills one per cycle; SessionMetrics consumes them. Trivially copyable and of fixed size so it
// can travel through a lock-free ring, a recording or a datagram unchanged.
//
// Frames and units: positions in the trainer frame, metres; forces in newtons; angles in
// radians; time on the cycle clock (CLOCK_MONOTONIC, or the simulated clock), nanoseconds.
#pragma once

#include <array>
#include <cstdint>
#include <type_traits>

namespace trainer::metrics {

inline constexpr std::size_t kMaxSampleInstruments = 4;

struct InstrumentSample {
  std::array<float, 3> tip_m{};  // instrument tip (jaw hinge side of the tip), trainer frame
  // Force the soft-tissue models and catheters put on the tool this cycle (the tool's reaction,
  // before the safety chain limits what the motors render), trainer frame. Its magnitude is
  // what the force metrics use.
  std::array<float, 3> tissue_force_n{};
  // Where the largest of those forces acts (trainer frame); read only when tissue_contact.
  std::array<float, 3> contact_point_m{};
  float grip_rad = 0.0F;             // jaw opening joint (0 = closed), radians
  std::uint8_t tissue_contact = 0;   // 1: a soft-tissue model or catheter touches the tool
  std::uint8_t grasping = 0;         // 1: the jaws hold a catheter this cycle
  std::array<std::uint8_t, 2> padding{};  // zero; keeps the layout explicit
};

struct CycleSample {
  std::uint64_t cycle = 0;           // cycle counter of the haptic loop
  std::int64_t time_ns = 0;          // the cycle's time on the loop clock (deadline or wake-up)
  std::uint32_t latched_faults = 0;  // safety::Fault bits latched at the end of the cycle
  std::uint32_t instrument_count = 0;  // entries of `instruments` in use (scene order)
  std::array<InstrumentSample, kMaxSampleInstruments> instruments{};
  // Catheter tip depth past the scene's [model.insertion] entry (the run's insertion depth,
  // rt/config InsertionGoalConfig), metres; NaN when the scene has no insertion goal.
  float insertion_depth_m = 0.0F;
  // Index (scene [[model]] order) of the model holding the largest tissue force this cycle;
  // -1 when nothing touches.
  std::int32_t contact_model = -1;
};

static_assert(std::is_trivially_copyable_v<InstrumentSample>);
static_assert(std::is_trivially_copyable_v<CycleSample>);
static_assert(sizeof(InstrumentSample) == 44);
static_assert(sizeof(CycleSample) == 24 + 4 * 44 + 8);

}  // namespace trainer::metrics
