// Private to model/runtime: the contact solve of BasicModalModel<Scalar> (solve_imposed and
// its caches: the compliance blocks per node pair, the free responses, the factorisations),
// included at the end of modal_model_impl.hpp, so in the same translation units (one per
// instantiation) as the rest of the model.
#pragma once

#include "trainer/model/modal_model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace trainer::model {
namespace detail {

#if defined(__SSE2__)
// The two lanes of a packed pair of sums, low and high (the values as computed, no rounding).
inline void store_lanes(__m128d pair, double& low, double& high) noexcept {
  low = _mm_cvtsd_f64(pair);
  high = _mm_cvtsd_f64(_mm_unpackhi_pd(pair, pair));
}
#endif

inline constexpr int kMaxContactRows = 3 * static_cast<int>(BasicModalModel<float>::kMaxContacts);
// A contact compliance whose smallest LDLᵀ pivot is below this fraction of the largest is
// treated as singular: with float data (relative error ~1e-7), below ~1e-8 the solved forces
// would be rounding noise (e.g. a fixed node, or nearly dependent shape rows). The double model
// keeps the same bound so that both precisions accept and refuse the same contact sets (a
// comparison of the two then times and measures the same work).
inline constexpr double kMinPivotRatio = 1e-8;
inline constexpr std::uint32_t kNoSlot = static_cast<std::uint32_t>(-1);

using ContactVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxContactRows, 1>;

}  // namespace detail

// The nine sums run side by side over the modes (nine independent dependency chains instead of
// one at a time: the sums are latency-bound), each in its own mode order, so every entry is
// the same sequence of roundings as a sum computed alone: s += (x·y)·k. With SSE2 the nine
// chains sit in the lanes of five registers (two entries per packed multiply and add, the same
// IEEE operations per lane), no longer spilled to the stack: ~235 → ~100 ns per block
// (40 modes, warm; docs/performance.md "Modal contact solve", round 5).
template <typename Scalar>
void BasicModalModel<Scalar>::modal_compliance_block(std::uint32_t node_a, std::uint32_t node_b,
                                                     double (&block)[3][3]) const noexcept {
  const Scalar* a0 = shape_row(node_a, 0);
  const Scalar* a1 = shape_row(node_a, 1);
  const Scalar* a2 = shape_row(node_a, 2);
  const Scalar* b0 = shape_row(node_b, 0);
  const Scalar* b1 = shape_row(node_b, 1);
  const Scalar* b2 = shape_row(node_b, 2);
#if defined(__SSE2__)
  __m128d s0 = _mm_setzero_pd();  // s00 s01
  __m128d s1 = _mm_setzero_pd();  // s10 s11
  __m128d s2 = _mm_setzero_pd();  // s20 s21
  __m128d s3 = _mm_setzero_pd();  // s02 s12
  __m128d s4 = _mm_setzero_pd();  // s22 (low lane)
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const __m128d k = _mm_set1_pd(inverse_k_hat_[i]);
    const __m128d x0 = _mm_set1_pd(static_cast<double>(a0[i]));
    const __m128d x1 = _mm_set1_pd(static_cast<double>(a1[i]));
    const __m128d x2 = _mm_set1_pd(static_cast<double>(a2[i]));
    const __m128d y01 = _mm_set_pd(static_cast<double>(b1[i]), static_cast<double>(b0[i]));
    const __m128d y2 = _mm_set1_pd(static_cast<double>(b2[i]));
    const __m128d x01 = _mm_unpacklo_pd(x0, x1);
    s0 = _mm_add_pd(s0, _mm_mul_pd(_mm_mul_pd(x0, y01), k));
    s1 = _mm_add_pd(s1, _mm_mul_pd(_mm_mul_pd(x1, y01), k));
    s2 = _mm_add_pd(s2, _mm_mul_pd(_mm_mul_pd(x2, y01), k));
    s3 = _mm_add_pd(s3, _mm_mul_pd(_mm_mul_pd(x01, y2), k));
    s4 = _mm_add_sd(s4, _mm_mul_sd(_mm_mul_sd(x2, y2), k));
  }
  detail::store_lanes(s0, block[0][0], block[0][1]);
  detail::store_lanes(s1, block[1][0], block[1][1]);
  detail::store_lanes(s2, block[2][0], block[2][1]);
  detail::store_lanes(s3, block[0][2], block[1][2]);
  block[2][2] = _mm_cvtsd_f64(s4);
