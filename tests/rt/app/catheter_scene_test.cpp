// The catheter in the trainer: config/scenes/catheter.toml runs with the particle catheter
// built in the arena and stepped every cycle (no heap after arming, held at its introducer);
// gravity pulls it by m·g per particle (the early free fall matches the analytical damped fall,
// then it hangs below its introducer, settled and unstretched); and a catheter that cannot be
// stable within its max_substeps is refused at setup, naming the file and the substeps needed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "catheter_build.hpp"
#include "catheter_images.hpp"
#include "trainer/app/report.hpp"
#include "trainer/app/trainer_run.hpp"
#include "trainer/config/model.hpp"
#include "trainer/core/alloc_counter.hpp"
#include "trainer/model/image_format.hpp"

namespace trainer::app {
namespace {

namespace fs = std::filesystem;

const fs::path kRepo{TRAINER_SOURCE_DIR};

std::string read_text(const fs::path& path) {
  std::ifstream stream(path, std::ios::binary);
  std::ostringstream text;
  text << stream.rdbuf();
  return text.str();
}

std::string replaced(std::string text, std::string_view from, std::string_view to) {
  const std::size_t position = text.find(from);
  EXPECT_NE(position, std::string::npos) << "test edit: '" << from << "' not in the text";
  if (position != std::string::npos) text.replace(position, from.size(), to);
  return text;
}

RunOptions simulated(const fs::path& scene, std::uint64_t cycles) {
  RunOptions options;
  options.scene_file = scene;
  options.time_source = TimeSource::simulated;
  options.cycles = cycles;
  options.on_log = [](const std::string&) {};
  return options;
}

const LoadedModelInfo* catheter_of(const RunResult& result) {
  for (const LoadedModelInfo& model : result.models) {
    if (model.kind == config::ModelKind::catheter) return &model;
  }
  return nullptr;
}

bool all_finite(const std::vector<std::array<float, 3>>& positions) {
  for (const auto& p : positions) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) return false;
  }
  return true;
}

// The default catheter's introducer (config/models/catheter.toml [pose] start_m).
constexpr std::array<float, 3> kIntroducerM{0.0F, 0.03F, -0.06F};

// 100,000 cycles (100 s of procedure); 10,000 in the sanitizer build, where the same run takes
// over two minutes and the point is memory errors, not the soak (CI's time budget).
#if defined(TRAINER_SANITIZER_BUILD)
constexpr std::uint64_t kSoakCycles = 10'000;
#else
constexpr std::uint64_t kSoakCycles = 100'000;
#endif

TEST(CatheterScene, RunsWithNoHeapAllocationsOverALongRun) {
  ASSERT_TRUE(core::alloc::hooks_installed());
  ASSERT_EQ(test::build_catheter_images(kRepo / "config/scenes/catheter.toml"), "");
  auto result = run_trainer(simulated(kRepo / "config/scenes/catheter.toml", kSoakCycles));
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->loop.cycles, kSoakCycles);
  EXPECT_EQ(result->heap_allocations_after_arming, 0U);
  EXPECT_EQ(result->latched_faults, 0U) << result->first_fault;
  EXPECT_EQ(result->app.model_step_errors, 0U);
  // The wall scene's chain still runs beside it.
  EXPECT_GT(result->app.instruments[0].contact_cycles, 1000U);

  const LoadedModelInfo* catheter = catheter_of(*result);
  ASSERT_NE(catheter, nullptr);
  EXPECT_EQ(catheter->name, "catheter");
  EXPECT_EQ(catheter->particle_count, 21U);
  // docs/catheter.md: 2/ω_r = 1277.5 µs for this catheter (the bending's explicit remainder,
  // ω_r² = ¼ · 20 k_b/(m l0²); axial, bending, damping and contacts linearly implicit), 1
  // substep per 1 ms.
  EXPECT_NEAR(catheter->stable_substep_s, 1277.45e-6, 0.01e-6);
  EXPECT_EQ(catheter->substeps_per_period, 1U);
  EXPECT_EQ(catheter->max_substeps, 64U);
  EXPECT_GT(catheter->arena_bytes, 21U * 7U * sizeof(float) * 3U);  // 7 arrays of N vectors
  ASSERT_EQ(catheter->final_positions_m.size(), 21U);
  EXPECT_TRUE(all_finite(catheter->final_positions_m));
  EXPECT_EQ(catheter->final_positions_m.front(), kIntroducerM);  // held exactly
  // Nothing touches it and gravity is off: it stays straight along +x, 0.3 m long.
  EXPECT_NEAR(catheter->final_positions_m.back()[0], 0.3F, 1e-5F);
  EXPECT_NEAR(catheter->final_positions_m.back()[2], kIntroducerM[2], 1e-5F);

  const nlohmann::json report = report_json(*result);
  ASSERT_EQ(report["models"].size(), 1U);
  EXPECT_EQ(report["models"][0]["kind"], "catheter");
  EXPECT_EQ(report["models"][0]["substeps_per_period"], 1);
  EXPECT_EQ(report["models"][0]["particle_count"], 21);
  EXPECT_EQ(report["metrics"]["samples"], kSoakCycles);
  EXPECT_EQ(report["metrics"]["refused_samples"], 0);
  EXPECT_NE(report_summary(*result).find("1 substeps per 1000.0 us period"), std::string::npos)
      << report_summary(*result);
}

