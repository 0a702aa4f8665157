// Cotin's tensor model at run time: mutual-influence solve, superposition and the
// quasi-non-linear amplitude maps (tensor_model.hpp).
#include "trainer/model/tensor_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace trainer::model {

namespace {

using core::Status;
using core::StatusCode;

// A pivot below this fraction of the system's largest entry means two contacts are (nearly)
// the same constraint: the corrected displacements would be noise amplified by 1/pivot.
// T(k, k) = I, so a well-separated set of contacts has pivots near 1.
constexpr double kSingularPivotRatio = 1e-7;

std::string describe(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", value);
  return text;
}

// Splits `vector` into its part along the unit `direction` (signed amplitude) and the rest,
// maps both amplitudes and recombines. A zero direction leaves the vector unchanged.
Vec3 map_components(const Vec3& vector, const Vec3& direction, const AmplitudeMap& colinear,
                    const AmplitudeMap& orthogonal) noexcept {
  if (direction.squaredNorm() == 0.0F) return vector;
  const float along = vector.dot(direction);
  const Vec3 across = vector - along * direction;
  const float across_norm = across.norm();
  const float mapped_along = std::copysign(colinear.evaluate(std::fabs(along)), along);
  Vec3 result = mapped_along * direction;
  if (across_norm > 0.0F) result += (orthogonal.evaluate(across_norm) / across_norm) * across;
  return result;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// AmplitudeMap

AmplitudeMap::AmplitudeMap() noexcept {
  coefficients_[1] = 1.0F;
  count_ = 2;
  max_amplitude_ = std::numeric_limits<float>::infinity();
  value_at_max_ = 0.0F;
  slope_at_max_ = 1.0F;
  identity_ = true;
}

core::Expected<AmplitudeMap> AmplitudeMap::create(std::span<const double> coefficients,
                                                  double max_amplitude, std::string_view what) {
  const std::string name(what);
  if (coefficients.size() < 2 || coefficients.size() > kMaxCoefficients) {
    return core::make_error(name + ": " + std::to_string(coefficients.size()) +
                            " coefficients, expected 2.." + std::to_string(kMaxCoefficients) +
                            " (c0, c1, ... for degree 1..7)");
  }
  for (std::size_t i = 0; i < coefficients.size(); ++i) {
    if (!std::isfinite(coefficients[i]) ||
        std::fabs(coefficients[i]) > static_cast<double>(std::numeric_limits<float>::max())) {
      return core::make_error(name + ": coefficient c" + std::to_string(i) + " = " +
                              describe(coefficients[i]) + " is not a finite float");
    }
  }
  if (coefficients[0] != 0.0) {
    return core::make_error(name + ": c0 = " + describe(coefficients[0]) +
                            ", expected 0 (no contact, no displacement or force)");
  }
  if (!std::isfinite(max_amplitude) || !(max_amplitude > 0.0)) {
    return core::make_error(name + ": max_amplitude = " + describe(max_amplitude) +
                            ", expected a finite value > 0 (the end of the fitted range)");
  }
  const auto value = [&](double a) {
    double sum = 0.0;
    for (std::size_t i = coefficients.size(); i-- > 0;) sum = sum * a + coefficients[i];
    return sum;
  };
  const auto slope = [&](double a) {
    double sum = 0.0;
    for (std::size_t i = coefficients.size(); i-- > 1;) {
      sum = sum * a + static_cast<double>(i) * coefficients[i];
    }
    return sum;
  };
  // Monotone non-decreasing on [0, max]: the derivative sampled densely must not go negative
  // (a tolerance of 1e-9 of the largest slope absorbs rounding at a double root).
  constexpr int kSamples = 1024;
  double largest_slope = 0.0;
  for (int i = 0; i <= kSamples; ++i) {
    largest_slope = std::max(largest_slope, std::fabs(slope(max_amplitude * i / kSamples)));
  }
  if (!(largest_slope > 0.0)) {
    return core::make_error(name + ": the polynomial is constant on [0, max_amplitude]");
  }
  for (int i = 0; i <= kSamples; ++i) {
    const double a = max_amplitude * i / kSamples;
    if (slope(a) < -1e-9 * largest_slope || !std::isfinite(value(a))) {
      return core::make_error(name + ": the polynomial decreases at amplitude " + describe(a) +
                              " (slope " + describe(slope(a)) +
                              "): an amplitude map must not decrease on [0, max_amplitude = " +
                              describe(max_amplitude) + "]");
    }
  }
  if (value(max_amplitude) > static_cast<double>(std::numeric_limits<float>::max()) / 4) {
    return core::make_error(name + ": value at max_amplitude " + describe(value(max_amplitude)) +
                            " overflows float");
  }
  AmplitudeMap map;
  map.coefficients_.fill(0.0F);
  for (std::size_t i = 0; i < coefficients.size(); ++i) {
    map.coefficients_[i] = static_cast<float>(coefficients[i]);
  }
  map.count_ = coefficients.size();
  map.max_amplitude_ = static_cast<float>(max_amplitude);
  map.value_at_max_ = static_cast<float>(value(max_amplitude));
  map.slope_at_max_ = static_cast<float>(slope(max_amplitude));
  map.identity_ = coefficients.size() == 2 && coefficients[1] == 1.0;
  return map;
}

float AmplitudeMap::evaluate(float amplitude) const noexcept {
  if (identity_) return amplitude;
  if (amplitude > max_amplitude_) {
    return value_at_max_ + slope_at_max_ * (amplitude - max_amplitude_);
  }
  float sum = 0.0F;
  for (std::size_t i = count_; i-- > 0;) sum = sum * amplitude + coefficients_[i];
  return sum;
}

// ---------------------------------------------------------------------------------------
// TensorModel: setup

core::Expected<TensorModel> TensorModel::create(const TensorModelData& data,
                                                const TensorSettings& settings,
                                                core::Arena& arena) {
  const std::size_t contacts = data.contact_nodes.size();
  const std::size_t responses = data.response_nodes.size();
  if (data.node_count == 0 || contacts == 0 || responses == 0) {
    return core::make_error("tensor model: node count " + std::to_string(data.node_count) +
                            ", " + std::to_string(contacts) + " contact nodes, " +
                            std::to_string(responses) + " stored nodes: all must be > 0");
  }
  if (data.rest_positions.size() != 3ULL * data.node_count ||
      data.displacement_tensors.size() != 9ULL * contacts * responses ||
      data.force_tensors.size() != 9ULL * contacts) {
    return core::make_error(
        "tensor model: array sizes do not match: rest positions " +
        std::to_string(data.rest_positions.size()) + " (expected 3n = " +
        std::to_string(3ULL * data.node_count) + "), displacement tensors " +
        std::to_string(data.displacement_tensors.size()) + " (expected 9·s·r = " +
        std::to_string(9ULL * contacts * responses) + "), force tensors " +
        std::to_string(data.force_tensors.size()) + " (expected 9s)");
  }
  if (settings.max_contacts == 0 || settings.max_contacts > kMaxContactsLimit) {
    return core::make_error("tensor model: max_contacts " + std::to_string(settings.max_contacts) +
                            ", expected 1.." + std::to_string(kMaxContactsLimit));
  }
  const auto check_list = [&](std::span<const std::uint32_t> nodes,
                              const char* name) -> core::Expected<void> {
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      if (nodes[i] >= data.node_count || (i > 0 && nodes[i] <= nodes[i - 1])) {
        return core::make_error(std::string("tensor model: ") + name + " entry " +
                                std::to_string(i) + " (node " + std::to_string(nodes[i]) +
                                ") must be below " + std::to_string(data.node_count) +
                                " and greater than the entry before it");
      }
    }
    return {};
  };
  if (auto ok = check_list(data.contact_nodes, "contact node"); !ok) return std::move(ok).error();
  if (auto ok = check_list(data.response_nodes, "stored node"); !ok) return std::move(ok).error();

  TensorModel model;
  model.data_ = data;
  model.maps_ = settings.nonlinear;
  model.nonlinear_ = !(settings.nonlinear.displacement_colinear.is_identity() &&
                       settings.nonlinear.displacement_orthogonal.is_identity() &&
                       settings.nonlinear.force_colinear.is_identity() &&
                       settings.nonlinear.force_orthogonal.is_identity());
  model.max_contacts_ = settings.max_contacts;
  auto contact_response = arena.allocate_array<std::int32_t>(contacts, "tensor contact map");
  if (!contact_response) return std::move(contact_response).error();
  model.contact_response_ = contact_response.value();
  for (std::size_t k = 0; k < contacts; ++k) {
    const auto found = std::lower_bound(data.response_nodes.begin(), data.response_nodes.end(),
                                        data.contact_nodes[k]);
    if (found == data.response_nodes.end() || *found != data.contact_nodes[k]) {
      return core::make_error("tensor model: contact node " +
                              std::to_string(data.contact_nodes[k]) +
                              " has no stored response (it must be among the stored nodes)");
    }
    model.contact_response_[k] =
        static_cast<std::int32_t>(found - data.response_nodes.begin());
  }
  const std::size_t unknowns = 3ULL * settings.max_contacts;
  auto system = arena.allocate_array<double>(unknowns * unknowns, "tensor mutual-influence system");
  if (!system) return std::move(system).error();
  auto rhs = arena.allocate_array<double>(unknowns, "tensor right-hand side");
  if (!rhs) return std::move(rhs).error();
  auto slot_contact = arena.allocate_array<std::uint32_t>(settings.max_contacts, "tensor slots");
  if (!slot_contact) return std::move(slot_contact).error();
  auto corrected = arena.allocate_array<float>(unknowns, "tensor corrected constraints");
  if (!corrected) return std::move(corrected).error();
  auto imposed = arena.allocate_array<float>(unknowns, "tensor imposed displacements");
  if (!imposed) return std::move(imposed).error();
  auto force = arena.allocate_array<float>(unknowns, "tensor contact forces");
  if (!force) return std::move(force).error();
  auto field = arena.allocate_array<float>(3 * responses, "tensor displacement field");
  if (!field) return std::move(field).error();
  model.system_ = system.value();
  model.rhs_ = rhs.value();
  model.slot_contact_ = slot_contact.value();
  model.slot_corrected_ = corrected.value();
  model.slot_imposed_ = imposed.value();
  model.slot_force_ = force.value();
  model.field_ = field.value();
  std::fill(model.field_.begin(), model.field_.end(), 0.0F);
  return model;
}

// ---------------------------------------------------------------------------------------
// TensorModel: RT path

std::int32_t TensorModel::contact_index_of(std::uint32_t node) const noexcept {
  const auto found =
      std::lower_bound(data_.contact_nodes.begin(), data_.contact_nodes.end(), node);
  if (found == data_.contact_nodes.end() || *found != node) return -1;
  return static_cast<std::int32_t>(found - data_.contact_nodes.begin());
}

std::int32_t TensorModel::response_index_of(std::uint32_t node) const noexcept {
  const auto found =
      std::lower_bound(data_.response_nodes.begin(), data_.response_nodes.end(), node);
  if (found == data_.response_nodes.end() || *found != node) return -1;
  return static_cast<std::int32_t>(found - data_.response_nodes.begin());
}

core::Status TensorModel::solve(std::span<const TensorContact> contacts) noexcept {
  const std::size_t m = contacts.size();
  if (m > max_contacts_) {
    return Status{StatusCode::capacity_exceeded, "more contacts than the model's max_contacts"};
  }
  // Validate everything before touching the accepted solution.
  for (std::size_t i = 0; i < m; ++i) {
    if (contact_index_of(contacts[i].node) < 0) {
      return Status{StatusCode::invalid_argument, "contact on a node that is not a contact node"};
    }
    if (!contacts[i].displacement_m.allFinite()) {
      return Status{StatusCode::numeric_error, "non-finite imposed displacement"};
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (contacts[j].node == contacts[i].node) {
        return Status{StatusCode::invalid_argument, "two contacts on one node"};
      }
    }
  }
  const std::size_t n = 3 * m;
  // A(i, j) block = T(k_i, k_j): the displacement of contact node i per unit displacement
  // imposed at contact node j.
  double largest = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const auto ki = static_cast<std::uint32_t>(contact_index_of(contacts[i].node));
    const auto response = static_cast<std::uint32_t>(contact_response_[ki]);
    for (std::size_t j = 0; j < m; ++j) {
      const auto kj = static_cast<std::uint32_t>(contact_index_of(contacts[j].node));
      const float* t = tensor(kj, response);
      for (std::size_t r = 0; r < 3; ++r) {
        for (std::size_t c = 0; c < 3; ++c) {
          const double value = static_cast<double>(t[3 * r + c]);
          system_[(3 * i + r) * n + 3 * j + c] = value;
          largest = std::max(largest, std::fabs(value));
        }
      }
    }
    for (std::size_t r = 0; r < 3; ++r) {
      rhs_[3 * i + r] = static_cast<double>(contacts[i].displacement_m[static_cast<int>(r)]);
    }
  }
  // Gaussian elimination with partial pivoting, in place, the right-hand side eliminated
  // alongside; then back substitution.
  double smallest_pivot = std::numeric_limits<double>::infinity();
  for (std::size_t col = 0; col < n; ++col) {
    std::size_t pivot_row = col;
    double pivot_abs = std::fabs(system_[col * n + col]);
    for (std::size_t row = col + 1; row < n; ++row) {
      const double candidate = std::fabs(system_[row * n + col]);
      if (candidate > pivot_abs) {
        pivot_abs = candidate;
        pivot_row = row;
      }
    }
    smallest_pivot = std::min(smallest_pivot, pivot_abs);
    if (!(pivot_abs > kSingularPivotRatio * largest)) {
      return Status{StatusCode::numeric_error, "contacts too close: mutual-influence system singular"};
    }
    if (pivot_row != col) {
      for (std::size_t c = 0; c < n; ++c) {
        std::swap(system_[col * n + c], system_[pivot_row * n + c]);
      }
      std::swap(rhs_[col], rhs_[pivot_row]);
    }
    const double pivot = system_[col * n + col];
    for (std::size_t row = col + 1; row < n; ++row) {
      const double factor = system_[row * n + col] / pivot;
      if (factor == 0.0) continue;
      system_[row * n + col] = factor;
      for (std::size_t c = col + 1; c < n; ++c) system_[row * n + c] -= factor * system_[col * n + c];
      rhs_[row] -= factor * rhs_[col];
    }
  }
  for (std::size_t row = n; row-- > 0;) {
    double sum = rhs_[row];
    for (std::size_t c = row + 1; c < n; ++c) sum -= system_[row * n + c] * rhs_[c];
    rhs_[row] = sum / system_[row * n + row];
    if (!std::isfinite(rhs_[row])) {
      return Status{StatusCode::numeric_error, "non-finite corrected constraint"};
    }
  }