#else
  double s00 = 0.0, s01 = 0.0, s02 = 0.0, s10 = 0.0, s11 = 0.0, s12 = 0.0, s20 = 0.0, s21 = 0.0,
         s22 = 0.0;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const double k = inverse_k_hat_[i];
    const auto x0 = static_cast<double>(a0[i]);
    const auto x1 = static_cast<double>(a1[i]);
    const auto x2 = static_cast<double>(a2[i]);
    const auto y0 = static_cast<double>(b0[i]);
    const auto y1 = static_cast<double>(b1[i]);
    const auto y2 = static_cast<double>(b2[i]);
    s00 += x0 * y0 * k;
    s01 += x0 * y1 * k;
    s02 += x0 * y2 * k;
    s10 += x1 * y0 * k;
    s11 += x1 * y1 * k;
    s12 += x1 * y2 * k;
    s20 += x2 * y0 * k;
    s21 += x2 * y1 * k;
    s22 += x2 * y2 * k;
  }
  block[0][0] = s00;
  block[0][1] = s01;
  block[0][2] = s02;
  block[1][0] = s10;
  block[1][1] = s11;
  block[1][2] = s12;
  block[2][0] = s20;
  block[2][1] = s21;
  block[2][2] = s22;
#endif
}

// The blocks of two cached nodes (a ≠ b: both orientations; a = b: the diagonal block, its
// upper triangle computed and mirrored, as a solve from scratch does).
template <typename Scalar>
void BasicModalModel<Scalar>::fill_cache_blocks(std::uint32_t slot_a,
                                                std::uint32_t slot_b) noexcept {
  ContactCache& cache = *contact_cache_;
  const std::uint32_t node_a = cache.nodes[slot_a];
  const std::uint32_t node_b = cache.nodes[slot_b];
  const auto entry = [&cache](std::uint32_t slot_row, int axis_row, std::uint32_t slot_column,
                              int axis_column) -> double& {
    return cache.compliance[(3 * static_cast<std::size_t>(slot_row) +
                             static_cast<std::size_t>(axis_row)) *
                                kContactRows +
                            3 * static_cast<std::size_t>(slot_column) +
                            static_cast<std::size_t>(axis_column)];
  };
  double block[3][3];
  modal_compliance_block(node_a, node_b, block);
  for (int axis_a = 0; axis_a < 3; ++axis_a) {
    for (int axis_b = (slot_a == slot_b ? axis_a : 0); axis_b < 3; ++axis_b) {
      const double modal = block[axis_a][axis_b];
      double value = modal;
      if (static_correction_) value += residual_entry(node_a, axis_a, node_b, axis_b);
      entry(slot_a, axis_a, slot_b, axis_b) = value;
      if (slot_a == slot_b) {
        entry(slot_b, axis_b, slot_a, axis_a) = value;
        continue;
      }
      // The transposed entry: the same modal sum (products commute, summed in the same
      // order); the residual compliance read in its own orientation, as a solve with node b
      // first reads it.
      double transposed = modal;
      if (static_correction_) {
        transposed = residual_symmetric_ ? value
                                         : transposed + residual_entry(node_b, axis_b, node_a, axis_a);
      }
      entry(slot_b, axis_b, slot_a, axis_a) = transposed;
    }
  }
  cache.pair_valid[slot_a * kMaxContacts + slot_b] = true;
  cache.pair_valid[slot_b * kMaxContacts + slot_a] = true;
}