// A copy of the catheter scene and everything it names in a temporary directory, with the
// catheter definition edited.
class EditedCatheterScene : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path() /
            ("trainer_catheter_scene_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(root_);
    for (const char* directory : {"scenes", "models", "devices", "trajectories"}) {
      fs::create_directories(root_ / directory);
    }
    fs::copy_file(kRepo / "config/scenes/catheter.toml", root_ / "scenes/catheter.toml");
    fs::copy_file(kRepo / "config/devices/sim.toml", root_ / "devices/sim.toml");
    fs::copy_file(kRepo / "config/trajectories/wall_press.csv",
                  root_ / "trajectories/wall_press.csv");
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(root_, ignored);
  }
  // Writes the default catheter with one edit and its image beside it (built as `modelc
  // build` does); returns the scene that names it.
  fs::path scene_with(std::string_view from, std::string_view to) const {
    write_definition(from, to);
    auto definition = config::load_model_definition(root_ / "models/catheter.toml");
    EXPECT_TRUE(definition) << definition.error().message;
    if (definition) (void)tools::modelc::build_catheter_model("catheter", *definition, 1e-3);
    return root_ / "scenes/catheter.toml";
  }
  // The definition alone (its image, if any, left as it is).
  void write_definition(std::string_view from, std::string_view to) const {
    std::string text =
        replaced(read_text(kRepo / "config/models/catheter.toml"), kRepoImage, kLocalImage);
    std::ofstream(root_ / "models/catheter.toml", std::ios::binary | std::ios::trunc)
        << replaced(text, from, to);
  }
  static constexpr std::string_view kRepoImage = "image = \"../../out/models/catheter.img\"";
  static constexpr std::string_view kLocalImage = "image = \"catheter.img\"";

  fs::path root_;
};

constexpr std::string_view kNoGravity = "gravity_m_per_s2 = [0.0, 0.0, 0.0]";
constexpr std::string_view kGravity = "gravity_m_per_s2 = [0.0, 0.0, -9.81]";

