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
// chains) are summed at once, which hides the add latency a single row's chain has; a full pass
// (every node in order) sums four nodes at once and reduces four rows per transpose
// (modal_shape_dot_12: the same operations per row; the duct's 336 nodes 2.8-3.0 → 2.3-2.5 µs).
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include <Eigen/Core>

#if defined(__SSE2__)
#include <xmmintrin.h>
#endif

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

#if defined(__SSE2__)
// Twelve consecutive rows (four consecutive nodes) into out[0..11], each summed exactly as
// modal_shape_dot sums it with 4-wide packets (Eigen's Packet4f) for n a multiple of 4 (no
// tail): twelve chains instead of six, and the reductions four rows at a time. A row's predux
// is (a0 + a2) + (a1 + a3) (Eigen's SSE predux: a + movehl(a), then lane 0 + lane 1), so after a
// 4 × 4 transpose the same sums for four rows are three packet adds; then + 0 and one store.
inline void modal_shape_dot_12(const float* rows, std::size_t stride, const float* q, std::size_t n,
                               float* out) noexcept {
  using Eigen::internal::padd;
  using Eigen::internal::ploadu;
  using Eigen::internal::pmadd;
  constexpr std::size_t kRows = 12;
  __m128 c[kRows];
  for (__m128& packet : c) packet = _mm_setzero_ps();
  for (std::size_t j = 0; j < n; j += 4) {
    const __m128 b = ploadu<Eigen::internal::Packet4f>(q + j);
    for (std::size_t k = 0; k < kRows; ++k) c[k] = pmadd(ploadu<Eigen::internal::Packet4f>(rows + k * stride + j), b, c[k]);
  }
  for (std::size_t g = 0; g < kRows; g += 4) {
    __m128 r0 = c[g];
    __m128 r1 = c[g + 1];
    __m128 r2 = c[g + 2];
    __m128 r3 = c[g + 3];
    _MM_TRANSPOSE4_PS(r0, r1, r2, r3);  // r_l: lane l of the four rows
    const __m128 sum = padd(padd(r0, r2), padd(r1, r3));
    _mm_storeu_ps(out + g, padd(_mm_setzero_ps(), sum));
  }
}
#endif

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
#if defined(__SSE2__)
  if constexpr (std::is_same_v<Scalar, float> && Eigen::internal::packet_traits<float>::size == 4) {
    // Every node in order (a full pass): four nodes' twelve rows are consecutive rows of the
    // matrix and consecutive values of out_3n.
    if (nodes == nullptr && n % 4 == 0) {
      for (; k + 4 <= count; k += 4) {
        detail::modal_shape_dot_12(shapes + 3 * k * stride, stride, modes, n, out_3n + 3 * k);
      }
    }
  }
#endif
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
