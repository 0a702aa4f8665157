// Session recording and bit-exact replay through the trainer (docs/recording.md), on the
// reference cbd scene (duct + catheter + two forceps) on the simulated bench:
//  - a recorded session replays with every output and state hash identical, and recording
//    allocates nothing on the RT thread;
//  - one encoder input changed at cycle k (rewritten through the library) is reported at k;
//  - a truncated file and a flipped byte replay up to the damage and say where it is;
//  - a gap (a cycle the ring dropped) is refused at the missing cycle; a changed image is
//    refused before anything runs;
//  - a real-clock run (dt measured, overruns possible) replays bit-exactly too;
//  - the HAL taps count records a full ring refused;
//  - the recording's channel 2 holds the telemetry frames at the stream's rate (no UDP
//    destination configured): each decodes, log time = its cycle time, image checksums match.
// The scene runs from a private copy with its own images, so tests building the shared ones
// in out/ at the same time cannot change an image under a replay.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "catheter_images.hpp"
#include "model_spec.hpp"
#include "trainer/app/hal_taps.hpp"
#include "trainer/app/session_recording.hpp"
#include "trainer/app/trainer_run.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/metrics/session_metrics.hpp"
#include "trainer/model_offline/modal_build.hpp"
#include "trainer/record/cycle_sample.hpp"
#include "trainer/record/recording.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::app {
namespace {

namespace fs = std::filesystem;
const fs::path kRepo{TRAINER_SOURCE_DIR};
// The right forceps first touch the duct at cycle 2990 of the scripted insertion. Sanitizer
// builds (the cbd cycle is ~20x slower under ASan) run 400 cycles, before any contact: the
// changed input then shows in the state hash instead of a command, and the file-damage tests
// (one chunk only) are left to record_test, which covers the reader under the sanitizers.
#if defined(TRAINER_SANITIZER_BUILD)
constexpr std::uint64_t kCycles = 400;
constexpr std::uint64_t kChanged = 300;
constexpr bool kFullSession = false;
#else
constexpr std::uint64_t kCycles = 4000;
constexpr std::uint64_t kChanged = 3000;
constexpr bool kFullSession = true;
#endif

std::string file_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << "'" << from << "' not in the text";
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// A private copy of the cbd scene (models with their images in the directory), built once.
class CbdCopy {
 public:
  static const CbdCopy& get() {
    static const CbdCopy copy;
    return copy;
  }
  fs::path dir;
  fs::path scene;
  std::string error;
  ~CbdCopy() {
    std::error_code ignored;
    fs::remove_all(dir, ignored);
  }

 private:
  CbdCopy() : dir(fs::temp_directory_path() / ("trainer_recording_" + std::to_string(::getpid()))) {
    fs::create_directories(dir / "scenes");
    fs::create_directories(dir / "models");
    write_text(dir / "models/duct.toml",
               replaced(file_text(kRepo / "config/models/duct.toml"),
                        "image = \"../../out/models/duct.img\"", "image = \"duct.img\""));
    write_text(
        dir / "models/catheter_cbd.toml",
        replaced(file_text(kRepo / "config/models/catheter_cbd.toml"),
                 "image = \"../../out/models/catheter_cbd.img\"", "image = \"catheter_cbd.img\""));
    std::string scene_text = file_text(kRepo / "config/scenes/cbd.toml");
    scene_text = replaced(scene_text, "device = \"../devices/sim.toml\"",
                          "device = \"" + (kRepo / "config/devices/sim.toml").string() + "\"");
    scene_text =
        replaced(scene_text, "script = \"../trajectories/cbd_insertion.csv\"",
                 "script = \"" + (kRepo / "config/trajectories/cbd_insertion.csv").string() + "\"");
    scene = dir / "scenes/cbd.toml";
    write_text(scene, scene_text);
    error = test::build_catheter_images(scene);
    if (!error.empty()) return;
    auto loaded = config::load_scene(scene);
    if (!loaded) {
      error = loaded.error().message;
      return;
    }
    for (const config::SceneModelConfig& entry : loaded->models) {
      if (entry.definition.kind != config::ModelKind::modal_shell) continue;
      auto spec = tools::modelc::modal_spec_from(entry.definition);
      if (!spec) {
        error = spec.error().message;
        return;
      }
      auto build = model::offline::build_modal_model(*spec);
      if (!build) {
        error = build.error().message;
        return;
      }
      if (auto written =
              model::offline::write_modal_image(*spec, *build, entry.definition.image_path);
          !written) {
        error = written.error().message;
      }
    }
  }
};

fs::path temp_path(const std::string& name) {
  return CbdCopy::get().dir / (name + ".mcap");
}

RunOptions cbd_options(const fs::path& record_file) {
  RunOptions options;
  options.scene_file = CbdCopy::get().scene;
  options.time_source = TimeSource::simulated;
  options.cycles = kCycles;
  options.on_log = [](const std::string&) {};
  options.record_file = record_file;
  return options;
}

// The recorded session of the cbd scene, recorded once per test program.
const fs::path& cbd_recording() {
  static const fs::path path = [] {
    const fs::path file = temp_path("cbd");
    auto result = run_trainer(cbd_options(file));
    EXPECT_TRUE(result) << (result ? "" : result.error().message);
    return file;
  }();
  return path;
}

// Copies a recording through the library: `edit_session` may change the metadata, `edit`
// a record (false leaves it out).
void rewrite(const fs::path& from, const fs::path& to,
             const std::function<bool(record::CycleRecord&)>& edit,
             const std::function<void(record::SessionInfo&)>& edit_session = {}) {
  std::vector<record::CycleRecord> records;
  auto scan = record::scan_recording(from, [&](const record::CycleRecord& r) {
    records.push_back(r);
    return true;
  });
  ASSERT_TRUE(scan) << scan.error().message;
  record::SessionInfo session = scan->session;
  if (edit_session) edit_session(session);
  record::RecordingWriter writer;
  ASSERT_TRUE(writer.open(to, session));
  for (record::CycleRecord& r : records) {
    if (edit(r)) {
      ASSERT_TRUE(writer.add(r));
    }
  }
  ASSERT_TRUE(writer.close(0));
}

class Recording : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_EQ(CbdCopy::get().error, "") << "cbd copy and images"; }
};

