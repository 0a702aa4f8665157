// Golden-trace regression test of the wall scene (config/scenes/wall.toml): the whole haptic
// cycle (sim HAL → kinematics → wall contact → safety chain → HAL write → publish) run on a
// manual clock for the full length of the scene's trainee script, sampled from the telemetry
// triple buffer and compared row by row with a committed trace (golden/wall_trace.csv).
//
// The run is deterministic: a core::ManualClock, the simulated device (its plant integrated in
// fixed sub-steps up to the clock), no threads. Any change of behaviour of the loop on this
// scene shows up here; the golden file is only ever rewritten on purpose:
//   TRAINER_UPDATE_GOLDEN=1 <build>/tests/rt/app/wall_golden_test
// writes the file and then FAILS, so a run with the variable set can never pass silently.
//
// Independently of the golden file the trace is also checked against physics the scene
// implies (contact happens, the wall pushes along its normal only, within the safety force
// limit, nothing non-finite, no fault), so a golden file regenerated from broken code does
// not make the test meaningless.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

#include "trainer/app/haptic_app.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_sim/sim_device.hpp"

namespace trainer::app {
namespace {

const std::filesystem::path kSourceDir{TRAINER_SOURCE_DIR};
const std::filesystem::path kScenePath = kSourceDir / "config/scenes/wall.toml";
const std::filesystem::path kGoldenPath = kSourceDir / "tests/rt/app/golden/wall_trace.csv";

// One row every 10 cycles: 10 ms at the scene's 1 kHz, ~1000 rows over the 10 s script. Fine
// enough to follow the 6 s insertion, the press, the slide and the withdrawal; the contact
// onset itself (a few cycles under the 4000 N/s slew limit) is covered by the row count of
// in-contact rows and by the exact in_contact column.
constexpr std::uint64_t kDecimationCycles = 10;

// Columns of a trace row, instrument 0 ("left") only: the scene has one instrument.
enum Column : std::size_t {
  kTime,
  kTipX,
  kTipY,
  kTipZ,
  kForceX,
  kForceY,
  kForceZ,
  kEffortPitch,
  kEffortYaw,
  kEffortInsertion,
  kEffortRoll,
  kEffortGrip,
  kInContact,
  kLatchedFaults,
  kColumnCount
};

// Tolerances: |actual − golden| <= absolute + relative·|golden|.
//
// The trace is computed in float (kinematics, contact, safety chain, Jᵀ·F efforts) from
// encoder counts that the sim quantises from a double-precision plant. On x86-64 (SSE, no
// -ffast-math, no FMA contraction without -march) float arithmetic is exact IEEE for a given
// sequence of operations, so optimisation level alone does not change the trace. Measured
// (script 10 s, 1000 rows):
//  - Release (-O3) vs ASan+UBSan RelWithDebInfo -O1: bit-identical, difference 0 everywhere.
//  - Release vs a build with -mfma -mavx2 -ffp-contract=fast (every a·b+c fused, i.e. a
//    different rounding everywhere, plant included): tip 3.7e-9 m, force 4.8e-7 N (1.2e-7
//    relative), efforts 4.8e-7 N / 3.7e-8 N·m; no encoder count flipped, contact and faults
//    identical.
//  - A refactor of haptic_app.cpp that reordered the effort arithmetic: yaw effort 3.5e-8 N·m
//    (on values near zero), everything else identical.
// So the tolerances below leave ~100x margin over rounding of that kind, yet stay under what a
// real change of behaviour produces, the smallest being one encoder count of the plant:
//  - tip position 1e-6 m absolute (float ulp at 0.1 m is 7.5e-9 m; one count is 1.5e-6 m of
//    insertion, ~9e-6 m of tip travel in pitch/yaw).
//  - force 1e-4 N + 1e-5 relative (at the ~4.7 N press 1.5e-4 N; one count of insertion
//    changes the wall's 400 N/m spring force by 6.1e-4 N).
//  - joint efforts 1e-5 (N·m, or N for insertion) + 1e-5 relative: the same margins through
//    the ~0.1 m lever arms.
//  - time, in_contact, latched fault bits: exact (discrete).
struct ColumnSpec {
  std::string_view name;
  double absolute;
  double relative;
};
constexpr std::array<ColumnSpec, kColumnCount> kColumns = {{
    {"time_s", 1e-9, 0.0},
    {"tip_x_m", 1e-6, 0.0},
    {"tip_y_m", 1e-6, 0.0},
    {"tip_z_m", 1e-6, 0.0},
    {"force_x_n", 1e-4, 1e-5},
    {"force_y_n", 1e-4, 1e-5},
    {"force_z_n", 1e-4, 1e-5},
    {"effort_pitch_n_m", 1e-5, 1e-5},
    {"effort_yaw_n_m", 1e-5, 1e-5},
    {"effort_insertion_n", 1e-5, 1e-5},
    {"effort_roll_n_m", 1e-5, 1e-5},
    {"effort_grip_n_m", 1e-5, 1e-5},
    {"in_contact", 0.0, 0.0},
    {"latched_faults", 0.0, 0.0},
}};

using TraceRow = std::array<double, kColumnCount>;

std::string header_line() {
  std::string line;
  for (const ColumnSpec& column : kColumns) {
    if (!line.empty()) line += ',';
    line += column.name;
  }
  return line;
}

// Float columns are written with 9 significant digits: every float round-trips exactly, so a
// freshly written golden file compares with zero difference against the run that wrote it.
std::string format_row(const TraceRow& row) {
  std::string line;
  std::array<char, 48> buffer{};
  for (std::size_t c = 0; c < kColumnCount; ++c) {
    if (c == kTime) {
      std::snprintf(buffer.data(), buffer.size(), "%.6f", row[c]);
    } else if (c == kInContact || c == kLatchedFaults) {
      std::snprintf(buffer.data(), buffer.size(), "%.0f", row[c]);
    } else {
      std::snprintf(buffer.data(), buffer.size(), "%.9g", row[c]);
    }
    if (c != 0) line += ',';
    line += buffer.data();
  }
  return line;
}

// Reads the golden file: '#' lines are comments, the first other line must be the header.
core::Expected<std::vector<TraceRow>> read_golden(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    return core::make_error("cannot open golden trace " + path.string() +
                            " (generate it with TRAINER_UPDATE_GOLDEN=1)");
  }
  std::vector<TraceRow> rows;
  std::string line;
  std::size_t line_number = 0;
  bool header_seen = false;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line.front() == '#') continue;
    const std::string where = path.string() + ":" + std::to_string(line_number);
    if (!header_seen) {
      if (line != header_line()) {
        return core::make_error(where + ": header '" + line + "', expected '" + header_line() +
                                "'");
      }
      header_seen = true;
      continue;
    }
    TraceRow row{};
    std::istringstream fields(line);
    std::string field;
    std::size_t column = 0;
    while (std::getline(fields, field, ',')) {
      if (column >= kColumnCount) break;
      char* end = nullptr;
      row[column] = std::strtod(field.c_str(), &end);
      if (end == field.c_str() || *end != '\0') {
        return core::make_error(where + ": column " + std::string(kColumns[column].name) +
                                " is '" + field + "', expected a number");
      }
      ++column;
    }
    if (column != kColumnCount || fields.rdbuf()->in_avail() > 0) {
      return core::make_error(where + ": expected " + std::to_string(kColumnCount) +
                              " comma-separated values");
    }
    rows.push_back(row);
  }
  if (!header_seen) return core::make_error(path.string() + ": no header line");
  return rows;
}

class WallGoldenTraceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto scene = config::load_scene(kScenePath);
    ASSERT_TRUE(scene) << scene.error().message;
    scene_ = std::move(*scene);
    device_ = std::make_unique<hal::sim::SimDevice>(clock_, sim_params_from(scene_));
    ASSERT_TRUE(device_->configure());
    ASSERT_TRUE(device_->activate());  // script time 0 = clock time 0
    auto arena = core::Arena::create(scene_.memory.arena_bytes);
    ASSERT_TRUE(arena);
    arena_ = std::make_unique<core::Arena>(std::move(*arena));
    auto app = HapticApp::create(scene_,
                                 {device_->encoders(), device_->actuators(),
                                  device_->digital_inputs(), device_->digital_outputs()},
                                 *arena_, log_, telemetry_, clock_);
    ASSERT_TRUE(app) << app.error().message;
    app_ = std::move(*app);
    arena_->seal();
    // The safety chain starts faulted; this explicit reset arms it in the first cycle.
    app_->request_reset();
  }

  // Runs the scene for the whole script at its period; one row per kDecimationCycles cycles,
  // taken from the telemetry the cycle published (what the telemetry thread would read).
  std::vector<TraceRow> record_trace() {
    const std::int64_t period_ns = scene_.loop.period_ns;
    const auto script_ns =
        static_cast<std::int64_t>(std::ceil(device_->script_duration_s() * 1e9));
    std::vector<TraceRow> rows;
    std::uint64_t cycle = 0;
    while (clock_.now_ns() < script_ns) {
      clock_.advance_ns(period_ns);
      loop::CycleTiming timing{};
      timing.cycle_index = cycle++;
      timing.deadline_ns = clock_.now_ns();
      timing.wake_ns = clock_.now_ns();
      timing.dt_s = static_cast<double>(period_ns) * 1e-9;
      // The status only reports encoder read errors, which the sim has none of here; a real
      // failure would show in latched_faults.
      (void)app_->run_cycle(timing);
      if (cycle % kDecimationCycles != 0) continue;
      if (!telemetry_.update()) {
        ADD_FAILURE() << "no telemetry published by cycle " << timing.cycle_index;
        return rows;
      }
      const TelemetrySnapshot& snapshot = telemetry_.latest();
      const InstrumentTelemetry& instrument = snapshot.instruments[0];
      TraceRow row{};
      row[kTime] = static_cast<double>(snapshot.time_ns) * 1e-9;
      for (std::size_t k = 0; k < 3; ++k) {
        row[kTipX + k] = static_cast<double>(instrument.tip_m[k]);
        row[kForceX + k] = static_cast<double>(instrument.force_n[k]);
      }
      for (std::size_t j = 0; j < 5; ++j) {
        row[kEffortPitch + j] = static_cast<double>(instrument.joint_efforts[j]);
      }
      row[kInContact] = instrument.in_contact ? 1.0 : 0.0;
      row[kLatchedFaults] = static_cast<double>(snapshot.latched_faults);
      rows.push_back(row);
    }
    return rows;
  }

  // Setup-path only (the test's regeneration mode).
  void write_golden(const std::vector<TraceRow>& rows) const {
    std::filesystem::create_directories(kGoldenPath.parent_path());
    std::ofstream out(kGoldenPath, std::ios::trunc);
    ASSERT_TRUE(out) << "cannot write " << kGoldenPath;
    const std::filesystem::path script(scene_.trainee.script);
    out << "# Golden trace of the wall scene, checked by tests/rt/app/wall_golden_trace_test.cpp.\n"
        << "# scene: " << std::filesystem::relative(kScenePath, kSourceDir).generic_string()
        << "\n# trainee script: "
        << std::filesystem::relative(script, kSourceDir).generic_string() << " ("
        << device_->script_duration_s() << " s)\n"
        << "# period: " << scene_.loop.period_ns << " ns; one row every " << kDecimationCycles
        << " cycles (decimation); armed by a reset before the first cycle; simulated device\n"
        << "# on a manual clock. Instrument 0 (left): tip in the trainer frame (m), force on the\n"
        << "# tool after the safety chain (N), commanded joint efforts (pitch/yaw/roll/grip N·m,\n"
        << "# insertion N), in_contact (0/1), latched safety::Fault bits.\n"
        << "# Regenerate only for an intended, reviewed change of behaviour:\n"
        << "#   TRAINER_UPDATE_GOLDEN=1 <build>/tests/rt/app/wall_golden_test\n"
        << "# (the test rewrites this file and fails on purpose), then review the diff.\n"
        << header_line() << '\n';
    for (const TraceRow& row : rows) out << format_row(row) << '\n';
    ASSERT_TRUE(out.good()) << "error writing " << kGoldenPath;
  }

  config::SceneConfig scene_;
  core::ManualClock clock_{0};
  std::unique_ptr<hal::sim::SimDevice> device_;
  std::unique_ptr<core::Arena> arena_;
  core::LogRing log_;
  core::TripleBuffer<TelemetrySnapshot> telemetry_;
  std::unique_ptr<HapticApp> app_;
};