template <typename Scalar>
void BasicModalModel<Scalar>::gather_contact_slots(
    std::span<const BasicImposedDisplacement<Scalar>> targets,
    std::span<std::uint32_t> slot_of) noexcept {
  ContactCache& cache = *contact_cache_;
  bool used[kMaxContacts] = {};
  for (std::size_t k = 0; k < targets.size(); ++k) {
    slot_of[k] = detail::kNoSlot;
    for (std::uint32_t slot = 0; slot < cache.slot_count; ++slot) {
      if (cache.nodes[slot] == targets[k].node) {
        slot_of[k] = slot;
        used[slot] = true;
        break;
      }
    }
  }
  for (std::size_t k = 0; k < targets.size(); ++k) {
    if (slot_of[k] != detail::kNoSlot) continue;
    // A free slot, else one no target uses (there is one: at most kMaxContacts targets, and
    // this one is not cached).
    std::uint32_t slot = 0;
    if (cache.slot_count < kMaxContacts) {
      slot = cache.slot_count++;
    } else {
      while (used[slot]) ++slot;
    }
    used[slot] = true;
    cache.nodes[slot] = targets[k].node;
    cache.response_epoch[slot] = 0;
    for (std::size_t other = 0; other < kMaxContacts; ++other) {
      cache.pair_valid[slot * kMaxContacts + other] = false;
      cache.pair_valid[other * kMaxContacts + slot] = false;
    }
    slot_of[k] = slot;
  }
  // Only the blocks this solve needs (pairs of its targets) are computed.
  std::uint8_t new_pairs[kMaxContacts * (kMaxContacts + 1) / 2][2];
  std::size_t new_count = 0;
  for (std::size_t k = 0; k < targets.size(); ++k) {
    for (std::size_t l = k; l < targets.size(); ++l) {
      if (!cache.pair_valid[slot_of[k] * kMaxContacts + slot_of[l]]) {
        new_pairs[new_count][0] = static_cast<std::uint8_t>(k);
        new_pairs[new_count][1] = static_cast<std::uint8_t>(l);
        ++new_count;
      }
    }
  }
  if (new_count == 0) return;
  // The memory the new blocks read is requested first, all of it, so that the misses overlap
  // instead of each one stalling its own block: the shape rows of the nodes in new pairs
  // (3 × stored modes values) and, with static correction, the three rows of R a block reads
  // (each in its own 4 KB page of the 4 MB residual compliance: a cache and TLB miss when
  // cold). Prefetches change no value.
  const std::size_t stride = 3 * static_cast<std::size_t>(surface_count_);
  const std::size_t shape_bytes = 3 * static_cast<std::size_t>(stored_modes_) * sizeof(Scalar);
  bool fetched[kMaxContacts] = {};
  for (std::size_t p = 0; p < new_count; ++p) {
    for (const std::uint8_t k : new_pairs[p]) {
      if (fetched[k]) continue;
      fetched[k] = true;
      const auto* rows = reinterpret_cast<const char*>(shape_row(targets[k].node, 0));
      for (std::size_t offset = 0; offset < shape_bytes; offset += 64)
        __builtin_prefetch(rows + offset);
      __builtin_prefetch(rows + shape_bytes - 1);
    }
    if (!static_correction_) continue;
    const std::uint32_t node_k = targets[new_pairs[p][0]].node;
    const std::uint32_t node_l = targets[new_pairs[p][1]].node;
    for (int orientation = 0; orientation < (residual_symmetric_ ? 1 : 2); ++orientation) {
      const Scalar* block = orientation == 0
                                ? compliance_block(surface_index_[node_k], surface_index_[node_l])
                                : compliance_block(surface_index_[node_l], surface_index_[node_k]);
      for (std::size_t axis = 0; axis < 3; ++axis) {
        __builtin_prefetch(block + axis * stride);
        __builtin_prefetch(block + axis * stride + 2);
      }
    }
  }
  for (std::size_t p = 0; p < new_count; ++p)
    fill_cache_blocks(slot_of[new_pairs[p][0]], slot_of[new_pairs[p][1]]);
}

