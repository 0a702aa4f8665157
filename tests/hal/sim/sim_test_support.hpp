// Shared fixtures for the hal/sim tests: a plausible bench (Maxon-class motors on capstan
// reductions, critically damped hand) and a helper that writes trajectory CSVs to temp files.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstddef>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::hal::sim::test_support {

// Joint parameters of one instrument. Every joint is critically damped (c = 2·sqrt(k·m)) so a
// settle of 2 s leaves an error far below one encoder count.
//   pitch/yaw: gear 20, 4096 counts/rev -> 7.67e-5 rad/count, max effort 0.0302·20·2 = 1.208 N·m
//   insertion: capstan r = 10 mm -> 1.53e-5 m/count, max effort 0.0302/0.01·2 = 6.04 N
//   roll:      gear 5 -> 3.07e-4 rad/count, max effort 0.0116·5·1 = 0.058 N·m
//   grip:      gear 10 -> 1.53e-4 rad/count, max effort 0.0116·10·1 = 0.116 N·m
inline SimInstrumentParams bench_instrument(std::string name) {
  SimInstrumentParams instrument;
  instrument.name = std::move(name);
  const auto revolute = [](double gear, double torque_constant, double current_limit) {
    JointScale scale;
    scale.kind = JointKind::revolute;
    scale.counts_per_rev = 4096;
    scale.gear_ratio = gear;
    scale.torque_constant_nm_per_a = torque_constant;
    scale.current_limit_a = current_limit;
    return scale;
  };
  instrument.scales[kPitchJoint] = revolute(20.0, 0.0302, 2.0);
  instrument.scales[kYawJoint] = revolute(20.0, 0.0302, 2.0);
  instrument.scales[kRollJoint] = revolute(5.0, 0.0116, 1.0);
  instrument.scales[kGripJoint] = revolute(10.0, 0.0116, 1.0);
  JointScale insertion;
  insertion.kind = JointKind::prismatic;
  insertion.counts_per_rev = 4096;
  insertion.gear_ratio = 1.0;
  insertion.capstan_radius_m = 0.01;
  insertion.torque_constant_nm_per_a = 0.0302;
  insertion.current_limit_a = 2.0;
  instrument.scales[kInsertionJoint] = insertion;

  instrument.plant[kPitchJoint] = {0.005, 2.0, 0.2, -0.8, 0.8};
  instrument.plant[kYawJoint] = {0.005, 2.0, 0.2, -0.8, 0.8};
  instrument.plant[kInsertionJoint] = {0.3, 200.0, 15.49193338, 0.0, 0.2};
  instrument.plant[kRollJoint] = {0.0005, 0.2, 0.02, -3.2, 3.2};
  instrument.plant[kGripJoint] = {0.0002, 0.1, 0.008944272, 0.0, 1.0};
  return instrument;
}

inline SimDeviceParams bench_params(std::vector<std::string> instrument_names,
                                    std::string script = "builtin:hold") {
  SimDeviceParams params;
  params.name = "test_bench";
  for (std::string& name : instrument_names) {
    params.instruments.push_back(bench_instrument(std::move(name)));
  }
  params.script = std::move(script);
  return params;
}

// Writes `contents` to a fresh file under the test temp dir and returns its path.
inline std::string write_temp_csv(const std::string& stem, const std::string& contents) {
  static std::atomic<int> counter{0};
  const std::string path = ::testing::TempDir() + "hal_sim_" + stem + "_" +
                           std::to_string(counter.fetch_add(1)) + ".csv";
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  file << contents;
  return path;
}

struct ScriptRow {
  double time_s = 0.0;
  std::string instrument;
  JointPose pose{};
};

// A trajectory CSV (with header) holding `rows`, numbers printed round-trip exact.
inline std::string csv_text(const std::vector<ScriptRow>& rows) {
  std::ostringstream out;
  out.precision(17);
  out << kCsvHeader << '\n';
  for (const ScriptRow& row : rows) {
    out << row.time_s << ',' << row.instrument;
    for (const double value : row.pose) out << ',' << value;
    out << '\n';
  }
  return out.str();
}

inline constexpr std::int64_t kMillisecondNs = 1'000'000;
inline constexpr std::int64_t kSecondNs = 1'000'000'000;

using Samples = std::array<EncoderSample, kMaxChannels>;
using Commands = std::array<ActuatorCommand, kMaxChannels>;
using Statuses = std::array<ActuatorStatus, kMaxChannels>;

}  // namespace trainer::hal::sim::test_support