bool update_requested() {
  const char* value = std::getenv("TRAINER_UPDATE_GOLDEN");
  return value != nullptr && std::string_view(value) == "1";
}

TEST_F(WallGoldenTraceTest, MatchesGoldenTrace) {
  const std::vector<TraceRow> rows = record_trace();
  ASSERT_FALSE(rows.empty());

  if (update_requested()) {
    write_golden(rows);
    FAIL() << "TRAINER_UPDATE_GOLDEN=1: rewrote " << kGoldenPath << " with " << rows.size()
           << " rows instead of comparing. Review its diff, then run again without the "
              "variable.";
  }

  auto golden = read_golden(kGoldenPath);
  ASSERT_TRUE(golden) << golden.error().message;
  const std::vector<TraceRow>& expected = *golden;
  const std::size_t common = std::min(rows.size(), expected.size());
  for (std::size_t r = 0; r < common; ++r) {
    for (std::size_t c = 0; c < kColumnCount; ++c) {
      const double want = expected[r][c];
      const double got = rows[r][c];
      const double tolerance = kColumns[c].absolute + kColumns[c].relative * std::fabs(want);
      // Written so that a NaN on either side fails.
      if (!(std::fabs(got - want) <= tolerance)) {
        std::array<char, 256> message{};
        std::snprintf(message.data(), message.size(),
                      "first difference at data row %zu (time %.3f s), column %.*s: golden %.9g, "
                      "actual %.9g, |difference| %.3g > tolerance %.3g",
                      r, expected[r][kTime], static_cast<int>(kColumns[c].name.size()),
                      kColumns[c].name.data(), want, got, std::fabs(got - want), tolerance);
        FAIL() << message.data() << "\n  golden: " << format_row(expected[r])
               << "\n  actual: " << format_row(rows[r])
               << "\nIf the change is intended, regenerate with TRAINER_UPDATE_GOLDEN=1.";
      }
    }
  }
  ASSERT_EQ(rows.size(), expected.size())
      << "row count differs (rows equal up to " << common << ")";
}

