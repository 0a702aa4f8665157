// What the viewer serves to the page (docs/viewer.md, "Page protocol"):
//   GET /scene.json   the scene: models (kind, counts, placement, where their static data is),
//                     instruments, the frame layout and where reconstruction happens;
//   GET /model/<i>.bin  model i's static data: rest positions and triangles, plus — when the
//                     browser reconstructs — the mode shapes, ω², surface nodes and residual
//                     compliance;
//   WebSocket /ws     one binary message per frame (layout below), text messages with the
//                     session panel's JSON and the stream status (refusals, faults).
// Binary frame "TVF1", little-endian, every field 4-byte aligned so the page reads it through
// typed arrays without copying:
//   0  u32 magic 0x31465654 ("TVF1")   4  u32 header bytes (80)
//   8  u64 stream sequence            16  u64 appliance cycle
//   24 i64 cycle time ns              32  i64 sent by the appliance ns
//   40 i64 received by the viewer ns  48  i64 handed to the WebSocket ns   (CLOCK_REALTIME)
//   56 f64 reconstruction time in the viewer, µs
//   64 u32 latched faults             68  u32 flags (bit 0: the browser reconstructs)
//   72 u32 model count                76  u32 instrument count
//   80 per model, scene order: u32 float count f, u32 load count l, f × f32, l × (u32 node,
//      3 × f32 force N). f32 are: 3n displacements (model frame) of a modal or tensor model
//      rebuilt in the viewer; the r modal coordinates of a modal model the browser rebuilds
//      (then the loads follow, for its static correction); 3N particle positions (trainer
//      frame) of a catheter.
//   then per instrument 16 × f32 (trainer frame): shaft start, hinge, jaw 0 tip, jaw 1 tip,
//      commanded force on the tool (N), flags (telemetry InstrumentFlag bits as a float);
//   then u32 contact count c, c × 7 f32: point (m), force on the tissue (N), instrument index.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "scene_assets.hpp"
#include "scene_frame.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::viewer {

enum class Reconstruction : std::uint8_t { viewer, browser };

constexpr std::uint32_t kViewFrameMagic = 0x31465654U;  // "TVF1"
constexpr std::size_t kViewFrameHeaderBytes = 80;
constexpr std::size_t kViewFrameHandedOffset = 48;
constexpr std::size_t kInstrumentFloats = 16;
constexpr std::size_t kContactFloats = 7;

std::int64_t realtime_now_ns() noexcept;

class ViewFrameEncoder {
 public:
  ViewFrameEncoder(SceneAssets& assets, Reconstruction reconstruction);

  // Rebuilds the surfaces (in the viewer or not, per the reconstruction choice) and writes the
  // binary frame into `out` (resized). Refuses a frame whose model or instrument counts differ
  // from the scene's, or whose state does not rebuild (reconstruct.hpp).
  core::Expected<void> encode(const SceneFrame& frame, std::vector<std::byte>& out);

  // Stamps the "handed to the WebSocket" time into an encoded frame.
  static void stamp_handed(std::vector<std::byte>& frame, std::int64_t ns) noexcept;

  std::string scene_json() const;
  std::vector<std::byte> model_blob(std::size_t index) const;
  Reconstruction reconstruction() const noexcept { return reconstruction_; }

 private:
  SceneAssets& assets_;
  Reconstruction reconstruction_;
  std::vector<float> scratch_;
};

}  // namespace trainer::viewer