  // Accept: corrected constraints and linear forces; then the non-linear force map.
  Vec3 imposed_sum = Vec3::Zero();
  for (std::size_t i = 0; i < m; ++i) imposed_sum += contacts[i].displacement_m;
  const float imposed_norm = imposed_sum.norm();
  direction_ = imposed_norm > 0.0F ? Vec3(imposed_sum / imposed_norm) : Vec3::Zero();
  Vec3 total_along = Vec3::Zero();
  Vec3 total_across = Vec3::Zero();
  for (std::size_t i = 0; i < m; ++i) {
    const auto k = static_cast<std::uint32_t>(contact_index_of(contacts[i].node));
    slot_contact_[i] = k;
    const Vec3 corrected(static_cast<float>(rhs_[3 * i]), static_cast<float>(rhs_[3 * i + 1]),
                         static_cast<float>(rhs_[3 * i + 2]));
    const Eigen::Map<const Eigen::Matrix<float, 3, 3, Eigen::RowMajor>> force_tensor(
        data_.force_tensors.data() + 9 * static_cast<std::size_t>(k));
    const Vec3 force = force_tensor * corrected;
    const Vec3 along = force.dot(direction_) * direction_;
    total_along += along;
    total_across += force - along;
    Eigen::Map<Vec3>(slot_corrected_.data() + 3 * i) = corrected;
    Eigen::Map<Vec3>(slot_imposed_.data() + 3 * i) = contacts[i].displacement_m;
    Eigen::Map<Vec3>(slot_force_.data() + 3 * i) = force;
  }
  if (nonlinear_ && direction_.squaredNorm() > 0.0F) {
    // The total force along the push follows the colinear map and the total across it the
    // orthogonal map; each contact keeps its linear share of both totals.
    const float along_linear = total_along.dot(direction_);
    const float across_linear = total_across.norm();
    const float along_scale =
        along_linear != 0.0F
            ? std::copysign(maps_.force_colinear.evaluate(std::fabs(along_linear)), along_linear) /
                  along_linear
            : 1.0F;
    const float across_scale =
        across_linear > 0.0F ? maps_.force_orthogonal.evaluate(across_linear) / across_linear
                             : 1.0F;
    for (std::size_t i = 0; i < m; ++i) {
      Eigen::Map<Vec3> force(slot_force_.data() + 3 * i);
      const Vec3 along = force.dot(direction_) * direction_;
      force = along_scale * along + across_scale * (force - along);
    }
  }
  contact_count_ = m;
  last_pivot_ratio_ = m == 0 ? 1.0 : smallest_pivot / largest;
  return Status{};
}