// Free responses (Φ_node x⁺₀, from predicted_) of the nodes in three cache slots (a slot may
// repeat: it is then computed twice, to the same value): nine sums side by side, each in mode
// order, the same sequence of roundings as one computed alone. Three nodes at a time hide the
// sums' latency (one node's three chains wait on the adds).
template <typename Scalar>
void BasicModalModel<Scalar>::free_responses(std::uint32_t slot_a, std::uint32_t slot_b,
                                             std::uint32_t slot_c) noexcept {
  ContactCache& cache = *contact_cache_;
  const Scalar* a0 = shape_row(cache.nodes[slot_a], 0);
  const Scalar* a1 = shape_row(cache.nodes[slot_a], 1);
  const Scalar* a2 = shape_row(cache.nodes[slot_a], 2);
  const Scalar* b0 = shape_row(cache.nodes[slot_b], 0);
  const Scalar* b1 = shape_row(cache.nodes[slot_b], 1);
  const Scalar* b2 = shape_row(cache.nodes[slot_b], 2);
  const Scalar* c0 = shape_row(cache.nodes[slot_c], 0);
  const Scalar* c1 = shape_row(cache.nodes[slot_c], 1);
  const Scalar* c2 = shape_row(cache.nodes[slot_c], 2);
  double* ra = cache.free_response + 3 * static_cast<std::size_t>(slot_a);
  double* rb = cache.free_response + 3 * static_cast<std::size_t>(slot_b);
  double* rc = cache.free_response + 3 * static_cast<std::size_t>(slot_c);
#if defined(__SSE2__) && !defined(__AVX__)
  // Two sums per packed multiply and add (the same IEEE operations per lane), no spills: 132 →
  // 109 ns per three nodes in the generic build; with AVX (x86-64-v3) GCC's own loop below is
  // not spilled and faster (88 vs 96 ns), so it stays there.
  __m128d sa01 = _mm_setzero_pd();
  __m128d sa2b0 = _mm_setzero_pd();
  __m128d sb12 = _mm_setzero_pd();
  __m128d sc01 = _mm_setzero_pd();
  __m128d sc2 = _mm_setzero_pd();
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const __m128d p = _mm_set1_pd(predicted_[i]);
    sa01 = _mm_add_pd(
        sa01, _mm_mul_pd(_mm_set_pd(static_cast<double>(a1[i]), static_cast<double>(a0[i])), p));
    sa2b0 = _mm_add_pd(
        sa2b0, _mm_mul_pd(_mm_set_pd(static_cast<double>(b0[i]), static_cast<double>(a2[i])), p));
    sb12 = _mm_add_pd(
        sb12, _mm_mul_pd(_mm_set_pd(static_cast<double>(b2[i]), static_cast<double>(b1[i])), p));
    sc01 = _mm_add_pd(
        sc01, _mm_mul_pd(_mm_set_pd(static_cast<double>(c1[i]), static_cast<double>(c0[i])), p));
    sc2 = _mm_add_sd(sc2, _mm_mul_sd(_mm_set_sd(static_cast<double>(c2[i])), p));
  }
  detail::store_lanes(sa01, ra[0], ra[1]);
  detail::store_lanes(sa2b0, ra[2], rb[0]);
  detail::store_lanes(sb12, rb[1], rb[2]);
  detail::store_lanes(sc01, rc[0], rc[1]);
  rc[2] = _mm_cvtsd_f64(sc2);
#else
  double sa0 = 0.0, sa1 = 0.0, sa2 = 0.0, sb0 = 0.0, sb1 = 0.0, sb2 = 0.0, sc0 = 0.0, sc1 = 0.0,
         sc2 = 0.0;
  for (std::size_t i = 0; i < active_modes_; ++i) {
    const double p = predicted_[i];
    sa0 += static_cast<double>(a0[i]) * p;
    sa1 += static_cast<double>(a1[i]) * p;
    sa2 += static_cast<double>(a2[i]) * p;
    sb0 += static_cast<double>(b0[i]) * p;
    sb1 += static_cast<double>(b1[i]) * p;
    sb2 += static_cast<double>(b2[i]) * p;
    sc0 += static_cast<double>(c0[i]) * p;
    sc1 += static_cast<double>(c1[i]) * p;
    sc2 += static_cast<double>(c2[i]) * p;
  }
  ra[0] = sa0;
  ra[1] = sa1;
  ra[2] = sa2;
  rb[0] = sb0;
  rb[1] = sb1;
  rb[2] = sb2;
  rc[0] = sc0;
  rc[1] = sc1;
  rc[2] = sc2;
#endif
}

