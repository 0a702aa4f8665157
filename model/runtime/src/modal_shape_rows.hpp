// Private to model/runtime, included by modal_model_impl.hpp: BasicModalModel::shape_rows, the
// one kernel that computes Φ_node q (issue 19; docs/collision.md "Lazy reconstruction"). Both
// reconstruct() (every node) and the lazy contact surface (rt/app LazyModalSurface: the nodes
// its queries touch) call this one compiled function, so a node's three values are the same
// bits on either path whatever the build's vector level: identity by construction, not by
// imitating Eigen's GEMV.
//
// Sum order of a row (kept from Eigen 3.4's row-major GEMV, which reconstruct() called before,
// so that the field, the golden traces and the state hashes did not move): Eigen's own packets
// accumulated with pmadd over whole packets from zero, predux, then the tail in order, added to
// a zeroed result (−0 becomes +0). Rows are independent; two nodes (six rows, six accumulator
// chains) are summed at once, which hides the add latency a single row's chain has.
#pragma once

#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

namespace trainer::model {
namespace detail {

// out[k] = Σ_j rows[k][j] q[j] for k < kRows, in the order described above.
template <typename Scalar, std::size_t kRows>
inline void modal_shape_dot(const Scalar* const (&rows)[kRows], const Scalar* q, std::size_t n,
                            Scalar* const (&out)[kRows]) noexcept {
  using Packet = typename Eigen::internal::packet_traits<Scalar>::type;
  constexpr std::size_t kSize = static_cast<std::size_t>(Eigen::internal::packet_traits<Scalar>::size);
  Packet c[kRows];
  for (std::size_t k = 0; k < kRows; ++k) c[k] = Eigen::internal::pset1<Packet>(Scalar(0));
  std::size_t j = 0;
  if constexpr (kSize > 1) {
    for (; j + kSize <= n; j += kSize) {
      const Packet b = Eigen::internal::ploadu<Packet>(q + j);
      for (std::size_t k = 0; k < kRows; ++k)
        c[k] = Eigen::internal::pmadd(Eigen::internal::ploadu<Packet>(rows[k] + j), b, c[k]);
    }
  }
  Scalar s[kRows];
  for (std::size_t k = 0; k < kRows; ++k) s[k] = Eigen::internal::predux(c[k]);
  for (; j < n; ++j) {
    for (std::size_t k = 0; k < kRows; ++k) s[k] += rows[k][j] * q[j];
  }
  for (std::size_t k = 0; k < kRows; ++k) *out[k] = Scalar(0) + s[k];
}

}  // namespace detail

template <typename Scalar>
void BasicModalModel<Scalar>::shape_rows(const std::uint32_t* nodes, std::size_t count,
                                         const Scalar* modes, Scalar* out_3n) const noexcept {
  const std::size_t stride = stored_modes_;
  const std::size_t n = active_modes_;
  const Scalar* shapes = mode_shapes_.data();
  const auto node_at = [nodes](std::size_t k) {
    return nodes != nullptr ? static_cast<std::size_t>(nodes[k]) : k;
  };
  std::size_t k = 0;
  for (; k + 2 <= count; k += 2) {
    const std::size_t a = 3 * node_at(k);
    const std::size_t b = 3 * node_at(k + 1);
    const Scalar* const rows[6] = {shapes + a * stride,       shapes + (a + 1) * stride,
                                   shapes + (a + 2) * stride, shapes + b * stride,
                                   shapes + (b + 1) * stride, shapes + (b + 2) * stride};
    Scalar* const out[6] = {out_3n + a, out_3n + a + 1, out_3n + a + 2,
                            out_3n + b, out_3n + b + 1, out_3n + b + 2};
    detail::modal_shape_dot<Scalar, 6>(rows, modes, n, out);
  }
  for (; k < count; ++k) {
    const std::size_t a = 3 * node_at(k);
    const Scalar* const rows[3] = {shapes + a * stride, shapes + (a + 1) * stride,
                                   shapes + (a + 2) * stride};
    Scalar* const out[3] = {out_3n + a, out_3n + a + 1, out_3n + a + 2};
    detail::modal_shape_dot<Scalar, 3>(rows, modes, n, out);
  }
}

}  // namespace trainer::model