Vec3 TensorModel::contact_force(std::size_t index) const noexcept {
  if (index >= contact_count_) return Vec3::Zero();
  return {slot_force_[3 * index], slot_force_[3 * index + 1], slot_force_[3 * index + 2]};
}

Vec3 TensorModel::total_force() const noexcept {
  Vec3 total = Vec3::Zero();
  for (std::size_t i = 0; i < contact_count_; ++i) total += contact_force(i);
  return total;
}

Vec3 TensorModel::linear_contribution(std::size_t slot, std::uint32_t response) const noexcept {
  const Eigen::Map<const Eigen::Matrix<float, 3, 3, Eigen::RowMajor>> t(
      tensor(slot_contact_[slot], response));
  return t * Eigen::Map<const Vec3>(slot_corrected_.data() + 3 * slot);
}

Vec3 TensorModel::node_displacement(std::uint32_t node) const noexcept {
  const std::int32_t response = response_index_of(node);
  Vec3 sum = Vec3::Zero();
  if (response < 0) return sum;
  for (std::size_t slot = 0; slot < contact_count_; ++slot) {
    sum += linear_contribution(slot, static_cast<std::uint32_t>(response));
  }
  if (!nonlinear_) return sum;
  return map_components(sum, direction_, maps_.displacement_colinear,
                        maps_.displacement_orthogonal);
}