TEST_F(Recording, CbdSessionReplaysBitExactlyWithoutHeapOnTheRtThread) {
  const fs::path file = temp_path("cbd_heap");
  ASSERT_TRUE(core::alloc::hooks_installed());
  auto result = run_trainer(cbd_options(file));
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->heap_allocations_after_arming, 0U);  // taps, hash and ring push included
  EXPECT_EQ(result->recorded_cycles, kCycles);
  EXPECT_EQ(result->recording_dropped_cycles, 0U);
  EXPECT_EQ(result->recording_error, "");
  EXPECT_EQ(result->models.size(), 2U);

  auto replay = replay_recording(file);
  ASSERT_TRUE(replay) << replay.error().message;
  EXPECT_TRUE(replay->identical) << replay_summary(*replay);
  EXPECT_EQ(replay->cycles_replayed, kCycles);
  EXPECT_TRUE(replay->complete);
  EXPECT_EQ(replay_summary(*replay),
            std::to_string(kCycles) + " cycles, all outputs and state hashes identical");
  EXPECT_FALSE(result->telemetry_stream) << "no UDP destination: no stream in the report";

  // Channel 2: the telemetry frames the stream would send, at its rate (60 Hz by default) on
  // the loop's clock in simulated time: at most session time × 60 plus the first and the run's
  // last frame, and at most one per supervisor wake (2 ms of wall time) when the simulation
  // runs faster than that. Each carries the session's metrics so far. How many wakes the
  // supervisor (an ordinary thread) gets while a simulated session runs for a few tens of
  // milliseconds depends on the machine's load: with four copies of this test on two CPUs it
  // sent 6-12 frames where 9-15 wakes were expected, so the lower bound is the first and the
  // last frame only.
  std::uint64_t frames = 0;
  std::uint64_t undecoded = 0;
  std::uint64_t wrong_checksums = 0;
  std::uint64_t wrong_log_times = 0;
  std::int64_t previous_time = -1;
  std::uint64_t backwards = 0;
  std::uint32_t last_flags = 0;
  std::uint64_t without_metrics = 0;
  auto frame = std::make_unique<telemetry::Frame>();
  auto with_frames = record::scan_recording(file, {}, [&](const record::TelemetryMessage& m) {
    ++frames;
    const auto decoded = telemetry::decode(std::as_bytes(m.bytes), *frame);
    if (!decoded.ok()) {
      ++undecoded;
      return true;
    }
    if (static_cast<std::uint64_t>(frame->cycle_time_ns) != m.log_time_ns) ++wrong_log_times;
    if (frame->cycle_time_ns < previous_time) ++backwards;
    previous_time = frame->cycle_time_ns;
    last_flags = frame->flags;
    if (!frame->has_metrics) ++without_metrics;
    for (std::size_t i = 0; i < frame->model_count; ++i) {
      const telemetry::ModelState& model = frame->models[i];
      const auto& info = result->models.at(model.scene_index);
      if (model.image_checksum != info.image_checksum) ++wrong_checksums;
    }
    return true;
  });
  ASSERT_TRUE(with_frames) << with_frames.error().message;
  EXPECT_EQ(with_frames->records, kCycles);
  EXPECT_EQ(with_frames->telemetry_frames, frames);
  const double session_s = static_cast<double>(kCycles) * 1e-3;  // cbd: 1 ms period
  EXPECT_LE(static_cast<double>(frames), session_s * 60.0 + 2.0) << result->wall_time_s << " s";
  EXPECT_GE(frames, 2U);
  EXPECT_EQ(without_metrics, 0U);
  // The last frame's metrics are the report's (every cycle fed before it was sent).
  ASSERT_TRUE(result->metrics);
  EXPECT_FLOAT_EQ(frame->metrics.session_time_s, static_cast<float>(result->metrics->session_time_s));
  EXPECT_FLOAT_EQ(frame->metrics.instruments[0].path_length_m,
                  static_cast<float>(result->metrics->instruments[0].path_length_m));
  EXPECT_EQ(undecoded, 0U);
  EXPECT_EQ(wrong_log_times, 0U);
  EXPECT_EQ(wrong_checksums, 0U);
  EXPECT_EQ(backwards, 0U);
  EXPECT_NE(last_flags & telemetry::kFlagRunEnded, 0U);
  std::printf("channel 2: %llu telemetry frames over %.2f s of session, %.2f s of wall time\n",
              static_cast<unsigned long long>(frames), session_s, result->wall_time_s);
  if (!kFullSession) return;

  // The recording holds what the session did: contacts with the duct, distinct state hashes.
  std::uint64_t contact_cycles = 0;
  std::uint64_t duct_loaded_cycles = 0;
  std::uint64_t other_model_cycles = 0;
  std::uint64_t hash_changes = 0;
  std::uint64_t previous_hash = 0;
  auto scan = record::scan_recording(file, [&](const record::CycleRecord& r) {
    if (r.derived.instruments[1].tissue_contact != 0) ++contact_cycles;
    if (r.derived.contact_model == 0) ++duct_loaded_cycles;  // the duct is the scene's model 0
    if (r.derived.contact_model > 0) ++other_model_cycles;   // the catheter is not tissue
    if (r.state_hash != previous_hash) ++hash_changes;
    previous_hash = r.state_hash;
    return true;
  });
  ASSERT_TRUE(scan);
  EXPECT_GT(contact_cycles, 100U);

  // Trainee metrics straight from the recording's derived blocks (no replay).
  auto scene = config::load_scene(CbdCopy::get().scene);
  ASSERT_TRUE(scene) << scene.error().message;
  metrics::SessionSetup setup;
  setup.thresholds = scene->metrics;
  setup.period_ns = scene->loop.period_ns;
  setup.instrument_count = static_cast<std::uint32_t>(scene->instruments.size());
  auto session = metrics::SessionMetrics::create(setup);
  ASSERT_TRUE(session) << session.error().message;
  auto fed = record::scan_recording(file, [&](const record::CycleRecord& r) {
    (void)session->add(record::cycle_sample_of(r));
    return true;
  });
  ASSERT_TRUE(fed);
  const metrics::SessionResult figures = session->result();
  EXPECT_EQ(figures.samples, kCycles);
  EXPECT_EQ(figures.refused_samples, 0U);
  EXPECT_TRUE(figures.task_started);
  EXPECT_GT(figures.instruments[1].peak_force_n, 0.0);  // the right forceps on the duct
  EXPECT_GT(figures.instruments[0].path_length_m, 0.0);
  EXPECT_TRUE(figures.insertion.present);
  EXPECT_GE(duct_loaded_cycles, contact_cycles);
  EXPECT_EQ(other_model_cycles, 0U);
  EXPECT_GT(hash_changes, kCycles / 2);
}

