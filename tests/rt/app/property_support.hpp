// Support of the force-command property tests (force_command_property_test.cpp,
// haptic_app_property_test.cpp): a seeded, platform-independent PRNG with the hostile value
// mixtures both use, and the environment variables that reproduce a failure or run a long soak:
//
//   TRAINER_PROPERTY_SEED=<u64>|random   seed of every random choice (default: a fixed seed,
//                                        so CI is deterministic); `random` draws one and prints it
//   TRAINER_PROPERTY_CASES=<n>           force pipeline cases (default 10^6; fewer in sanitizer
//                                        builds)
//   TRAINER_PROPERTY_CYCLES=<n>          haptic cycles per reference scene (defaults per scene)
//   TRAINER_PROPERTY_EPISODE=<n>         force pipeline: run only this episode (from a failure
//                                        message) to replay it
//
// xoshiro256** seeded through splitmix64 (Blackman & Vigna): the same seed gives the same
// numbers with any standard library, unlike std::uniform_*_distribution.
#pragma once

#include <filesystem>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <string_view>

#include <Eigen/Core>

namespace trainer::app::property {

inline const std::filesystem::path kRepo{TRAINER_SOURCE_DIR};

inline std::uint64_t splitmix64(std::uint64_t& state) noexcept {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31U);
}

class Random {
 public:
  explicit Random(std::uint64_t seed) noexcept {
    std::uint64_t state = seed;
    for (std::uint64_t& word : s_) word = splitmix64(state);
  }

  std::uint64_t next() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5U, 7) * 9U;
    const std::uint64_t t = s_[1] << 17U;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // [0, 1) with 53 random bits.
  double unit() noexcept { return static_cast<double>(next() >> 11U) * 0x1.0p-53; }
  double uniform(double low, double high) noexcept { return low + (high - low) * unit(); }
  float uniform_float(double low, double high) noexcept {
    return static_cast<float>(uniform(low, high));
  }
  bool chance(double probability) noexcept { return unit() < probability; }
  std::size_t index(std::size_t count) noexcept {
    return static_cast<std::size_t>(unit() * static_cast<double>(count)) % count;
  }
  // log-uniform magnitude in [low, high], both > 0.
  double log_uniform(double low, double high) noexcept {
    return std::exp(uniform(std::log(low), std::log(high)));
  }
  double sign() noexcept { return chance(0.5) ? 1.0 : -1.0; }

  Eigen::Vector3f unit_vector() noexcept {
    for (;;) {
      const Eigen::Vector3d v(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
      const double norm = v.norm();
      if (norm > 1e-3 && norm <= 1.0) return (v / norm).cast<float>();
    }
  }

  // A value no sane input holds: NaN, ±Inf, ±FLT_MAX, huge, subnormal or a signed zero.
  float hostile() noexcept {
    constexpr float kMax = std::numeric_limits<float>::max();
    switch (index(8)) {
      case 0: return std::numeric_limits<float>::quiet_NaN();
      case 1: return std::numeric_limits<float>::infinity();
      case 2: return -std::numeric_limits<float>::infinity();
      case 3: return static_cast<float>(sign()) * kMax;
      case 4: return static_cast<float>(sign() * log_uniform(1e10, 1e38));
      case 5: return static_cast<float>(sign()) * std::numeric_limits<float>::denorm_min() * 7.0F;
      case 6: return -0.0F;
      default: return static_cast<float>(sign() * log_uniform(1e3, 1e9));
    }
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept {
    return (x << static_cast<unsigned>(k)) | (x >> static_cast<unsigned>(64 - k));
  }
  std::uint64_t s_[4]{};
};

inline std::optional<std::uint64_t> env_u64(const char* name) {
  const char* value = std::getenv(name);
  if (value == nullptr || *value == '\0') return std::nullopt;
  char* end = nullptr;
  const unsigned long long parsed = std::strtoull(value, &end, 0);
  if (end == value || *end != '\0') {
    std::fprintf(stderr, "%s='%s' is not an unsigned integer; ignored\n", name, value);
    return std::nullopt;
  }
  return static_cast<std::uint64_t>(parsed);
}

// The seed of this run: TRAINER_PROPERTY_SEED, `random`, or `fallback`. Printed so a failing
// run can always be repeated.
inline std::uint64_t seed_for(std::string_view test, std::uint64_t fallback) {
  std::uint64_t seed = fallback;
  const char* value = std::getenv("TRAINER_PROPERTY_SEED");
  if (value != nullptr && std::string_view(value) == "random") {
    std::random_device device;
    seed = (static_cast<std::uint64_t>(device()) << 32U) ^ device();
  } else if (const auto given = env_u64("TRAINER_PROPERTY_SEED")) {
    seed = *given;
  }
  std::printf("%.*s: TRAINER_PROPERTY_SEED=%llu\n", static_cast<int>(test.size()), test.data(),
              static_cast<unsigned long long>(seed));
  std::fflush(stdout);
  return seed;
}

inline std::string vec_text(const Eigen::Vector3f& v) {
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "[%.9g, %.9g, %.9g]", static_cast<double>(v.x()),
                static_cast<double>(v.y()), static_cast<double>(v.z()));
  return buffer;
}

inline std::string number_text(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.9g", value);
  return buffer;
}

}  // namespace trainer::app::property