void TensorModel::update_field() noexcept {
  std::fill(field_.begin(), field_.end(), 0.0F);
  const auto responses = static_cast<std::uint32_t>(data_.response_nodes.size());
  // Stream each contact's tensors once (the hot loop of the field update).
  for (std::size_t slot = 0; slot < contact_count_; ++slot) {
    const float* t = tensor(slot_contact_[slot], 0);
    const float d0 = slot_corrected_[3 * slot];
    const float d1 = slot_corrected_[3 * slot + 1];
    const float d2 = slot_corrected_[3 * slot + 2];
    for (std::uint32_t j = 0; j < responses; ++j, t += 9) {
      float* u = field_.data() + 3 * static_cast<std::size_t>(j);
      u[0] += t[0] * d0 + t[1] * d1 + t[2] * d2;
      u[1] += t[3] * d0 + t[4] * d1 + t[5] * d2;
      u[2] += t[6] * d0 + t[7] * d1 + t[8] * d2;
    }
  }
  if (!nonlinear_ || contact_count_ == 0) return;
  for (std::uint32_t j = 0; j < responses; ++j) {
    Eigen::Map<Vec3> u(field_.data() + 3 * static_cast<std::size_t>(j));
    u = map_components(u, direction_, maps_.displacement_colinear, maps_.displacement_orthogonal);
  }
}

}  // namespace trainer::model