TEST_F(Recording, OneChangedEncoderInputIsReportedAtItsCycle) {
  // The right forceps press the duct from cycle 2990 on; its insertion joint (device
  // instrument 1, joint 2: channel 7) moved by 0.1 mm at cycle 3000 changes that cycle's
  // command.
  const fs::path changed = temp_path("changed");
  rewrite(cbd_recording(), changed, [](record::CycleRecord& r) {
    if (r.cycle_index == kChanged) r.encoders[7].position += 1e-4F;
    return true;
  });
  auto replay = replay_recording(changed);
  ASSERT_TRUE(replay) << replay.error().message;
  EXPECT_FALSE(replay->identical);
  ASSERT_TRUE(replay->first_difference_cycle.has_value()) << replay_summary(*replay);
  EXPECT_EQ(*replay->first_difference_cycle, kChanged) << replay->difference;
  EXPECT_EQ(replay->cycles_replayed, kChanged);
  if (!kFullSession) {
    EXPECT_EQ(replay->difference.rfind("state_hash: ", 0), 0U) << replay->difference;
    return;
  }
  // The force on the duct changed: the command of one of the right instrument's channels.
  EXPECT_EQ(replay->difference.rfind("command[channel ", 0), 0U) << replay->difference;
  EXPECT_NE(replay_summary(*replay).find("replay differs at cycle 3000: command[channel "),
            std::string::npos);
}

