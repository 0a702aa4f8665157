// Scripted trainee: CSV parsing, the built-in scripts and minimum-jerk sampling.
#include "trainer/hal_sim/trainee_script.hpp"

#include "text_format.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

namespace trainer::hal::sim {

namespace {

constexpr std::size_t kCsvColumnCount = 2 + kJointsPerInstrument;

std::string_view trim(std::string_view text) noexcept {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields.push_back(trim(line.substr(start)));
      return fields;
    }
    fields.push_back(trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
}

using detail::format_number;

std::string known_names(std::span<const std::string> names) {
  std::string joined;
  for (const std::string& name : names) {
    if (!joined.empty()) joined += ", ";
    joined += "'" + name + "'";
  }
  return joined.empty() ? std::string("none") : joined;
}

// Minimum-jerk blend s(τ) and its derivative ds/dτ for τ in [0, 1].
double min_jerk(double tau) noexcept {
  const double tau3 = tau * tau * tau;
  return tau3 * (10.0 + tau * (-15.0 + 6.0 * tau));
}
double min_jerk_rate(double tau) noexcept {
  const double one_minus = 1.0 - tau;
  return 30.0 * tau * tau * one_minus * one_minus;
}

}  // namespace

core::Expected<TraineeScript> TraineeScript::load(std::string_view spec,
                                                  std::span<const std::string> instrument_names) {
  if (spec == kHoldScript) return builtin_hold(instrument_names.size());
  if (spec == kSweepScript) return builtin_sweep(instrument_names.size());
  if (spec.starts_with("builtin:")) {
    return core::make_error("unknown built-in script '" + std::string(spec) + "'; expected '" +
                            std::string(kHoldScript) + "', '" + std::string(kSweepScript) +
                            "' or a path to a trajectory CSV");
  }
  if (spec.empty()) {
    return core::make_error("script is empty; expected '" + std::string(kHoldScript) +
                            "', '" + std::string(kSweepScript) + "' or a path to a trajectory CSV");
  }
  return load_csv_file(std::string(spec), instrument_names);
}

core::Expected<TraineeScript> TraineeScript::load_csv_file(
    const std::string& path, std::span<const std::string> instrument_names) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    const int error_number = errno;
    return core::make_error("cannot open trajectory file '" + path +
                            "': " + std::strerror(error_number));
  }
  std::ostringstream contents;
  contents << file.rdbuf();
  if (file.bad()) return core::make_error("cannot read trajectory file '" + path + "'");
  return parse_csv(contents.str(), path, instrument_names);
}

