// The catheter's beam-to-chain derivation (docs/catheter.md): parameter checks, the chain
// constants and stable substep, the substep count of a haptic period, and the rest shape —
// shared by Catheter::create(params, setup) and the offline image writer.
#include "trainer/model/catheter_chain.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "catheter_refusal.hpp"

namespace trainer::model {

using detail::catheter_number;
using detail::catheter_positive_finite;
using detail::catheter_refusal;
namespace {

core::Expected<void> check_params(const CatheterParams& params) {
  if (params.particle_count < 3 || params.particle_count > kMaxCatheterParticles) {
    return catheter_refusal("particle_count = " + std::to_string(params.particle_count) +
                            ": expected 3.." + std::to_string(kMaxCatheterParticles));
  }
  if (!catheter_positive_finite(params.length_m))
    return catheter_refusal("length_m = " + catheter_number(params.length_m) + ": expected > 0");
  if (!catheter_positive_finite(params.outer_radius_m)) {
    return catheter_refusal("outer_radius_m = " + catheter_number(params.outer_radius_m) +
                            ": expected > 0");
  }
  if (!catheter_positive_finite(params.bending_stiffness_n_m2)) {
    return catheter_refusal("bending_stiffness_n_m2 (EI) = " +
                            catheter_number(params.bending_stiffness_n_m2) + ": expected > 0");
  }
  if (!catheter_positive_finite(params.axial_stiffness_n)) {
    return catheter_refusal(
        "axial_stiffness_n (EA) = " + catheter_number(params.axial_stiffness_n) + ": expected > 0");
  }
  if (!catheter_positive_finite(params.linear_density_kg_per_m)) {
    return catheter_refusal("linear_density_kg_per_m = " +
                            catheter_number(params.linear_density_kg_per_m) + ": expected > 0");
  }
  if (!std::isfinite(params.damping_n_s_per_m) || params.damping_n_s_per_m < 0.0F) {
    return catheter_refusal("damping_n_s_per_m = " + catheter_number(params.damping_n_s_per_m) +
                            ": expected >= 0");
  }
  if (!std::isfinite(params.contact_stiffness_n_per_m) || params.contact_stiffness_n_per_m < 0.0F) {
    return catheter_refusal("contact stiffness = " +
                            catheter_number(params.contact_stiffness_n_per_m) + ": expected >= 0");
  }
  return {};
}

}  // namespace

double catheter_stable_substep_s(double mass_kg, double bending_n_m_per_rad, double rest_length_m,
                                 double contact_stiffness_n_per_m) noexcept {
  (void)contact_stiffness_n_per_m;
  const double omega_max_squared =
      kCatheterRemainderShare * 20.0 * bending_n_m_per_rad / (mass_kg * rest_length_m * rest_length_m);
  return 2.0 / std::sqrt(omega_max_squared);
}

core::Expected<CatheterChain> derive_catheter_chain(const CatheterParams& params) {
  if (auto ok = check_params(params); !ok) return std::move(ok).error();
  const double count = static_cast<double>(params.particle_count);
  const double rest_length_m = static_cast<double>(params.length_m) / (count - 1.0);
  const double mass_kg = static_cast<double>(params.linear_density_kg_per_m) *
                         static_cast<double>(params.length_m) / count;
  const double axial_n_per_m = static_cast<double>(params.axial_stiffness_n) / rest_length_m;
  const double bending_n_m = static_cast<double>(params.bending_stiffness_n_m2) / rest_length_m;
  CatheterChain chain;
  chain.particle_count = params.particle_count;
  chain.rest_length_m = static_cast<float>(rest_length_m);
  chain.particle_mass_kg = static_cast<float>(mass_kg);
  chain.axial_n_per_m = static_cast<float>(axial_n_per_m);
  chain.bending_n_m_per_rad = static_cast<float>(bending_n_m);
  chain.radius_m = params.outer_radius_m;
  chain.damping_n_s_per_m = params.damping_n_s_per_m;
  chain.stable_substep_s = static_cast<float>(
      catheter_stable_substep_s(mass_kg, bending_n_m, rest_length_m,
                                static_cast<double>(params.contact_stiffness_n_per_m)));
  return chain;
}

std::uint64_t catheter_substeps_for(double period_s, double substep_s) noexcept {
  const double ratio = std::ceil(period_s / substep_s - 1e-9);  // exact multiples stay exact
  if (ratio < 1.0) return 1U;
  // A substep so small (a denormal from an image, say) that the count does not fit: converting
  // that double would be undefined behaviour. Saturate; every budget refuses it.
  constexpr double kTwoTo64 = 18446744073709551616.0;
  if (!(ratio < kTwoTo64)) return std::numeric_limits<std::uint64_t>::max();
  return static_cast<std::uint64_t>(ratio);
}

core::Expected<std::uint32_t> catheter_substeps_per_period(const CatheterParams& params,
                                                           const CatheterChain& chain,
                                                           float haptic_period_s,
                                                           std::uint32_t max_substeps) {
  if (!catheter_positive_finite(haptic_period_s)) {
    return catheter_refusal("haptic_period_s = " + catheter_number(haptic_period_s) +
                            ": expected > 0");
  }
  if (max_substeps == 0) return catheter_refusal("max_substeps = 0: expected >= 1");
  // step() divides the period by the stored float substep, so count with that same value: the
  // double one can round to a float a few ulp smaller, and a period within rounding of a
  // multiple of it would then need one substep more at run time than counted here (a catheter
  // accepted at exactly max_substeps would refuse every step).
  const std::uint64_t needed = catheter_substeps_for(static_cast<double>(haptic_period_s),
                                                     static_cast<double>(chain.stable_substep_s));
  if (needed > max_substeps) {
    return catheter_refusal(
        "a haptic period of " + catheter_number(haptic_period_s) + " s needs " +
        std::to_string(needed) + " substeps of at most " + catheter_number(chain.stable_substep_s) +
        " s (the largest substep of the linearly implicit chain, from EI = " +
        catheter_number(params.bending_stiffness_n_m2) + " N·m², particle mass " +
        catheter_number(chain.particle_mass_kg) + " kg, segment " +
        catheter_number(chain.rest_length_m) + " m; EA = " +
        catheter_number(params.axial_stiffness_n) + " N, damping " +
        catheter_number(chain.damping_n_s_per_m) +
        " N·s/m and contacts do not limit it) but max_substeps = " + std::to_string(max_substeps) +
        ": raise max_substeps, use fewer particles, a softer EI, or a shorter period");
  }
  return static_cast<std::uint32_t>(needed);
}

core::Expected<Eigen::Vector3f> catheter_rest_direction(const Eigen::Vector3f& direction) {
  const float norm = direction.norm();
  if (!catheter_positive_finite(norm))
    return catheter_refusal("direction: expected a finite non-zero vector");
  return Eigen::Vector3f(direction / norm);
}

void place_catheter_rest(const Eigen::Vector3f& start_m, const Eigen::Vector3f& unit_direction,
                         float rest_length_m, std::span<Eigen::Vector3f> positions_m) noexcept {
  for (std::size_t i = 0; i < positions_m.size(); ++i) {
    positions_m[i] = start_m + (static_cast<float>(i) * rest_length_m) * unit_direction;
  }
}

}  // namespace trainer::model