// Not the fixture: the sanitizer build skips them before building the images.
TEST(RecordingDamage, TruncatedAndCorruptFilesReplayUpToTheDamage) {
  if (!kFullSession) GTEST_SKIP() << "one chunk in the sanitizer build's session";
  ASSERT_EQ(CbdCopy::get().error, "") << "cbd copy and images";
  const auto bytes = *record::mcap::read_file(cbd_recording());
  const fs::path cut = temp_path("cut");
  {
    std::ofstream out(cut, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()),
              static_cast<std::streamsize>(bytes.size() * 2 / 3));
  }
  auto truncated = replay_recording(cut);
  ASSERT_TRUE(truncated) << truncated.error().message;
  EXPECT_FALSE(truncated->identical);
  EXPECT_FALSE(truncated->first_difference_cycle.has_value());
  EXPECT_GT(truncated->cycles_replayed, 1000U);
  EXPECT_LT(truncated->cycles_replayed, kCycles);
  EXPECT_NE(truncated->damage.find("truncated"), std::string::npos) << truncated->damage;

  auto flipped_bytes = bytes;
  flipped_bytes[bytes.size() / 2] ^= 0x01;
  const fs::path flipped = temp_path("flipped");
  {
    std::ofstream out(flipped, std::ios::binary);
    out.write(reinterpret_cast<const char*>(flipped_bytes.data()),
              static_cast<std::streamsize>(flipped_bytes.size()));
  }
  auto corrupt = replay_recording(flipped);
  ASSERT_TRUE(corrupt) << corrupt.error().message;
  EXPECT_FALSE(corrupt->identical);
  EXPECT_FALSE(corrupt->first_difference_cycle.has_value());
  EXPECT_LT(corrupt->cycles_replayed, kCycles);
  EXPECT_NE(corrupt->damage.find("byte "), std::string::npos) << corrupt->damage;
  EXPECT_NE(replay_summary(*corrupt).find("identical up to the damage"), std::string::npos);
}

TEST(RecordingDamage, GapAndChangedImageAreRefused) {
  if (!kFullSession) GTEST_SKIP() << "release only (CI time); record_test covers the reader";
  ASSERT_EQ(CbdCopy::get().error, "") << "cbd copy and images";
  const fs::path gap = temp_path("gap");
  rewrite(cbd_recording(), gap, [](record::CycleRecord& r) { return r.cycle_index != 1234; });
  auto gapped = replay_recording(gap);
  ASSERT_TRUE(gapped) << gapped.error().message;
  EXPECT_FALSE(gapped->identical);
  EXPECT_EQ(gapped->cycles_replayed, 1234U);
  EXPECT_NE(gapped->damage.find("cycle 1234 is missing"), std::string::npos) << gapped->damage;

  const fs::path other_image = temp_path("other_image");
  rewrite(
      cbd_recording(), other_image, [](record::CycleRecord&) { return true; },
      [](record::SessionInfo& session) { session["model.0.image_checksum"] = "12345"; });
  auto refused = replay_recording(other_image);
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("model 'duct' image"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("the recording 12345"), std::string::npos);
}

TEST_F(Recording, RealClockRunReplaysBitExactly) {
  const fs::path file = temp_path("real");
  RunOptions options = cbd_options(file);
  options.time_source = TimeSource::real;
  options.apply_rt_settings = false;
  options.cycles = kFullSession ? 500 : 200;
  auto result = run_trainer(options);
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->recorded_cycles, *options.cycles);
  auto replay = replay_recording(file);
  ASSERT_TRUE(replay) << replay.error().message;
  EXPECT_TRUE(replay->identical) << replay_summary(*replay);
  EXPECT_EQ(replay->cycles_replayed, *options.cycles);
  // Measured dt: the wake-to-wake intervals were recorded, not the nominal period.
  bool measured_dt = false;
  auto scan = record::scan_recording(file, [&](const record::CycleRecord& r) {
    if (r.cycle_index > 0 && r.dt_s != 1e-3) measured_dt = true;
    return true;
  });
  ASSERT_TRUE(scan);
  EXPECT_TRUE(measured_dt);
}

