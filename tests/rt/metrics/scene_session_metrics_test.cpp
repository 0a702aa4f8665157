// The metrics end to end on the repository scenes (cbd, duct, wall, catheter) without touching the
// RT cycle: the scene's HapticApp on the simulated bench in simulated time, wrapped in a
// CycleTask that after every cycle builds a CycleSample from what the app already exposes —
// the telemetry snapshot it publishes (tip, jaw angle, commanded force, contact flag, faults)
// and its run statistics (grasping this cycle, the catheter's insertion depth) — and feeds
// SessionMetrics. Until the cycle fills a CycleSample itself (issue 18's integration), two
// fields are stand-ins: the force is the commanded tip force after the safety chain (the cbd
// scene has no rigid object, so it is the tissue force as limited), the contact point is the
// tip and the contact model unknown (-1).
//
// Checks: the metrics agree with the app's own statistics where both measure the same thing
// (peak force, contact time, grasps, slips, insertion target), the procedure's task is complete,
// and the figures are printed (docs/metrics.md "The cbd scene" records them).
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "catheter_images.hpp"
#include "model_spec.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/app/haptic_app.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/hal_sim/sim_device.hpp"
#include "trainer/loop/periodic_loop.hpp"
#include "trainer/metrics/metrics_report.hpp"
#include "trainer/metrics/session_metrics.hpp"
#include "trainer/model_offline/modal_build.hpp"

namespace trainer::metrics {
namespace {

const std::filesystem::path kRepo{TRAINER_SOURCE_DIR};

// The duct image the scene names, built in-process into a directory of this test's own
// (as tests/rt/app/haptic_app_property_test.cpp does; about 0.5 s).
std::string build_duct_image(config::SceneConfig& scene, const std::filesystem::path& directory) {
  for (config::SceneModelConfig& entry : scene.models) {
    if (entry.definition.kind != config::ModelKind::modal_shell) continue;
    auto spec = tools::modelc::modal_spec_from(entry.definition);
    if (!spec) return spec.error().message;
    auto build = model::offline::build_modal_model(*spec);
    if (!build) return build.error().message;
    const std::filesystem::path image = directory / (entry.name + ".img");
    if (auto written = model::offline::write_modal_image(*spec, *build, image); !written) {
      return written.error().message;
    }
    entry.definition.image_path = image;
  }
  return {};
}

// Runs the app's cycle, then turns what it published into one CycleSample.
class MetricsFeed final : public loop::CycleTask {
 public:
  MetricsFeed(app::HapticApp& haptic, core::TripleBuffer<app::TelemetrySnapshot>& telemetry,
              SessionMetrics& metrics, int insertion_catheter)
      : app_(haptic), telemetry_(telemetry), metrics_(metrics),
        insertion_catheter_(insertion_catheter) {}

  core::Status run_cycle(const loop::CycleTiming& timing) noexcept override {
    const core::Status status = app_.run_cycle(timing);
    (void)telemetry_.update();
    const app::TelemetrySnapshot& t = telemetry_.latest();
    const app::AppStats& stats = app_.stats();
    CycleSample sample;
    sample.cycle = t.cycle;
    sample.time_ns = t.time_ns;
    sample.latched_faults = t.latched_faults;
    sample.instrument_count = t.instrument_count;
    for (std::size_t i = 0; i < t.instrument_count; ++i) {
      const app::InstrumentTelemetry& in = t.instruments[i];
      InstrumentSample& out = sample.instruments[i];
      out.tip_m = in.tip_m;
      out.tissue_force_n = in.force_n;
      out.contact_point_m = in.tip_m;
      out.grip_rad = in.joints[4];
      out.tissue_contact = in.in_contact ? 1 : 0;
      const std::uint64_t grasping_cycles = stats.instruments[i].grasping_cycles;
      out.grasping = grasping_cycles > last_grasping_cycles_[i] ? 1 : 0;
      last_grasping_cycles_[i] = grasping_cycles;
    }
    sample.insertion_depth_m =
        insertion_catheter_ >= 0
            ? stats.catheters[static_cast<std::size_t>(insertion_catheter_)].insertion_depth_m
            : std::numeric_limits<float>::quiet_NaN();
    sample.contact_model = -1;
    if (!metrics_.add(sample)) ++refused_;
    return status;
  }
  void on_overrun_fault(std::uint32_t streak) noexcept override { app_.on_overrun_fault(streak); }