core::Expected<TraineeScript> TraineeScript::parse_csv(
    std::string_view text, std::string_view source_name,
    std::span<const std::string> instrument_names) {
  const std::string source(source_name);
  std::vector<Keyframe> keyframes;
  // Line of the previous keyframe of each instrument, for the ordering message.
  std::array<std::size_t, kMaxInstruments> previous_line{};
  const std::vector<std::string_view> header_fields = split_fields(kCsvHeader);
  bool header_seen = false;
  std::size_t line_number = 0;

  while (!text.empty()) {
    const std::size_t newline = text.find('\n');
    std::string_view line = text.substr(0, newline);
    text = newline == std::string_view::npos ? std::string_view{} : text.substr(newline + 1);
    ++line_number;

    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    line = trim(line);
    if (line.empty()) continue;

    const std::string where = source + ":" + std::to_string(line_number) + ": ";
    const std::vector<std::string_view> fields = split_fields(line);
    if (!header_seen) {
      std::string normalised;
      for (const std::string_view field : fields) {
        if (!normalised.empty()) normalised += ',';
        normalised += field;
      }
      if (normalised != kCsvHeader) {
        return core::make_error(where + "expected the header line '" + std::string(kCsvHeader) +
                                "', got '" + std::string(line) + "'");
      }
      header_seen = true;
      continue;
    }

    if (fields.size() != kCsvColumnCount) {
      return core::make_error(where + "expected " + std::to_string(kCsvColumnCount) +
                              " comma-separated columns (" + std::string(kCsvHeader) + "), got " +
                              std::to_string(fields.size()));
    }
    if (keyframes.size() == kMaxKeyframes) {
      return core::make_error(where + "too many keyframes: a script holds at most " +
                              std::to_string(kMaxKeyframes));
    }

    Keyframe keyframe;
    const std::string_view instrument_name = fields[1];
    const auto found = std::find(instrument_names.begin(), instrument_names.end(), instrument_name);
    if (found == instrument_names.end()) {
      return core::make_error(where + "unknown instrument '" + std::string(instrument_name) +
                              "'; the device has " + known_names(instrument_names));
    }
    keyframe.instrument = static_cast<std::size_t>(found - instrument_names.begin());

    std::array<double, kCsvColumnCount> numbers{};
    for (std::size_t column = 0; column < kCsvColumnCount; ++column) {
      if (column == 1) continue;
      const std::string_view field = fields[column];
      double value = 0.0;
      const char* const end = field.data() + field.size();
      const auto [stop, error] = std::from_chars(field.data(), end, value);
      if (error == std::errc::result_out_of_range) {
        return core::make_error(where + "column " + std::string(header_fields[column]) + ": '" +
                                std::string(field) + "' is out of the range of a double");
      }
      if (field.empty() || error != std::errc{} || stop != end) {
        return core::make_error(where + "column " + std::string(header_fields[column]) + ": '" +
                                std::string(field) + "' is not a number");
      }
      if (!std::isfinite(value)) {
        return core::make_error(where + "column " + std::string(header_fields[column]) + ": '" +
                                std::string(field) + "' is not finite");
      }
      numbers[column] = value;
    }
    keyframe.time_s = numbers[0];
    for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
      keyframe.pose[joint] = numbers[2 + joint];
    }
    if (keyframe.time_s < 0.0) {
      return core::make_error(where + "time_s " + format_number(keyframe.time_s) +
                              " is negative; script time starts at 0");
    }
    // Per-instrument ordering: find this instrument's latest keyframe so far.
    for (auto previous = keyframes.rbegin(); previous != keyframes.rend(); ++previous) {
      if (previous->instrument != keyframe.instrument) continue;
      if (!(keyframe.time_s > previous->time_s)) {
        return core::make_error(where + "time_s " + format_number(keyframe.time_s) +
                                " for instrument '" + std::string(instrument_name) +
                                "' is not after its previous keyframe (time_s " +
                                format_number(previous->time_s) + " at line " +
                                std::to_string(previous_line[keyframe.instrument]) +
                                "); times must increase strictly per instrument");
      }
      break;
    }
    previous_line[keyframe.instrument] = line_number;
    keyframes.push_back(keyframe);
  }

  if (!header_seen) {
    return core::make_error(source + ": no header line; expected '" + std::string(kCsvHeader) +
                            "'");
  }
  if (keyframes.empty()) return core::make_error(source + ": no keyframes after the header");
  return from_keyframes(keyframes, instrument_names.size(), source_name);
}

core::Expected<TraineeScript> TraineeScript::from_keyframes(std::span<const Keyframe> keyframes,
                                                            std::size_t instrument_count,
                                                            std::string_view source_name) {
  const std::string source(source_name);
  if (instrument_count > kMaxInstruments) {
    return core::make_error(source + ": " + std::to_string(instrument_count) +
                            " instruments; expected at most " + std::to_string(kMaxInstruments));
  }
  if (keyframes.size() > kMaxKeyframes) {
    return core::make_error(source + ": " + std::to_string(keyframes.size()) +
                            " keyframes; a script holds at most " + std::to_string(kMaxKeyframes));
  }

  for (const Keyframe& keyframe : keyframes) {
    if (keyframe.instrument >= instrument_count) {
      return core::make_error(source + ": keyframe for instrument " +
                              std::to_string(keyframe.instrument) + "; the device has " +
                              std::to_string(instrument_count));
    }
  }

  TraineeScript script;
  script.instrument_count_ = instrument_count;
  script.keyframes_.reserve(keyframes.size() + instrument_count);
  for (std::size_t instrument = 0; instrument < instrument_count; ++instrument) {
    script.begin_[instrument] = script.keyframes_.size();
    const Keyframe* previous = nullptr;
    for (const Keyframe& keyframe : keyframes) {
      if (keyframe.instrument != instrument) continue;
      bool finite = std::isfinite(keyframe.time_s);
      for (const double value : keyframe.pose) finite = finite && std::isfinite(value);
      if (!finite) {
        return core::make_error(source + ": keyframe of instrument " + std::to_string(instrument) +
                                " has a non-finite time or joint value");
      }
      if (keyframe.time_s < 0.0) {
        return core::make_error(source + ": keyframe time " + format_number(keyframe.time_s) +
                                " s is negative; script time starts at 0");
      }
      if (previous != nullptr && !(keyframe.time_s > previous->time_s)) {
        return core::make_error(source + ": keyframe times of instrument " +
                                std::to_string(instrument) + " are not strictly increasing (" +
                                format_number(previous->time_s) + " then " +
                                format_number(keyframe.time_s) + ")");
      }
      script.keyframes_.push_back(keyframe);
      script.duration_s_ = std::max(script.duration_s_, keyframe.time_s);
      previous = &keyframe;
    }
    if (previous == nullptr) script.keyframes_.push_back(Keyframe{0.0, instrument, kNeutralPose});
  }
  for (std::size_t instrument = instrument_count; instrument <= kMaxInstruments; ++instrument) {
    script.begin_[instrument] = script.keyframes_.size();
  }
  return script;
}