TEST_F(EditedCatheterScene, GravityFallsAsTheDampedFreeFallAtFirst) {
  // For 20 ms the tip, 0.3 m from the held root, does not yet feel the root (bending
  // "diffusion" length √(t √(EI/ρ_l)) ≈ 5.5 cm): it falls as a free particle under m·g with
  // the drag −b v, z(t) = g/c · t − g/c² (1 − e^{−ct}), c = b/m. A cycle skipped or stepped
  // twice, or a force other than m·g, moves it by far more than the 1 % tolerance. Run at
  // 10 kHz (200 cycles): the step error of (semi-)implicit Euler is first order, 1/n of the
  // drop after n steps — 0.5 % here; at 1 kHz, one 1 ms substep per cycle since issue 19
  // round 3, it would be 3.7 % (it was 0.8 % with 6 substeps). (At 100 ms the tip does feel
  // the chain: 32.8 mm against the free particle's 27.1 mm, the same at 1 ms and 10 µs steps.)
  const std::uint64_t cycles = 200;
  RunOptions options = simulated(scene_with(kNoGravity, kGravity), cycles);
  options.loop_overrides.period_us = 100;
  auto result = run_trainer(options);
  ASSERT_TRUE(result) << result.error().message;
  EXPECT_EQ(result->app.model_step_errors, 0U);
  const LoadedModelInfo* catheter = catheter_of(*result);
  ASSERT_NE(catheter, nullptr);
  ASSERT_EQ(catheter->final_positions_m.size(), 21U);

  const double mass_kg = 1.65e-3 * 0.3 / 21.0;  // ρ_l L / N
  const double c = 5.0e-4 / mass_kg;
  const double g = 9.81;
  const double t = static_cast<double>(cycles) * 1e-4;
  const double expected_drop_m = g / c * t - g / (c * c) * (1.0 - std::exp(-c * t));
  const auto& tip = catheter->final_positions_m.back();
  const double drop_m = static_cast<double>(kIntroducerM[2]) - static_cast<double>(tip[2]);
  EXPECT_NEAR(drop_m, expected_drop_m, 0.01 * expected_drop_m);
  EXPECT_NEAR(tip[0], 0.3F, 1e-4F);
  EXPECT_EQ(catheter->final_positions_m.front(), kIntroducerM);
}

TEST_F(EditedCatheterScene, UnderGravityItHangsBelowItsIntroducerAndSettles) {
  const fs::path scene = scene_with(kNoGravity, kGravity);
  auto early = run_trainer(simulated(scene, 4000));
  auto late = run_trainer(simulated(scene, 6000));
  ASSERT_TRUE(early) << early.error().message;
  ASSERT_TRUE(late) << late.error().message;
  EXPECT_EQ(late->heap_allocations_after_arming, 0U);  // the m·g path allocates nothing either
  EXPECT_EQ(late->app.model_step_errors, 0U);
  const LoadedModelInfo* a = catheter_of(*early);
  const LoadedModelInfo* b = catheter_of(*late);
  ASSERT_TRUE(a != nullptr && b != nullptr);
  ASSERT_EQ(b->final_positions_m.size(), 21U);
  EXPECT_TRUE(all_finite(b->final_positions_m));
  EXPECT_EQ(b->final_positions_m.front(), kIntroducerM);

  // Every particle but the held root below the introducer; the tip well below (a linear
  // cantilever estimate ρ_l g L⁴/(8 EI) = 0.42 m exceeds L: it hangs).
  for (std::size_t i = 1; i < b->final_positions_m.size(); ++i) {
    EXPECT_LT(b->final_positions_m[i][2], kIntroducerM[2]) << "particle " << i;
  }
  EXPECT_LT(b->final_positions_m.back()[2], kIntroducerM[2] - 0.1F);
  // Unstretched: its weight (4.9 mN) strains EA = 157 N by 3e-5.
  double length_m = 0.0;
  for (std::size_t i = 1; i < b->final_positions_m.size(); ++i) {
    const auto& p = b->final_positions_m[i];
    const auto& q = b->final_positions_m[i - 1];
    length_m += std::hypot(static_cast<double>(p[0] - q[0]), static_cast<double>(p[1] - q[1]),
                           static_cast<double>(p[2] - q[2]));
  }
  EXPECT_NEAR(length_m, 0.3, 0.3 * 1e-3);
  // Settled: the tip moved less than 0.1 mm between 4 s and 6 s (it hangs at about 0.22 m below).
  const auto& tip_a = a->final_positions_m.back();
  const auto& tip_b = b->final_positions_m.back();
  EXPECT_LT(std::hypot(tip_a[0] - tip_b[0], tip_a[1] - tip_b[1], tip_a[2] - tip_b[2]), 1e-4F);
}