// The same target nodes in the same order as one of the kept factorisations: the same matrix
// (every entry a constant of the model), so that factorisation stands. Otherwise the upper
// triangle of Φ_K diag(1/k̂) Φ_Kᵀ + R_KK is gathered from the contact cache (row node first,
// as a cold solve computes it), mirrored below, factorised into the least recently used entry
// and checked.
template <typename Scalar>
const Eigen::LDLT<typename BasicModalModel<Scalar>::ContactMatrix>*
BasicModalModel<Scalar>::contact_factorisation(
    std::span<const BasicImposedDisplacement<Scalar>> targets,
    std::span<const std::uint32_t> slot_of) noexcept {
  FactorisationCache& kept = *factorisations_;
  const std::size_t c = targets.size();
  ++kept.clock;
  Factorisation* victim = &kept.entries[0];
  for (Factorisation& entry : kept.entries) {
    bool same_nodes = entry.count == c;
    for (std::size_t k = 0; same_nodes && k < c; ++k)
      same_nodes = entry.nodes[k] == targets[k].node;
    if (same_nodes) {
      entry.last_use = kept.clock;
      return &entry.ldlt;
    }
    if (entry.last_use < victim->last_use) victim = &entry;
  }
  ContactCache& cache = *contact_cache_;
  const auto rows = static_cast<Eigen::Index>(3 * c);
  victim->count = 0;
  ContactMatrix compliance(rows, rows);
  for (std::size_t k = 0; k < c; ++k) {
    const std::size_t cache_row = 3 * static_cast<std::size_t>(slot_of[k]);
    for (int axis_k = 0; axis_k < 3; ++axis_k) {
      const Eigen::Index row = static_cast<Eigen::Index>(3 * k) + axis_k;
      const double* cached =
          cache.compliance + (cache_row + static_cast<std::size_t>(axis_k)) * kContactRows;
      for (std::size_t l = k; l < c; ++l) {
        const std::size_t cache_column = 3 * static_cast<std::size_t>(slot_of[l]);
        for (int axis_l = (l == k ? axis_k : 0); axis_l < 3; ++axis_l) {
          const Eigen::Index column = static_cast<Eigen::Index>(3 * l) + axis_l;
          const double value = cached[cache_column + static_cast<std::size_t>(axis_l)];
          compliance(row, column) = value;
          compliance(column, row) = value;
        }
      }
    }
  }
  ++kept.computed;
  victim->ldlt.compute(compliance);
  const detail::ContactVector pivots = victim->ldlt.vectorD();
  if (victim->ldlt.info() != Eigen::Success ||
      !(pivots.minCoeff() > detail::kMinPivotRatio * pivots.maxCoeff())) {
    return nullptr;
  }
  for (std::size_t k = 0; k < c; ++k) victim->nodes[k] = targets[k].node;
  victim->count = c;
  victim->last_use = kept.clock;
  return &victim->ldlt;
}