TraineeScript TraineeScript::builtin_hold(std::size_t instrument_count) {
  std::vector<Keyframe> keyframes;
  for (std::size_t instrument = 0; instrument < instrument_count; ++instrument) {
    keyframes.push_back(Keyframe{0.0, instrument, kNeutralPose});
  }
  auto script = from_keyframes(keyframes, instrument_count, kHoldScript);
  // Cannot fail for a valid instrument count; fall back to an empty script otherwise.
  return script ? std::move(script).value() : TraineeScript{};
}

TraineeScript TraineeScript::builtin_sweep(std::size_t instrument_count) {
  // All joints together: neutral -> +amplitude -> neutral -> -amplitude -> neutral, 2.5 s per
  // leg. A minimum-jerk leg peaks at 1.875 * change / duration, i.e. 0.75 * amplitude per
  // second here: 0.15 rad/s in pitch and yaw, 0.015 m/s in insertion, a slow, deliberate hand.
  constexpr JointPose kAmplitude = {0.2, 0.2, 0.02, 0.5, 0.2};
  constexpr std::array<double, 5> kLegSign = {0.0, 1.0, 0.0, -1.0, 0.0};
  constexpr double kSecondsPerLeg = 2.5;
  std::vector<Keyframe> keyframes;
  for (std::size_t instrument = 0; instrument < instrument_count; ++instrument) {
    for (std::size_t leg = 0; leg < kLegSign.size(); ++leg) {
      Keyframe keyframe{kSecondsPerLeg * static_cast<double>(leg), instrument, kNeutralPose};
      for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
        keyframe.pose[joint] += kLegSign[leg] * kAmplitude[joint];
      }
      keyframes.push_back(keyframe);
    }
  }
  auto script = from_keyframes(keyframes, instrument_count, kSweepScript);
  return script ? std::move(script).value() : TraineeScript{};
}

std::span<const Keyframe> TraineeScript::keyframes(std::size_t instrument) const noexcept {
  if (instrument >= instrument_count_) return {};
  return std::span<const Keyframe>(keyframes_).subspan(
      begin_[instrument], begin_[instrument + 1] - begin_[instrument]);
}

PoseSample TraineeScript::sample(std::size_t instrument, double time_s) const noexcept {
  PoseSample result;
  const std::span<const Keyframe> frames = keyframes(instrument);
  if (frames.empty()) {
    result.position = kNeutralPose;
    return result;
  }
  if (!(time_s > frames.front().time_s)) {  // also catches NaN: hold the first pose
    result.position = frames.front().pose;
    return result;
  }
  if (time_s >= frames.back().time_s) {
    result.position = frames.back().pose;
    return result;
  }
  // First keyframe strictly after time_s; the segment starts one before it.
  const auto after = std::upper_bound(
      frames.begin(), frames.end(), time_s,
      [](double time, const Keyframe& keyframe) { return time < keyframe.time_s; });
  const Keyframe& to = *after;
  const Keyframe& from = *(after - 1);
  const double segment_s = to.time_s - from.time_s;
  const double tau = (time_s - from.time_s) / segment_s;
  const double blend = min_jerk(tau);
  const double blend_rate_per_s = min_jerk_rate(tau) / segment_s;
  for (std::size_t joint = 0; joint < kJointsPerInstrument; ++joint) {
    const double change = to.pose[joint] - from.pose[joint];
    result.position[joint] = from.pose[joint] + change * blend;
    result.velocity[joint] = change * blend_rate_per_s;
  }
  return result;
}

}  // namespace trainer::hal::sim
