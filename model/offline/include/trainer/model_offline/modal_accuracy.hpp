// Accuracy and cost of the reduced-modal model against the full-system reference (DNIOS),
// Basdogan Appendix B-C: the same mesh, damping, time step and load history integrated by
// (a) the runtime ModalModel (float32 data, as the appliance runs it) with r modes, with and
// without static correction, and (b) FullNewmark on every dof (double, sparse Cholesky).
// Errors are relative to the reference; costs are medians of per-step wall-clock times measured
// in the same process, one after the other, so their ratio is the speedup on this machine.
#pragma once

#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::model::offline {

struct AccuracyScenario {
  std::string name;
  Eigen::Vector3d load_point_m;  // the load goes to the surface node nearest this point
  Eigen::Vector3d force_n;       // full force, reached by a linear ramp
  double ramp_s = 0.02;
  double duration_s = 0.3;
};

struct AccuracyPoint {
  std::string scenario;
  int load_node = -1;
  int modes = 0;
  bool static_correction = false;
  double local_error = 0.0;  // max_t |u_m − u_ref| at the loaded node / max_t |u_ref| there
  double field_error = 0.0;  // RMS over time and nodes of |u_m − u_ref| / RMS of |u_ref|
  double final_local_error = 0.0;  // at the last step (quasi-static by then)
  double modal_step_ns = 0.0;      // median: force projection + step + loaded-node displacement
  double reference_step_ns = 0.0;  // median: FullNewmark step + displacement
  double speedup = 0.0;            // reference_step_ns / modal_step_ns
};

// For each r in `mode_counts` (≤ the basis' modes) and static correction off/on (on only when
// the build has residual compliance), integrates `scenario` with both models.
core::Expected<std::vector<AccuracyPoint>> measure_modal_accuracy(
    const ModalBuildSpec& spec, const ModalBuildResult& build, std::span<const int> mode_counts,
    const AccuracyScenario& scenario);

}  // namespace trainer::model::offline
