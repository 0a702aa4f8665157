// Private to model/runtime: an array carved from a core::Arena on a setup path, its failure
// message prefixed with the structure that asked ("bucket grid: arena exhausted: ...").
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>

#include "trainer/core/arena.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::model::detail {

template <class T>
core::Expected<std::span<T>> carve_array(core::Arena& arena, std::size_t count,
                                         std::string_view what, std::string_view owner) {
  auto span = arena.allocate_array<T>(count, what);
  if (!span) {
    return core::make_error(std::string(owner) + ": arena exhausted: " + span.error().message);
  }
  return span.value();
}

}  // namespace trainer::model::detail