// A HAL of one encoder and one actuator, for the taps alone.
class OneChannel final : public hal::EncoderInterface, public hal::ActuatorInterface {
 public:
  std::size_t encoder_count() const noexcept override { return 1; }
  hal::ReturnCode read_encoders(std::span<hal::EncoderSample> out) noexcept override {
    out[0].position = 0.5F;
    out[0].valid = true;
    return hal::ReturnCode::ok;
  }
  std::size_t actuator_count() const noexcept override { return 1; }
  hal::ReturnCode write_actuators(std::span<const hal::ActuatorCommand>) noexcept override {
    return hal::ReturnCode::error;
  }
  hal::ReturnCode read_actuator_status(std::span<hal::ActuatorStatus>) noexcept override {
    return hal::ReturnCode::ok;
  }
};

TEST(HalTaps, RecordWhatPassesAndCountAFullRing) {
  OneChannel hal;
  auto ring = std::make_unique<RecordRing>();
  auto taps = HalTaps::create(HalBinding{&hal, &hal, nullptr, nullptr}, ring.get());
  ASSERT_TRUE(taps);
  HalTaps& tap = **taps;
  EXPECT_EQ(tap.binding().digital_inputs, nullptr);
  const std::uint64_t cycles = kRecordRingCapacity + 100;
  std::array<hal::EncoderSample, 1> samples{};
  std::array<hal::ActuatorCommand, 1> commands{{{0.25F, true}}};
  for (std::uint64_t k = 0; k < cycles; ++k) {
    tap.begin_cycle(loop::CycleTiming{k, 0, 0, 1e-3, 0});
    EXPECT_EQ(tap.binding().encoders->read_encoders(samples), hal::ReturnCode::ok);
    EXPECT_EQ(tap.binding().actuators->write_actuators(commands), hal::ReturnCode::error);
  }
  tap.finish();
  EXPECT_EQ(ring->dropped(), 100U);  // the RT side never waits: the newest are dropped
  EXPECT_EQ(tap.pushed(), kRecordRingCapacity);
  record::CycleRecord first{};
  ASSERT_TRUE(ring->pop(first));
  EXPECT_EQ(first.cycle_index, 0U);
  EXPECT_EQ(first.channel_count, 1U);
  EXPECT_EQ(first.encoders[0].position, 0.5F);
  EXPECT_EQ(first.encoder_rc, 0U);
  EXPECT_EQ(first.commands[0].effort, 0.25F);
  EXPECT_EQ(first.actuator_write_rc, 1U);  // error, as the HAL returned it
  EXPECT_EQ(first.status_rc, record::kNotCalled);
}

TEST(HalTaps, InSimulatedTimeAFullRingWaitsForTheWriter) {
  OneChannel hal;
  auto ring = std::make_unique<RecordRing>();
  auto taps = HalTaps::create(HalBinding{&hal, &hal, nullptr, nullptr}, ring.get());
  ASSERT_TRUE(taps);
  HalTaps& tap = **taps;
  tap.set_wait_when_full(true);
  const std::uint64_t cycles = 3 * kRecordRingCapacity;
  std::atomic<bool> done{false};
  std::thread cycle_thread([&] {
    std::array<hal::EncoderSample, 1> samples{};
    for (std::uint64_t k = 0; k < cycles; ++k) {
      tap.begin_cycle(loop::CycleTiming{k, 0, 0, 1e-3, 0});
      (void)tap.binding().encoders->read_encoders(samples);
    }
    tap.finish();
    done.store(true, std::memory_order_release);
  });
  // A slow writer: the ring fills up many times over.
  std::uint64_t expected = 0;
  record::CycleRecord r{};
  for (;;) {
    const bool finished = done.load(std::memory_order_acquire);
    if (ring->pop(r)) {
      ASSERT_EQ(r.cycle_index, expected);
      ++expected;
      if (expected % 512 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    } else if (finished) {
      break;
    }
  }
  cycle_thread.join();
  EXPECT_EQ(expected, cycles);
  EXPECT_EQ(ring->dropped(), 0U);
}

}  // namespace
}  // namespace trainer::app
