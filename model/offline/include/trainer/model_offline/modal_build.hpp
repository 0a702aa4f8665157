// Builds a reduced-modal shell model end to end (METHODS.md §1): mesh → validated assembly with
// boundary conditions eliminated → the r lowest modes → damping → residual (static-correction)
// compliance of the surface nodes → truncation-error estimate → float32 image. `modelc build`
// calls this for every modal model a scene names; tests and benchmarks call it directly.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "trainer/core/expected.hpp"
#include "trainer/model/modal_model.hpp"
#include "trainer/model_offline/modal_analysis.hpp"
#include "trainer/model_offline/residual.hpp"
#include "trainer/model_offline/shell_model.hpp"

namespace trainer::model::offline {

struct ModalBuildSpec {
  std::string name;
  ShellMesh mesh;
  ShellMaterial material;
  BendingElement bending = BendingElement::dkt;
  std::vector<DofFix> fixes;
  int mode_count = 0;
  std::optional<ModalMethod> method;  // nullopt: shift-invert, or condensation for all modes
  double damping_ratio = 0.0;         // ζ, realised as Rayleigh damping fitted at ω_1 and ω_r
  double time_step_s = 0.0;           // the haptic period the image is prepared for
  bool static_correction = true;
  std::string surface_set;            // "" = every node with a free translation
  // Rayleigh damping to use instead of fitting ζ at ω_1 and ω_r: lets builds with different r
  // share one physical damping (the trade-off sweep and `modelc build --error-budget` fix it
  // at the definition's own mode count, so changing r changes the reduction, not the tissue).
  std::optional<RayleighDamping> damping_override;
};

struct ModalBuildTimings {
  double assembly_s = 0.0;
  double modes_s = 0.0;
  double residual_s = 0.0;
  double error_estimate_s = 0.0;
  double total_s = 0.0;
};

struct ModalBuildResult {
  AssembledShell shell;
  ModalBasis basis;
  RayleighDamping rayleigh;        // the system damping B = α_M M + β_K K
  Eigen::VectorXd modal_damping;   // α_i = α_M + β_K ω_i², 1/s
  std::vector<int> surface_nodes;  // strictly increasing
  std::optional<ResidualCompliance> residual;
  TruncationError truncation;      // static error of r modes without correction, surface loads
  ModalBuildTimings timings;
};

core::Expected<ModalBuildResult> build_modal_model(const ModalBuildSpec& spec);

// Copies of what the image would hold, in `Scalar`, viewed as the runtime model's data: for
// measuring the runtime model on a build without writing and reading an image file.
// FloatModalData rounds to float32 exactly as the image writer does (what the appliance runs);
// DoubleModalData keeps the build's doubles, so the same build can run in either precision
// (ModalModel and ModalModelDouble) and the difference is the runtime's precision alone.
template <typename Scalar>
class ModalDataCopy {
 public:
  ModalDataCopy(const ModalBuildSpec& spec, const ModalBuildResult& build);
  model::BasicModalModelData<Scalar> view() const;

 private:
  std::vector<Scalar> rest_positions_, mode_shapes_, omega_squared_, modal_damping_, residual_;
  std::vector<std::uint32_t> surface_nodes_;
  std::uint32_t node_count_ = 0;
  std::uint32_t mode_count_ = 0;
};

extern template class ModalDataCopy<float>;
extern template class ModalDataCopy<double>;
using FloatModalData = ModalDataCopy<float>;
using DoubleModalData = ModalDataCopy<double>;

// What an image built against an error budget records in its metadata (`error_budget`, and
// `error_estimate` = the error measured for the chosen configuration, worst over every
// scenario, tuning and held out; both fractions).
struct ErrorBudgetRecord {
  double budget = 0.0;
  double measured_error = 0.0;
};

// Writes the image (format: docs/model-image.md) atomically to `path`.
core::Expected<void> write_modal_image(const ModalBuildSpec& spec, const ModalBuildResult& result,
                                       const std::filesystem::path& path,
                                       const std::optional<ErrorBudgetRecord>& budget = {});

// Rayleigh coefficients giving damping ratio ζ exactly at ω_low and ω_high (ζ between them is
// slightly lower, outside higher): α_M = 2ζ ω_l ω_h/(ω_l+ω_h), β_K = 2ζ/(ω_l+ω_h).
RayleighDamping rayleigh_for_ratio(double damping_ratio, double omega_low, double omega_high);

}  // namespace trainer::model::offline