TEST_F(EditedCatheterScene, CatheterUnstableWithinItsBudgetIsRefusedBeforeArming) {
  // The default needs 1 substep of 1277 µs per 1 ms period; with EI = 1 N·m² (a steel rod's)
  // it needs 126 of 7.98 µs, and its budget of 64 cannot hold it.
  auto result = run_trainer(
      simulated(scene_with("bending_stiffness_n_m2 = 3.9e-5", "bending_stiffness_n_m2 = 1.0"), 10));
  ASSERT_FALSE(result);
  const std::string& message = result.error().message;
  EXPECT_NE(message.find((root_ / "scenes/catheter.toml").string()), std::string::npos) << message;
  EXPECT_NE(message.find("model 'catheter' (" + (root_ / "models/catheter.img").string() +
                         ", built from " + (root_ / "models/catheter.toml").string() + ")"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("needs 126 substeps"), std::string::npos) << message;
  EXPECT_NE(message.find("max_substeps = 64"), std::string::npos) << message;

  // The same file with more particles needs more substeps (the bending's ω² grows as N⁴: 28
  // at N = 121, 111 at N = 241) than its 64.
  auto dense = run_trainer(simulated(scene_with("particle_count = 21", "particle_count = 241"), 10));
  ASSERT_FALSE(dense);
  EXPECT_NE(dense.error().message.find("needs 111 substeps"), std::string::npos)
      << dense.error().message;
}

// The trainer runs catheters from their images only: a missing image, one built from other
// parameters than the scene's definition, and a damaged one are refused before arming, each
// naming the file and what is wrong (and how to rebuild).
TEST_F(EditedCatheterScene, MissingStaleOrDamagedImagesAreRefusedBeforeArming) {
  const fs::path scene = scene_with(kNoGravity, kNoGravity);
  const fs::path image = root_ / "models/catheter.img";
  ASSERT_TRUE(fs::exists(image));
  ASSERT_TRUE(run_trainer(simulated(scene, 5)));

  // Stale: the definition edited after the image was built.
  write_definition("axial_stiffness_n = 157.0", "axial_stiffness_n = 200.0");
  auto stale = run_trainer(simulated(scene, 5));
  ASSERT_FALSE(stale);
  EXPECT_NE(stale.error().message.find(image.string()), std::string::npos) << stale.error().message;
  EXPECT_NE(stale.error().message.find("[catheter] axial_stiffness_n = 200"), std::string::npos)
      << stale.error().message;
  EXPECT_NE(stale.error().message.find("out of date"), std::string::npos) << stale.error().message;
  EXPECT_NE(stale.error().message.find("modelc build --scene"), std::string::npos)
      << stale.error().message;

  // Damaged: one byte of the rest positions flipped (the checksum catches it).
  write_definition(kNoGravity, kNoGravity);
  std::string bytes = read_text(image);
  ASSERT_GT(bytes.size(), 600U);
  bytes[bytes.size() - 70] = static_cast<char>(bytes[bytes.size() - 70] ^ 0x10);
  std::ofstream(image, std::ios::binary | std::ios::trunc) << bytes;
  auto damaged = run_trainer(simulated(scene, 5));
  ASSERT_FALSE(damaged);
  EXPECT_NE(damaged.error().message.find(image.string()), std::string::npos)
      << damaged.error().message;
  EXPECT_NE(damaged.error().message.find("checksum"), std::string::npos) << damaged.error().message;

  // Missing.
  fs::remove(image);
  auto missing = run_trainer(simulated(scene, 5));
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find(image.string()), std::string::npos)
      << missing.error().message;
  EXPECT_NE(missing.error().message.find("build it with: modelc build --scene"), std::string::npos)
      << missing.error().message;
}

