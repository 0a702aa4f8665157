// The repository's catheter definitions as images: `modelc build` (the real binary) writes a
// loadable catheter image for the cbd and catheter scenes, refuses a definition whose image the
// loader would refuse, and a catheter created from the image steps bit for bit like the one
// created from the same definition's parameters — over 1,000 periods with gravity, a moving
// tip load, contact planes on a particle and on a segment, a clamped or free start, and a
// grasped segment dragged and released.
#include <cstring>
#include <filesystem>
#include <fstream>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "command_test_support.hpp"
#include "model_spec.hpp"
#include "trainer/config/model.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/catheter.hpp"
#include "trainer/model/catheter_image.hpp"
#include "trainer/model/image_loader.hpp"
#include "trainer/model_offline/catheter_image.hpp"

namespace trainer::model::offline {
namespace {

namespace fs = std::filesystem;
using Vec3 = Eigen::Vector3f;

const fs::path kRepo = TRAINER_SOURCE_DIR;
constexpr float kPeriodS = 1e-3F;
constexpr std::uint32_t kPlaneCapacity = 8;

class CatheterDefinitionImage : public testing::CommandTest {
 protected:
  // A private copy of config/, so images land in directory_/out (the definitions say ../../out).
  fs::path copy_config() {
    fs::copy(kRepo / "config", directory_ / "config", fs::copy_options::recursive);
    return directory_ / "config";
  }

  core::Expected<ModelImage> load(const fs::path& image) {
    arena_ = core::Arena::create(64 * 1024).value();
    return load_model_image(image, arena_, ImageLimits{}, ModelKind::catheter);
  }

