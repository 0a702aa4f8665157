// Wall time of a precompute step, for build reports. Private to model/offline.
#pragma once

#include <chrono>

namespace trainer::model::offline::detail {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace trainer::model::offline::detail