// Files an appliance trusts (docs/fuzzing.md): an image damaged behind a valid checksum (the
// record's stable substep a denormal, which fuzz_model_image found converting ~1e40 to an
// integer), a truncated image, a malformed device file and a malformed scene are each refused
// by run_trainer with a message naming the file, and nothing runs: no cycle, no log line (the
// loop logs when it arms). trainer_main turns every run_trainer error into exit status 1
// (tests/rt/app/untrusted_files_test.sh checks the status on the trainer binary).
TEST_F(EditedCatheterScene, TheTrainerNeverArmsOnADamagedImageOrAMalformedFile) {
  const fs::path scene = scene_with(kNoGravity, kNoGravity);
  const fs::path image = root_ / "models/catheter.img";
  ASSERT_TRUE(fs::exists(image));
  std::vector<std::string> log;
  const auto refused = [&](const RunOptions& options) -> std::string {
    log.clear();
    RunOptions logged = options;
    logged.on_log = [&log](const std::string& line) { log.push_back(line); };
    auto result = run_trainer(logged);
    EXPECT_FALSE(result) << "armed and ran " << (result ? result->loop.cycles : 0) << " cycles";
    EXPECT_TRUE(log.empty()) << log.front();
    return result ? std::string{} : result.error().message;
  };
  const std::string good = read_text(image);

  // The stable substep a float denormal, checksum recomputed: the loader accepts the record
  // (finite, > 0, below the stability bound), the catheter's substep budget refuses it.
  std::string tiny = good;
  model::ImageHeaderV1 header{};
  std::memcpy(&header, tiny.data(), sizeof header);
  std::uint64_t record_offset = 0;
  for (std::uint32_t i = 0; i < header.section_count; ++i) {
    model::SectionEntryV1 entry{};
    std::memcpy(&entry, tiny.data() + model::kImageHeaderBytes + i * model::kImageSectionEntryBytes,
                sizeof entry);
    if (entry.id == static_cast<std::uint32_t>(model::SectionId::catheter_parameters)) {
      record_offset = entry.offset;
    }
  }
  ASSERT_NE(record_offset, 0U);
  const float denormal = 1e-44F;
  std::memcpy(tiny.data() + record_offset + offsetof(model::CatheterParametersV1, stable_substep_s),
              &denormal, sizeof denormal);
  const std::uint64_t checksum = model::compute_image_checksum(
      {reinterpret_cast<const std::byte*>(tiny.data()), tiny.size()});
  std::memcpy(tiny.data() + model::kImageChecksumOffset, &checksum, sizeof checksum);
  std::ofstream(image, std::ios::binary | std::ios::trunc) << tiny;
  std::string message = refused(simulated(scene, 5));
  EXPECT_NE(message.find(image.string()), std::string::npos) << message;
  EXPECT_NE(message.find("substeps"), std::string::npos) << message;

  // Truncated by one byte.
  std::ofstream(image, std::ios::binary | std::ios::trunc) << good.substr(0, good.size() - 1);
  message = refused(simulated(scene, 5));
  EXPECT_NE(message.find(image.string()), std::string::npos) << message;
  EXPECT_NE(message.find("file_bytes"), std::string::npos) << message;
  std::ofstream(image, std::ios::binary | std::ios::trunc) << good;

  // A device file with a syntax error, given as the scene's device (trainer --device).
  const fs::path device = root_ / "devices/broken.toml";
  std::ofstream(device, std::ios::binary | std::ios::trunc)
      << replaced(read_text(kRepo / "config/devices/sim.toml"), "[device]", "[device");
  RunOptions with_device = simulated(scene, 5);
  with_device.device_file = device;
  message = refused(with_device);
  EXPECT_NE(message.find("broken.toml:"), std::string::npos) << message;
  EXPECT_NE(message.find("syntax error"), std::string::npos) << message;

  // A scene with a value out of range.
  const fs::path bad_scene = root_ / "scenes/broken.toml";
  std::ofstream(bad_scene, std::ios::binary | std::ios::trunc)
      << replaced(read_text(scene), "period_us = 1000", "period_us = 0");
  message = refused(simulated(bad_scene, 5));
  EXPECT_NE(message.find("broken.toml:"), std::string::npos) << message;
  EXPECT_NE(message.find("period_us"), std::string::npos) << message;

  // The good image still runs (the edits above are what was refused).
  auto runs = run_trainer(simulated(scene, 5));
  ASSERT_TRUE(runs) << runs.error().message;
  EXPECT_EQ(runs->loop.cycles, 5U);
}

}  // namespace
}  // namespace trainer::app