  core::Arena arena_ = core::Arena::create(64).value();
};

bool same_bits(std::span<const Vec3> a, std::span<const Vec3> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
}

TEST_F(CatheterDefinitionImage, ModelcBuildWritesALoadableImageForEachScene) {
  const fs::path config = copy_config();
  struct Case {
    const char* scene;
    const char* definition;
    std::uint32_t particles;
  };
  for (const Case& c :
       {Case{"cbd.toml", "catheter_cbd.toml", 11}, Case{"catheter.toml", "catheter.toml", 21}}) {
    ASSERT_EQ(run(MODELC_PATH, "build --scene " + (config / "scenes" / c.scene).string() +
                                   " --only catheter --report " + report_path()),
              0)
        << output_;
    const fs::path image_path =
        directory_ / "out/models" / fs::path(c.definition).replace_extension(".img");
    EXPECT_NE(
        output_.find("model 'catheter': catheter, " + std::to_string(c.particles) + " particles"),
        std::string::npos)
        << output_;
    EXPECT_NE(output_.find(image_path.string()), std::string::npos) << output_;

    const nlohmann::json entry = report()["models"][0];
    EXPECT_EQ(entry["kind"], "catheter");
    EXPECT_EQ(entry["built"], true);
    EXPECT_EQ(entry["image"], image_path.string());
    EXPECT_EQ(entry["image_bytes"].get<std::uintmax_t>(), fs::file_size(image_path));
    EXPECT_EQ(entry["particle_count"], c.particles);
    EXPECT_EQ(entry["max_substeps"], 64);
    EXPECT_LE(entry["substeps_per_period"].get<int>(), 64);
    EXPECT_GE(entry["timings_s"]["total"].get<double>(), 0.0);

    auto image = load(image_path);
    ASSERT_TRUE(image) << image.error().message;
    const CatheterModelData data = catheter_model_data(image.value());
    auto definition = config::load_model_definition(config / "models" / c.definition);
    ASSERT_TRUE(definition) << definition.error().message;
    EXPECT_EQ(definition->image_path, image_path);
    auto chain = derive_catheter_chain(tools::modelc::catheter_inputs_from(*definition).params);
    ASSERT_TRUE(chain) << chain.error().message;
    EXPECT_EQ(std::memcmp(&data.chain, &chain.value(), sizeof data.chain), 0);
    EXPECT_EQ(entry["stable_substep_s"].get<double>(),
              static_cast<double>(data.chain.stable_substep_s));
    EXPECT_EQ(data.hold_start, definition->catheter.hold_start);
  }
}

TEST_F(CatheterDefinitionImage, AStiffContactKeepsTheSubstepAStiffBendingShortensIt) {
  const fs::path config = copy_config();
  // Contacts are linearly implicit: 1e5 N/m on the cbd chain keeps its 1 substep per 1 ms.
  const fs::path definition = config / "models/catheter_cbd.toml";
  const auto edit = [&](const std::string& from, const std::string& to) {
    std::stringstream text;
    text << std::ifstream(definition).rdbuf();
    std::string edited = text.str();
    ASSERT_NE(edited.find(from), std::string::npos) << from;
    edited.replace(edited.find(from), from.size(), to);
    std::ofstream(definition, std::ios::trunc) << edited;
  };
  edit("wall_stiffness_n_per_m = 500.0", "wall_stiffness_n_per_m = 1.0e5");
  const std::string command =
      "build --scene " + (config / "scenes/cbd.toml").string() + " --only catheter";
  EXPECT_EQ(run(MODELC_PATH, command), 0) << output_;
  EXPECT_NE(output_.find("largest substep 1248.08 us: 1 substeps per 1000.0 us loop period (budget 64)"),
            std::string::npos)
      << output_;
  // The bending's remainder sets the substep: 2/ω_r, ω_r² = ¼ · 20 k_b/(m l0²). EI = 0.3 N·m²
  // (7,700× the cbd catheter's) gives ω_r² = 1.98e10 s⁻², 14.23 µs, 71 per 1 ms period: beyond
  // max_substeps = 64. modelc writes the image and warns that the trainer will refuse the
  // scene at this period.
  edit("bending_stiffness_n_m2 = 3.9e-5", "bending_stiffness_n_m2 = 0.3");
  EXPECT_EQ(run(MODELC_PATH, command), 0) << output_;
  EXPECT_NE(output_.find("largest substep 14.23 us: 71 substeps per 1000.0 us loop period (budget 64)"),
            std::string::npos)
      << output_;
  EXPECT_NE(output_.find("warning: at this loop period the catheter needs more substeps than its "
                         "max_substeps"),
            std::string::npos)
      << output_;
  EXPECT_TRUE(fs::exists(directory_ / "out/models/catheter_cbd.img"));
}

// Drives two catheters through the same 1,000 periods and requires every state and output to
// be bit-identical after every step.
void expect_bit_identical_runs(Catheter& from_params, Catheter& from_image,
                               const CatheterModelData& data) {
  const std::uint32_t count = from_params.particle_count();
  const Vec3 direction = data.rest_direction;
  const Vec3 side = direction.unitOrthogonal();  // the planes' normal, towards the chain
  const Vec3 gravity_force = from_image.particle_mass_kg() * data.gravity_m_per_s2;
  const std::uint32_t middle = count / 2;
  bool touched = false;
  bool held = false;
  for (int period = 0; period < 1000; ++period) {
    // The tip is pushed towards the planes and back, a segment near the root is grasped and
    // dragged sideways from period 200 to 600, then released.
    const float phase = 0.02F * static_cast<float>(period);
    const Vec3 tip_force = 2e-3F * std::sin(phase) * side + 5e-4F * std::cos(phase) * direction;
    const ContactPlane planes[] = {
        {middle, middle, 0.0F, from_image.rest_positions_m()[middle] - 2e-3F * side, side,
         Vec3::Zero(), data.chain.radius_m, data.contact.wall_stiffness_n_per_m,
         data.contact.wall_damping_n_s_per_m, data.contact.max_contact_force_n},
        {count - 2, count - 1, 0.3F, from_image.rest_positions_m()[count - 2] - 3e-3F * side, side,
         Vec3(0.0F, 1e-3F, 0.0F), data.chain.radius_m, data.contact.tool_stiffness_n_per_m, 0.0F,
         data.contact.max_contact_force_n},
    };
    for (Catheter* catheter : {&from_params, &from_image}) {
      ASSERT_TRUE(catheter->set_contact_planes(planes).is_ok());
      catheter->clear_forces();
      for (std::uint32_t p = 0; p < count; ++p)
        ASSERT_TRUE(catheter->add_force(p, gravity_force).is_ok());
      ASSERT_TRUE(catheter->add_force(count - 1, tip_force).is_ok());
      if (period >= 200 && period < 600) {
        const Vec3 drag = 1e-5F * static_cast<float>(period - 200) * (side + direction);
        for (const std::uint32_t p : {2U, 3U})
          ASSERT_TRUE(catheter->hold(p, catheter->rest_positions_m()[p] + drag).is_ok());
      } else if (period == 600) {
        for (const std::uint32_t p : {2U, 3U}) ASSERT_TRUE(catheter->release(p).is_ok());
      }
    }
    ASSERT_EQ(from_params.step(kPeriodS).code(), from_image.step(kPeriodS).code())
        << "period " << period;
    ASSERT_TRUE(same_bits(from_params.positions_m(), from_image.positions_m()))
        << "period " << period;
    ASSERT_TRUE(same_bits(from_params.velocities_m_per_s(), from_image.velocities_m_per_s()))
        << "period " << period;
    ASSERT_TRUE(same_bits(from_params.hold_forces_n(), from_image.hold_forces_n()))
        << "period " << period;
    ASSERT_TRUE(
        same_bits(from_params.contact_plane_forces_n(), from_image.contact_plane_forces_n()))
        << "period " << period;
    for (const Vec3& force : from_image.contact_plane_forces_n())
      touched = touched || !force.isZero(0.0F);
    held = held || !from_image.hold_forces_n()[2].isZero(0.0F);
  }
  // The run exercised what it claims to: contacts engaged, the grasp pulled, the chain moved.
  EXPECT_TRUE(touched);
  EXPECT_TRUE(held);
  EXPECT_GT((from_image.positions_m()[count - 1] - from_image.rest_positions_m()[count - 1]).norm(),
            1e-4F);
}

TEST_F(CatheterDefinitionImage, TheImageCatheterStepsBitIdenticallyToTheParametersCatheter) {
  for (const char* name : {"catheter_cbd.toml", "catheter.toml"}) {
    SCOPED_TRACE(name);
    auto definition = config::load_model_definition(kRepo / "config/models" / name);
    ASSERT_TRUE(definition) << definition.error().message;
    // The definition in the runtime's precision: each double rounded once to float, as the
    // trainer does when it creates the catheter from its definition.
    const CatheterImageInputs inputs = tools::modelc::catheter_inputs_from(*definition);
    const fs::path image_path = directory_ / (std::string(name) + ".img");
    ASSERT_TRUE(write_catheter_image(image_path, inputs));
    auto image = load(image_path);
    ASSERT_TRUE(image) << image.error().message;
    const CatheterModelData data = catheter_model_data(image.value());

    CatheterSetup setup;
    setup.start_position_m = inputs.start_m;
    setup.direction = inputs.direction;
    setup.haptic_period_s = kPeriodS;
    setup.max_substeps = inputs.max_substeps;
    setup.max_contact_planes = kPlaneCapacity;
    auto from_params = Catheter::create(inputs.params, setup, arena_);
    auto from_image = Catheter::create(data, kPeriodS, kPlaneCapacity, arena_);
    ASSERT_TRUE(from_params) << from_params.error().message;
    ASSERT_TRUE(from_image) << from_image.error().message;
    EXPECT_EQ(from_params->stiffness().axial_n_per_m, from_image->stiffness().axial_n_per_m);
    EXPECT_EQ(from_params->stiffness().bending_n_m_per_rad,
              from_image->stiffness().bending_n_m_per_rad);
    EXPECT_EQ(from_params->stiffness().rest_length_m, from_image->stiffness().rest_length_m);
    EXPECT_EQ(from_params->stiffness().root_tangent, from_image->stiffness().root_tangent);
    EXPECT_EQ(from_params->stable_substep_s(), from_image->stable_substep_s());
    EXPECT_EQ(from_params->substeps_per_period(), from_image->substeps_per_period());
    EXPECT_EQ(from_params->particle_mass_kg(), from_image->particle_mass_kg());
    EXPECT_TRUE(same_bits(from_params->rest_positions_m(), from_image->rest_positions_m()));
    EXPECT_EQ(data.hold_start, inputs.hold_start);
    from_params->clamp_start(inputs.hold_start);
    from_image->clamp_start(data.hold_start);
    expect_bit_identical_runs(*from_params, *from_image, data);
  }
}

}  // namespace
}  // namespace trainer::model::offline