template <typename Scalar>
core::Status BasicModalModel<Scalar>::solve_imposed(
    std::span<const BasicImposedDisplacement<Scalar>> targets,
    std::span<Vector3> forces_out) noexcept {
  const std::size_t c = targets.size();
  if (c == 0) return core::Status::ok();
  if (c > kMaxContacts) {
    return {core::StatusCode::capacity_exceeded,
            "modal model: more imposed displacements than kMaxContacts"};
  }
  if (forces_out.size() < c) {
    return {core::StatusCode::invalid_argument, "modal model: forces_out shorter than targets"};
  }
  std::size_t new_nodes = 0;
  for (std::size_t k = 0; k < c; ++k) {
    const std::uint32_t node = targets[k].node;
    if (node >= node_count_)
      return {core::StatusCode::invalid_argument, "modal model: unknown contact node"};
    if (!targets[k].displacement_m.allFinite()) {
      return {core::StatusCode::numeric_error, "modal model: non-finite imposed displacement"};
    }
    if (static_correction_ && surface_index_[node] < 0) {
      return {core::StatusCode::invalid_argument,
              "modal model: contact on a non-surface node with static correction on"};
    }
    for (std::size_t l = 0; l < k; ++l) {
      if (targets[l].node == node) {
        return {core::StatusCode::invalid_argument, "modal model: contact node imposed twice"};
      }
    }
    if (find_pending(node) == detail::kNotFound) ++new_nodes;
  }
  if (pending_count_ + new_nodes > kMaxLoadedNodes) {
    return {core::StatusCode::capacity_exceeded, "modal model: too many loaded nodes"};
  }
  if (!static_correction_ && active_modes_ < 3 * c) {
    return {core::StatusCode::invalid_argument,
            "modal model: fewer active modes than imposed components (enable static correction)"};
  }

  // Next-step modal displacement without the new forces: x⁺₀ = (Φᵀ F + a0 x + a2 v + a)/k̂,
  // needed only for a node whose free response this step is not cached yet.
  project_pending_forces();
  std::array<std::uint32_t, kMaxContacts> slot_of{};
  gather_contact_slots(targets, slot_of);
  ContactCache& cache = *contact_cache_;
  // A free response is cached only when no load is applied (the usual case at the first solve
  // of a step, and after a release's clear_forces()): with loads, it depends on them.
  const bool unloaded = pending_count_ == 0;
  const std::span<const NodeLoad> pending{pending_loads_.data(), pending_count_};
  // The slots whose free response this step is not cached yet, computed three nodes at a time.
  std::array<std::uint32_t, kMaxContacts> fresh{};
  std::size_t fresh_count = 0;
  for (std::size_t k = 0; k < c; ++k) {
    const std::uint32_t slot = slot_of[k];
    if (!unloaded || cache.response_epoch[slot] != state_epoch_) {
      fresh[fresh_count++] = slot;
      cache.response_epoch[slot] = unloaded ? state_epoch_ : 0;
    }
  }
  if (fresh_count > 0) {
    for (std::size_t i = 0; i < active_modes_; ++i) {
      predicted_[i] =
          (modal_force_[i] + a0_[i] * x_[i] + a2_[i] * v_[i] + a_[i]) * inverse_k_hat_[i];
    }
    for (std::size_t first = 0; first < fresh_count; first += 3) {
      const std::size_t last = fresh_count - 1;
      free_responses(fresh[first], fresh[std::min(first + 1, last)],
                     fresh[std::min(first + 2, last)]);
    }
  }
  const auto rows = static_cast<Eigen::Index>(3 * c);
  detail::ContactVector rhs(rows);
  for (std::size_t k = 0; k < c; ++k) {
    const std::uint32_t node_k = targets[k].node;
    const double* free_response = cache.free_response + 3 * static_cast<std::size_t>(slot_of[k]);
    const Eigen::Vector3d static_part = static_response(node_k, pending);
    for (int axis_k = 0; axis_k < 3; ++axis_k) {
      const Eigen::Index row = static_cast<Eigen::Index>(3 * k) + axis_k;
      rhs[row] = static_cast<double>(targets[k].displacement_m[axis_k]) - free_response[axis_k] -
                 static_part[axis_k];
    }
  }
  const Eigen::LDLT<ContactMatrix>* factorisation = contact_factorisation(targets, slot_of);
  if (factorisation == nullptr) {
    return {core::StatusCode::numeric_error,
            "modal model: contact compliance singular (fixed node or dependent contacts)"};
  }
  const detail::ContactVector forces = factorisation->solve(rhs);
  // Forces are returned as Scalar: one that would overflow it is refused like a non-finite one.
  constexpr double kScalarMax = static_cast<double>(std::numeric_limits<Scalar>::max());
  for (Eigen::Index j = 0; j < rows; ++j) {
    if (!std::isfinite(forces[j]) || std::abs(forces[j]) > kScalarMax) {
      return {core::StatusCode::numeric_error, "modal model: non-finite contact force"};
    }
  }
  for (std::size_t k = 0; k < c; ++k) {
    const Eigen::Vector3d force = forces.segment<3>(static_cast<Eigen::Index>(3 * k));
    forces_out[k] = force.cast<Scalar>();
    // Cannot fail: node, finiteness, surface membership and capacity were checked above.
    (void)add_force(targets[k].node, force);
  }
  return core::Status::ok();
}

}  // namespace trainer::model
