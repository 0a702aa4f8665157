// Private to model/runtime: what triangle_bvh.cpp (build, refit, queries) and
// triangle_bvh_cache.cpp (the cached queries) share: the arena carve with the hierarchy's error
// prefix, a vertex of a flat position array, and the traversal template TriangleBvh::collect.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "arena_carve.hpp"
#include "trainer/model/triangle_bvh.hpp"

namespace trainer::model {
namespace bvh_detail {

template <class T>
core::Expected<std::span<T>> carve_bvh(core::Arena& arena, std::size_t count, std::string_view what) {
  return detail::carve_array<T>(arena, count, what, "triangle bvh");
}

inline Vec3 bvh_vertex(std::span<const float> positions, std::uint32_t v) noexcept {
  const std::size_t base = 3 * static_cast<std::size_t>(v);
  return {positions[base], positions[base + 1], positions[base + 2]};
}

}  // namespace bvh_detail

template <class Accept4>
core::Status TriangleBvh::collect(Accept4&& accept4, std::span<std::uint32_t> out_ids,
                                  std::size_t& out_count) noexcept {
  out_count = 0;
  if (!ready_) return core::Status::ok();
  // A pop pushes at most 4 and the wide tree is at most depth_ levels deep.
  std::uint32_t stack[3 * kMaxDepth + 4];
  std::size_t stack_size = 0;
  stack[stack_size++] = 0;
  std::size_t low_word = hit_bits_.size();
  std::size_t high_word = 0;
  while (stack_size > 0) {
    const WideNode& node = wide_[stack[--stack_size]];
    unsigned lanes = accept4(node.boxes);
    while (lanes != 0) {
      const auto lane = static_cast<std::size_t>(std::countr_zero(lanes));
      lanes &= lanes - 1;
      if (node.packs[lane] == 0) {
        stack[stack_size++] = node.child[lane];
        continue;
      }
      for (std::uint32_t pack = node.child[lane]; pack < node.child[lane] + node.packs[lane]; ++pack) {
        unsigned hits = accept4(leaf_packs_[pack]);
        while (hits != 0) {
          const auto bit = static_cast<std::size_t>(std::countr_zero(hits));
          hits &= hits - 1;
          const std::uint32_t id = pack_ids_[4 * static_cast<std::size_t>(pack) + bit];
          const std::size_t word = id >> 6U;
          hit_bits_[word] |= std::uint64_t{1} << (id & 63U);
          low_word = std::min(low_word, word);
          high_word = std::max(high_word, word);
        }
      }
    }
  }
  bool truncated = false;
  for (std::size_t word = low_word; word <= high_word && word < hit_bits_.size(); ++word) {
    std::uint64_t bits = hit_bits_[word];
    hit_bits_[word] = 0;
    while (bits != 0) {
      const auto bit = static_cast<std::uint32_t>(std::countr_zero(bits));
      bits &= bits - 1;
      if (out_count == out_ids.size()) {
        truncated = true;
        continue;  // keep clearing
      }
      out_ids[out_count++] = static_cast<std::uint32_t>(word * 64) + bit;
    }
  }
  if (truncated) return {core::StatusCode::capacity_exceeded, "triangle bvh: query output full"};
  return core::Status::ok();
}

}  // namespace trainer::model
