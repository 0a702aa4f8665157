// Deformed surfaces from the streamed state (the appliance sends modal coordinates, loads and
// contact displacements, never the mesh):
//   modal:  u = Φ q over the streamed modes, plus — when the image has a residual compliance —
//           the static correction R·F of the step's nodal loads, and the static part
//           Σ_{i ≥ streamed} φ_i φ_iᵀ F / ω_i² of stored modes the stream left out (what the
//           runtime adds when it integrates fewer modes than stored, modal_model.hpp);
//   tensor: the runtime's TensorModel solved for the streamed contact displacements, its
//           stored field scattered over all nodes (others stay at rest).
// Displacements are in the model frame, 3 floats per node.
#pragma once

#include <span>

#include "scene_assets.hpp"
#include "scene_frame.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::viewer {

// `out` has 3n floats. Refuses more coordinates than stored modes, or a load on an unknown node.
core::Expected<void> reconstruct_modal(const ModelAssets& model, const ModelState& state,
                                       std::span<float> out);

core::Expected<void> reconstruct_tensor(ModelAssets& model, const ModelState& state,
                                        std::span<float> out);

}  // namespace trainer::viewer
