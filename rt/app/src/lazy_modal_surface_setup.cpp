// LazyModalSurface's setup path (docs/collision.md "Lazy reconstruction"): the node clusters and
// the per-cluster maxima of the mode shapes and of the residual compliance its bound uses, and
// every array carved from the arena. The RT path is in lazy_modal_surface.cpp.
#include "trainer/app/lazy_modal_surface.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>
#include <vector>

namespace trainer::app {
namespace {

// Setup: the nodes split at the median of their rest positions along the longest axis of
// their box, down to clusters of at most `leaf` nodes (ties broken by node id: deterministic).
void lazy_surface_split(std::span<const float> rest, std::vector<std::uint32_t>& order, std::size_t first,
                        std::size_t last, std::size_t leaf, std::vector<std::uint32_t>& starts) {
  if (last - first <= leaf) {
    starts.push_back(static_cast<std::uint32_t>(last));
    return;
  }
  float low[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                  std::numeric_limits<float>::max()};
  float high[3] = {-low[0], -low[1], -low[2]};
  for (std::size_t k = first; k < last; ++k) {
    for (std::size_t a = 0; a < 3; ++a) {
      low[a] = std::min(low[a], rest[3 * order[k] + a]);
      high[a] = std::max(high[a], rest[3 * order[k] + a]);
    }
  }
  std::size_t axis = 0;
  for (std::size_t a = 1; a < 3; ++a) {
    if (high[a] - low[a] > high[axis] - low[axis]) axis = a;
  }
  const std::size_t middle = first + (last - first) / 2;
  std::nth_element(order.begin() + static_cast<std::ptrdiff_t>(first),
                   order.begin() + static_cast<std::ptrdiff_t>(middle),
                   order.begin() + static_cast<std::ptrdiff_t>(last), [&](std::uint32_t x, std::uint32_t y) {
                     const float px = rest[3 * x + axis];
                     const float py = rest[3 * y + axis];
                     return px < py || (px == py && x < y);
                   });
  lazy_surface_split(rest, order, first, middle, leaf, starts);
  lazy_surface_split(rest, order, middle, last, leaf, starts);
}

template <class T>
core::Status lazy_surface_carve(core::Arena& arena, std::size_t count, std::string_view what,
                                std::span<T>& out) {
  auto span = arena.allocate_array<T>(std::max<std::size_t>(count, 1), what);
  if (!span) return {core::StatusCode::capacity_exceeded, "lazy modal surface: arena exhausted"};
  out = span.value();
  return core::Status::ok();
}

}  // namespace

core::Expected<LazyModalSurface> LazyModalSurface::create(const model::ModalModelData& data,
                                                          const model::ModalModel& modal,
                                                          core::Arena& arena) {
  LazyModalSurface lazy;
  lazy.rest_ = data.rest_positions;
  lazy.shapes_ = data.mode_shapes;
  lazy.node_count_ = data.node_count;
  lazy.stored_modes_ = data.mode_count;
  lazy.active_modes_ = modal.active_mode_count();
  lazy.static_correction_ = modal.static_correction();
  lazy.surface_count_ = static_cast<std::uint32_t>(data.surface_nodes.size());
  if (lazy.static_correction_) lazy.residual_ = data.residual_compliance;
  lazy.lazy_allowed_ = !(lazy.static_correction_ && lazy.active_modes_ < lazy.stored_modes_);
  const std::size_t n = data.node_count;
  const std::size_t r = lazy.stored_modes_;
  const std::size_t active = lazy.active_modes_;
  const std::size_t s = lazy.surface_count_;
  if (n == 0 || data.rest_positions.size() != 3 * n || data.mode_shapes.size() != 3 * n * r || active > r) {
    return core::make_error("lazy modal surface: model data sizes disagree");
  }
  if (lazy.static_correction_ && lazy.residual_.size() != 9 * s * s) {
    return core::make_error("lazy modal surface: residual compliance is not 3s x 3s");
  }
  std::span<std::int32_t> index;
  if (!lazy_surface_carve(arena, n, "lazy surface: surface index", index).is_ok()) {
    return core::make_error("lazy modal surface: arena exhausted (surface index)");
  }
  std::fill(index.begin(), index.end(), -1);
  for (std::size_t k = 0; k < s; ++k) {
    if (data.surface_nodes[k] >= n) return core::make_error("lazy modal surface: surface node out of range");
    index[data.surface_nodes[k]] = static_cast<std::int32_t>(k);
  }
  lazy.surface_index_ = index;
  lazy.surface_first_node_ = s > 0 ? data.surface_nodes[0] : 0;
  lazy.surface_run_ = s > 0;
  for (std::size_t k = 0; k < s && lazy.surface_run_; ++k) {
    lazy.surface_run_ = data.surface_nodes[k] == lazy.surface_first_node_ + k;
  }

  // Clusters.
  std::vector<std::uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
  std::vector<std::uint32_t> starts{0};
  lazy_surface_split(data.rest_positions, order, 0, n, kClusterNodes, starts);
  const std::size_t clusters = starts.size() - 1;
  const std::size_t padded = (clusters + 7) / 8 * 8;
  lazy.cluster_stride_ = padded;
  std::vector<double> shape_max(clusters * active, 0.0);
  std::vector<double> residual_max(lazy.static_correction_ ? clusters * s : 0, 0.0);

  bool carved = lazy_surface_carve(arena, n, "lazy surface: cluster nodes", lazy.cluster_nodes_).is_ok() &&
                lazy_surface_carve(arena, clusters + 1, "lazy surface: clusters", lazy.cluster_start_).is_ok() &&
                lazy_surface_carve(arena, active * padded, "lazy surface: shape maxima", lazy.shape_max_t_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: row norms", lazy.row_norm_max_).is_ok() &&
                lazy_surface_carve(arena, clusters * 3 * active, "lazy surface: mean rows", lazy.centre_rows_).is_ok() &&
                lazy_surface_carve(arena, active * padded, "lazy surface: spread maxima", lazy.spread_max_t_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: spread norms", lazy.spread_norm_max_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: mode sums", lazy.mode_sum_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: load parts", lazy.load_part_).is_ok() &&
                lazy_surface_carve(arena, lazy.static_correction_ ? s * padded : 1, "lazy surface: residual maxima",
                                   lazy.residual_max_t_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: cluster epochs", lazy.cluster_epoch_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: used slack", lazy.used_m_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: bounds", lazy.bound_).is_ok() &&
                lazy_surface_carve(arena, kEpochs, "lazy surface: epochs", lazy.epochs_).is_ok() &&
                lazy_surface_carve(arena, active, "lazy surface: all shape maxima", lazy.all_shape_max_).is_ok() &&
                lazy_surface_carve(arena, s, "lazy surface: all residual maxima", lazy.all_residual_max_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: checked", lazy.checked_).is_ok() &&
                lazy_surface_carve(arena, clusters, "lazy surface: deviations", lazy.checked_deviation_).is_ok() &&
                lazy_surface_carve(arena, active, "lazy surface: modes", lazy.modes_).is_ok() &&
                lazy_surface_carve(arena, model::ModalModel::kMaxLoadedNodes, "lazy surface: loads", lazy.loads_)
                    .is_ok() &&
                lazy_surface_carve(arena, 3 * s, "lazy surface: residual scratch", lazy.full_residual_).is_ok() &&
                lazy_surface_carve(arena, n, "lazy surface: stamps", lazy.stamp_).is_ok() &&
                lazy_surface_carve(arena, 3 * n, "lazy surface: coordinate deviations", lazy.coordinate_deviation_)
                    .is_ok() &&
                lazy_surface_carve(arena, 3 * model::ModalModel::kMaxLoadedNodes, "lazy surface: load rows",
                                   lazy.load_rows_)
                    .is_ok() &&
                lazy_surface_carve(arena, 3 * model::ModalModel::kMaxLoadedNodes, "lazy surface: load forces",
                                   lazy.load_forces_)
                    .is_ok() &&
                lazy_surface_carve(arena, n, "lazy surface: pending", lazy.pending_).is_ok();
  for (std::size_t e = 0; carved && e < kEpochs; ++e) {
    Epoch& epoch = lazy.epochs_[e];
    carved = lazy_surface_carve(arena, active, "lazy surface: epoch modes", epoch.modes).is_ok() &&
             lazy_surface_carve(arena, model::ModalModel::kMaxLoadedNodes, "lazy surface: epoch loads", epoch.loads)
                 .is_ok() &&
             lazy_surface_carve(arena, active, "lazy surface: epoch mode changes", epoch.abs_dq).is_ok() &&
             lazy_surface_carve(arena, active, "lazy surface: epoch mode changes f", epoch.abs_dq_f).is_ok() &&
             lazy_surface_carve(arena, active, "lazy surface: epoch signed mode changes", epoch.dq_f).is_ok() &&
             lazy_surface_carve(arena, 2 * model::ModalModel::kMaxLoadedNodes, "lazy surface: epoch deltas",
                                epoch.delta_index)
                 .is_ok() &&
             lazy_surface_carve(arena, 2 * model::ModalModel::kMaxLoadedNodes, "lazy surface: epoch delta norms",
                                epoch.delta_norm)
                 .is_ok() &&
             lazy_surface_carve(arena, 2 * model::ModalModel::kMaxLoadedNodes, "lazy surface: epoch delta norms f",
                                epoch.delta_norm_f)
                 .is_ok();
  }
  if (!carved) return core::make_error("lazy modal surface: arena exhausted");
  lazy.cluster_nodes_ = lazy.cluster_nodes_.first(n);
  lazy.cluster_start_ = lazy.cluster_start_.first(clusters + 1);
  std::copy(order.begin(), order.end(), lazy.cluster_nodes_.begin());
  std::copy(starts.begin(), starts.end(), lazy.cluster_start_.begin());
  std::fill(lazy.shape_max_t_.begin(), lazy.shape_max_t_.end(), 0.0F);
  std::fill(lazy.spread_max_t_.begin(), lazy.spread_max_t_.end(), 0.0F);
  std::fill(lazy.row_norm_max_.begin(), lazy.row_norm_max_.end(), 0.0);
  std::fill(lazy.residual_max_t_.begin(), lazy.residual_max_t_.end(), 0.0F);
  std::fill(lazy.all_shape_max_.begin(), lazy.all_shape_max_.end(), 0.0);
  std::fill(lazy.all_residual_max_.begin(), lazy.all_residual_max_.end(), 0.0);
  std::fill(lazy.bound_.begin(), lazy.bound_.end(), std::numeric_limits<double>::quiet_NaN());
  std::fill(lazy.stamp_.begin(), lazy.stamp_.end(), std::uint64_t{0});

  // Per loaded surface node l and coordinate (k, a): ‖R_{(k,a),l}‖ as reconstruct() reads R
  // (row block l at column 3k + a, the symmetric orientation).
  std::vector<double> residual_norm;
  if (lazy.static_correction_) {
    const std::size_t stride = 3 * s;
    residual_norm.assign(s * stride, 0.0);
    for (std::size_t l = 0; l < s; ++l) {
      for (std::size_t b = 0; b < 3; ++b) {
        const float* row = lazy.residual_.data() + (3 * l + b) * stride;
        for (std::size_t column = 0; column < stride; ++column) {
          const double value = row[column];
          residual_norm[l * stride + column] += value * value;
          lazy.max_residual_entry_ = std::max(lazy.max_residual_entry_, std::abs(value));
        }
      }
    }
    for (double& value : residual_norm) value = std::sqrt(value);
  }
  for (std::size_t c = 0; c < clusters; ++c) {
    for (std::uint32_t k = lazy.cluster_start_[c]; k < lazy.cluster_start_[c + 1]; ++k) {
      const std::uint32_t node = lazy.cluster_nodes_[k];
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const float* row = data.mode_shapes.data() + (3 * static_cast<std::size_t>(node) + axis) * r;
        double squared = 0.0;
        for (std::size_t j = 0; j < active; ++j) {
          const double value = std::abs(static_cast<double>(row[j]));
          squared += value * value;
          shape_max[c * active + j] = std::max(shape_max[c * active + j], value);
          lazy.max_shape_entry_ = std::max(lazy.max_shape_entry_, value);
        }
        lazy.row_norm_max_[c] = std::max(lazy.row_norm_max_[c], std::sqrt(squared));
        lazy.max_rest_abs_ = std::max(lazy.max_rest_abs_,
                                      std::abs(static_cast<double>(data.rest_positions[3 * node + axis])));
        const std::int32_t surface = index[node];
        if (!lazy.static_correction_ || surface < 0) continue;
        const std::size_t column = 3 * static_cast<std::size_t>(surface) + axis;
        for (std::size_t l = 0; l < s; ++l) {
          residual_max[c * s + l] = std::max(residual_max[c * s + l], residual_norm[l * 3 * s + column]);
        }
      }
    }
    // The mean row per axis (rounded to float: the bound uses the stored value) and the rows'
    // spread about it (differences of floats: exact in double; maxima rounded up).
    const std::uint32_t members = lazy.cluster_start_[c + 1] - lazy.cluster_start_[c];
    double spread_norm = 0.0;
    for (std::size_t axis = 0; axis < 3; ++axis) {
      float* centre = lazy.centre_rows_.data() + (3 * c + axis) * active;
      for (std::size_t j = 0; j < active; ++j) {
        double sum = 0.0;
        for (std::uint32_t k = lazy.cluster_start_[c]; k < lazy.cluster_start_[c + 1]; ++k) {
          sum += static_cast<double>(data.mode_shapes[(3 * static_cast<std::size_t>(lazy.cluster_nodes_[k]) + axis) * r + j]);
        }
        centre[j] = static_cast<float>(sum / static_cast<double>(members));
      }
      for (std::uint32_t k = lazy.cluster_start_[c]; k < lazy.cluster_start_[c + 1]; ++k) {
        const float* row = data.mode_shapes.data() + (3 * static_cast<std::size_t>(lazy.cluster_nodes_[k]) + axis) * r;
        double squared = 0.0;
        for (std::size_t j = 0; j < active; ++j) {
          const double spread = std::abs(static_cast<double>(row[j]) - static_cast<double>(centre[j]));
          squared += spread * spread;
          float& stored = lazy.spread_max_t_[j * padded + c];
          stored = std::max(stored, float_up(spread));
        }
        spread_norm = std::max(spread_norm, std::sqrt(squared));
      }
    }
    lazy.spread_norm_max_[c] = spread_norm * (1.0 + 1e-12);
    // Float copies, transposed: |Φ| is a float already; a residual norm is rounded up.
    for (std::size_t j = 0; j < active; ++j) {
      lazy.all_shape_max_[j] = std::max(lazy.all_shape_max_[j], shape_max[c * active + j]);
      lazy.shape_max_t_[j * padded + c] = float_up(shape_max[c * active + j]);
    }
    lazy.all_row_norm_max_ = std::max(lazy.all_row_norm_max_, lazy.row_norm_max_[c]);
    for (std::size_t l = 0; lazy.static_correction_ && l < s; ++l) {
      lazy.all_residual_max_[l] = std::max(lazy.all_residual_max_[l], residual_max[c * s + l]);
      lazy.residual_max_t_[l * padded + c] = float_up(residual_max[c * s + l]);
    }
  }
  return lazy;
}

}  // namespace trainer::app