  std::uint64_t refused() const noexcept { return refused_; }

 private:
  app::HapticApp& app_;
  core::TripleBuffer<app::TelemetrySnapshot>& telemetry_;
  SessionMetrics& metrics_;
  int insertion_catheter_;
  std::array<std::uint64_t, kMaxSampleInstruments> last_grasping_cycles_{};
  std::uint64_t refused_ = 0;
};

struct SceneCase {
  const char* name;  // config/scenes/<name>.toml
  bool procedure;    // the cbd procedure: grasp, insertion target, task completed
};

std::ostream& operator<<(std::ostream& stream, const SceneCase& scene_case) {
  return stream << scene_case.name;
}

class SceneSessionMetrics : public ::testing::TestWithParam<SceneCase> {};

TEST_P(SceneSessionMetrics, ScriptedRunGivesMetricsConsistentWithTheAppsStatistics) {
  const SceneCase& scene_case = GetParam();
  const std::filesystem::path directory =
      std::filesystem::temp_directory_path() /
      ("trainer_metrics_" + std::string(scene_case.name) + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(directory);
  struct Cleanup {
    std::filesystem::path path;
    ~Cleanup() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  } cleanup{directory};

  const std::filesystem::path scene_file =
      kRepo / "config/scenes" / (std::string(scene_case.name) + ".toml");
  ASSERT_EQ(test::build_catheter_images(scene_file), "");
  auto loaded = config::load_scene(scene_file);
  ASSERT_TRUE(loaded) << loaded.error().message;
  config::SceneConfig scene = std::move(*loaded);
  ASSERT_EQ(build_duct_image(scene, directory), "");

  core::ManualClock clock(0);
  hal::sim::SimDevice device(clock, app::sim_params_from(scene));
  ASSERT_TRUE(device.configure());
  ASSERT_TRUE(device.activate());
  auto arena = core::Arena::create(scene.memory.arena_bytes);
  ASSERT_TRUE(arena) << arena.error().message;
  auto log = std::make_unique<core::LogRing>();
  auto telemetry = std::make_unique<core::TripleBuffer<app::TelemetrySnapshot>>();
  auto created = app::HapticApp::create(
      scene,
      {device.encoders(), device.actuators(), device.digital_inputs(), device.digital_outputs()},
      *arena, *log, *telemetry, clock);
  ASSERT_TRUE(created) << created.error().message;
  app::HapticApp& haptic = **created;
  arena->seal();

  // The session's setup from the scene: its [metrics], loop period, instruments and the
  // catheter's insertion goal.
  SessionSetup setup;
  setup.thresholds = scene.metrics;
  setup.period_ns = scene.loop.period_ns;
  setup.instrument_count = static_cast<std::uint32_t>(scene.instruments.size());
  int insertion_catheter = -1;
  int catheter_index = 0;
  std::vector<std::string> model_names;
  for (const config::SceneModelConfig& entry : scene.models) {
    model_names.push_back(entry.name);
    if (entry.definition.kind != config::ModelKind::catheter) continue;
    if (entry.insertion) {
      insertion_catheter = catheter_index;
      setup.insertion_target_depth_m = entry.insertion->target_depth_m;
    }
    ++catheter_index;
  }
  EXPECT_EQ(insertion_catheter >= 0, scene_case.procedure);
  auto session = SessionMetrics::create(setup);
  ASSERT_TRUE(session) << session.error().message;

  const auto cycles = static_cast<std::uint64_t>(
      std::ceil(device.script_duration_s() / (static_cast<double>(scene.loop.period_ns) * 1e-9)));
  MetricsFeed feed(haptic, *telemetry, *session, insertion_catheter);
  haptic.request_reset();
  loop::PeriodicLoop periodic(
      clock, loop::LoopSettings{scene.loop.period_ns, scene.loop.overrun_streak_limit, cycles});
  std::atomic<bool> stop{false};
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  periodic.run(feed, stop);
  core::alloc::end_counting_this_thread();
  const std::uint64_t allocations = core::alloc::counted_allocations() - before;
  const std::uint32_t faults = haptic.safety().latched_faults();  // before the shutdown latch
  haptic.shutdown();

  const SessionResult r = session->result();
  const app::AppStats& stats = haptic.stats();
  std::vector<std::string> instrument_names;
  for (const config::SceneInstrumentConfig& instrument : scene.instruments)
    instrument_names.push_back(instrument.name);
  std::printf("%s metrics:\n%s\n", scene_case.name,
              metrics_json(r, scene.metrics, instrument_names, model_names).dump(2).c_str());
  std::printf("%s", metrics_summary(r, instrument_names).c_str());

  EXPECT_EQ(allocations, 0U) << "the cycle and the metrics feed together";
  EXPECT_EQ(feed.refused(), 0U);
  EXPECT_EQ(r.samples, cycles);
  EXPECT_EQ(faults, 0U);
  ASSERT_TRUE(r.task_started);
  EXPECT_GT(r.task_time_s, 0.0);
  if (scene_case.procedure) {
    // The task starts with the first motion and ends at the insertion target.
    EXPECT_TRUE(r.task_completed);
    ASSERT_TRUE(r.insertion.present);
    EXPECT_TRUE(r.insertion.target_reached);
    EXPECT_TRUE(stats.catheters[0].target_reached);
    // The app's first_target_cycle counts cycles run (cycle index + 1); on the manual clock
    // the cycle of index c wakes at (c + 1) periods.
    EXPECT_EQ(r.insertion.target_time_ns,
              static_cast<std::int64_t>(stats.catheters[0].first_target_cycle) *
                  scene.loop.period_ns);
    EXPECT_LT(r.task_time_s, device.script_duration_s());
    EXPECT_DOUBLE_EQ(r.insertion.time_to_target_s, r.task_time_s);
    EXPECT_GE(r.insertion.max_depth_m, *setup.insertion_target_depth_m);
    EXPECT_EQ(r.instruments[0].grasps, 1U);  // the left forceps grasp the catheter once
  } else {
    // No insertion goal: no insertion metrics, and the task runs to the session's end.
    EXPECT_FALSE(r.task_completed);
    EXPECT_FALSE(r.insertion.present);
    EXPECT_EQ(r.task_end_ns, r.last_time_ns);
  }
  for (std::size_t i = 0; i < scene.instruments.size(); ++i) {
    const InstrumentMetrics& m = r.instruments[i];
    const app::InstrumentStats& s = stats.instruments[i];
    SCOPED_TRACE(scene.instruments[i].name);
    // Where the app measures the same thing, the metrics agree with it.
    EXPECT_NEAR(m.peak_force_n, static_cast<double>(s.peak_force_n), 1e-5);
    EXPECT_NEAR(m.contact_time_s, static_cast<double>(s.contact_cycles) * 1e-3, 1e-9);
    EXPECT_EQ(m.grasps, s.grasps);
    EXPECT_EQ(m.slips, s.slips);
    EXPECT_NEAR(m.grasp_time_s, static_cast<double>(s.grasping_cycles) * 1e-3, 1e-9);
    if (s.contact_cycles > 0) {
      EXPECT_NEAR(m.mean_contact_force_n, s.force_sum_n / static_cast<double>(s.contact_cycles),
                  1e-4);
    }
    // Every instrument moves in the scripts.
    EXPECT_GT(m.movements, 0U);
    EXPECT_GT(m.path_length_m, 0.0);
    EXPECT_NEAR(m.moving_time_s + m.idle_time_s, r.task_time_s, 1e-9);
    ASSERT_TRUE(m.motion_economy.has_value());
    EXPECT_GT(*m.motion_economy, 0.0);
    EXPECT_LE(*m.motion_economy, 1.0);
  }
}

// The liver scene is not in ctest: its tensor image takes the offline tet4 FEM and tensor
// precompute (7.5 s with modelc's checks; tests/rt/app/liver_pipeline_test.sh), too long for
// this test's budget. Run by hand after `modelc build --scene config/scenes/liver.toml` (the
// image where the definition names it): --gtest_also_run_disabled_tests
// --gtest_filter='*liver*' (docs/metrics.md "The scenes").
INSTANTIATE_TEST_SUITE_P(DISABLED_PrebuiltImageScenes, SceneSessionMetrics,
                         ::testing::Values(SceneCase{"liver", false}),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

INSTANTIATE_TEST_SUITE_P(RepositoryScenes, SceneSessionMetrics,
                         ::testing::Values(SceneCase{"cbd", true}, SceneCase{"duct", false},
                                           SceneCase{"wall", false},
                                           SceneCase{"catheter", false}),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

}  // namespace
}  // namespace trainer::metrics