// Physics the scene implies, independent of the golden file.
TEST_F(WallGoldenTraceTest, TraceObeysTheWallScene) {
  const std::vector<TraceRow> rows = record_trace();
  ASSERT_EQ(rows.size(),
            static_cast<std::size_t>(std::ceil(device_->script_duration_s() * 1e9 /
                                               static_cast<double>(scene_.loop.period_ns))) /
                kDecimationCycles);

  ASSERT_EQ(scene_.objects.size(), 1U);
  const config::ObjectConfig& wall = scene_.objects[0];
  const auto max_force_n = scene_.safety.max_force_n;

  std::size_t contact_rows = 0;
  std::size_t pushing_rows = 0;
  double peak_force_n = 0.0;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const TraceRow& row = rows[r];
    for (std::size_t c = 0; c < kColumnCount; ++c) {
      ASSERT_TRUE(std::isfinite(row[c])) << "row " << r << " column " << kColumns[c].name;
    }
    ASSERT_EQ(row[kLatchedFaults], 0.0) << "fault latched by row " << r << " (t = "
                                        << row[kTime] << " s)";

    double normal_force_n = 0.0;
    double force_squared = 0.0;
    double depth_m = 0.0;  // tip behind the wall plane, along -normal
    for (std::size_t k = 0; k < 3; ++k) {
      normal_force_n += row[kForceX + k] * wall.normal[k];
      force_squared += row[kForceX + k] * row[kForceX + k];
      depth_m -= (row[kTipX + k] - wall.point_m[k]) * wall.normal[k];
    }
    const double force_norm_n = std::sqrt(force_squared);
    const double lateral_n =
        std::sqrt(std::max(0.0, force_squared - normal_force_n * normal_force_n));
    peak_force_n = std::max(peak_force_n, force_norm_n);
    EXPECT_LE(force_norm_n, max_force_n * (1.0 + 1e-6)) << "row " << r;

    if (row[kInContact] != 0.0) {
      ++contact_rows;
      // The contact point is the tip, so it is on or behind the plane.
      EXPECT_GE(depth_m, 0.0) << "row " << r;
      // A frictionless wall pushes along its outward normal only (never pulls: the damper is
      // clamped at zero), float rounding aside.
      EXPECT_GE(normal_force_n, 0.0) << "row " << r;
      EXPECT_LE(lateral_n, 1e-6 + 1e-5 * force_norm_n) << "row " << r;
      if (normal_force_n > 0.0) ++pushing_rows;
    } else {
      // Out of contact nothing renders a force: the safety chain lets a force drop to zero
      // at once (it only slew-limits rises).
      EXPECT_EQ(force_norm_n, 0.0) << "row " << r << " (t = " << row[kTime] << " s)";
      EXPECT_LT(depth_m, 1e-6) << "row " << r;
    }
  }
  // The script keeps the tip on the wall from ~3.8 s to ~9.2 s: ~550 rows at 100 rows/s.
  EXPECT_GT(contact_rows, 300U);
  EXPECT_GT(pushing_rows, contact_rows * 9 / 10);
  // The press is hard enough to be felt but the limit is not what shapes it.
  EXPECT_GT(peak_force_n, 1.0);

  // Quasi-static hold (script 6..7 s, hand still): the force is the spring's k·depth, the
  // damper's share being small (5 %, as in haptic_app_test), and the insertion motor pushes
  // the tool back out (negative insertion effort).
  std::size_t hold_rows = 0;
  for (const TraceRow& row : rows) {
    if (row[kTime] < 6.5 || row[kTime] > 7.0) continue;
    ++hold_rows;
    ASSERT_EQ(row[kInContact], 1.0) << "t = " << row[kTime] << " s";
    double depth_m = 0.0;
    for (std::size_t k = 0; k < 3; ++k) depth_m -= (row[kTipX + k] - wall.point_m[k]) * wall.normal[k];
    const double spring_n = wall.stiffness_n_per_m * depth_m;
    EXPECT_NEAR(row[kForceZ] * wall.normal[2], spring_n, 0.05 * spring_n) << "t = " << row[kTime];
    EXPECT_LT(row[kEffortInsertion], 0.0) << "t = " << row[kTime];
  }
  EXPECT_GT(hold_rows, 40U);
}

}  // namespace
}  // namespace trainer::app
