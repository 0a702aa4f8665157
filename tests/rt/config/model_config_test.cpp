// Model definition files: the repository's duct loads with its SI values, a scene names it with
// [[model]], and mistakes give their specific messages.
#include <gtest/gtest.h>

#include "config_test_files.hpp"
#include "trainer/config/model.hpp"
#include "trainer/config/scene.hpp"

namespace trainer::config {
namespace {

using testing::ConfigFileTest;
using testing::expect_contains;
using testing::read_text;
using testing::replace_first;
using testing::repo_path;

TEST(ModelDefinition, RepositoryDuctLoads) {
  auto model = load_model_definition(repo_path("config/models/duct.toml"));
  ASSERT_TRUE(model) << model.error().message;
  EXPECT_EQ(model->name, "duct");
  EXPECT_EQ(model->kind, ModelKind::modal_shell);
  EXPECT_EQ(model->mesh_source, MeshSource::tube);
  EXPECT_DOUBLE_EQ(model->tube.radius_m, 0.0043);
  EXPECT_EQ(model->tube.rings, 21);
  EXPECT_DOUBLE_EQ(model->material.young_modulus_pa, 3.0e5);
  EXPECT_EQ(model->bending, BendingKind::dkt);
  ASSERT_EQ(model->fixes.size(), 1U);
  EXPECT_EQ(model->fixes[0].node_set, "clamped");
  EXPECT_EQ(model->fixes[0].dofs, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(model->modal.mode_count, 40U);
  EXPECT_TRUE(model->modal.static_correction);
  EXPECT_TRUE(model->image_path.is_absolute());
  EXPECT_EQ(model->image_path.filename(), "duct.img");
  EXPECT_FALSE(model->material.reference.empty());
}

class ModelDefinitionErrors : public ConfigFileTest {
 protected:
  std::string message_for(std::string_view from, std::string_view to, int* line = nullptr) {
    const auto edited = replace_first(read_text(repo_path("config/models/duct.toml")), from, to);
    if (line != nullptr) *line = edited.line;
    const auto path = write("models/duct.toml", edited.text);
    auto model = load_model_definition(path);
    EXPECT_FALSE(model);
    return model ? std::string() : model.error().message;
  }
};

TEST_F(ModelDefinitionErrors, EachMistakeHasItsMessage) {
  int line = 0;
  std::string m = message_for("poisson_ratio = 0.45", "poisson_ratio = 0.5", &line);
  expect_contains(m, "duct.toml:" + std::to_string(line) + ":");
  expect_contains(m, "material.poisson_ratio = 0.5 is out of range");

  m = message_for("young_modulus_pa = 3.0e5", "young_modulus_pa = -1.0", &line);
  expect_contains(m, "material.young_modulus_pa = -1.0 is out of range");

  m = message_for("bending = \"dkt\"", "bending = \"dkq\"", &line);
  expect_contains(m, "element.bending");
  expect_contains(m, "dkq");

  m = message_for("dofs = [\"x\", \"y\", \"z\", \"rx\", \"ry\", \"rz\"]", "dofs = [\"x\", \"w\"]",
                  &line);
  expect_contains(m, "fix[0].dofs[1] = \"w\"");
  expect_contains(m, "expected one of x, y, z, rx, ry, rz");

  m = message_for("mode_count = 40", "mode_count = 0", &line);
  expect_contains(m, "modal.mode_count = 0 is out of range");

  m = message_for("segments = 16", "segmnets = 16", &line);
  expect_contains(m, "unknown key 'mesh.segmnets'");

  m = message_for("generator = \"tube\"", "generator = \"cone\"", &line);
  expect_contains(m, "mesh.generator");

  m = message_for("method = \"auto\"", "method = \"lanczos\"", &line);
  expect_contains(m, "modal.method");
  expect_contains(m, "auto, condensation, shift_invert");
}

TEST_F(ConfigFileTest, SceneListsModelsByDefinition) {
  const std::string model = read_text(repo_path("config/models/duct.toml"));
  write("models/duct.toml", model);
  std::string scene = read_text(repo_path("config/scenes/wall.toml"));
  const std::string device = read_text(repo_path("config/devices/sim.toml"));
  write("devices/sim.toml", device);
  scene = replace_first(scene, "script = \"../trajectories/wall_press.csv\"",
                        "script = \"builtin:hold\"")
              .text;
  scene += "\n[[model]]\nname = \"duct\"\ndefinition = \"../models/duct.toml\"\n";
  auto loaded = load_scene(write("scenes/scene.toml", scene));
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_EQ(loaded->models.size(), 1U);
  EXPECT_EQ(loaded->models[0].name, "duct");
  EXPECT_EQ(loaded->models[0].definition.modal.mode_count, 40U);

  // A definition with a mistake is reported under its own file name.
  write("models/duct.toml", replace_first(model, "rings = 21", "rings = 1").text);
  auto bad = load_scene(write("scenes/scene.toml", scene));
  ASSERT_FALSE(bad);
  expect_contains(bad.error().message, "duct.toml");
  expect_contains(bad.error().message, "mesh.rings = 1 is out of range");

  // Two models with one name.
  write("models/duct.toml", model);
  auto twice = load_scene(write(
      "scenes/scene.toml", scene + "\n[[model]]\nname = \"duct\"\ndefinition = \"../models/duct.toml\"\n"));
  ASSERT_FALSE(twice);
  expect_contains(twice.error().message, "expected unique model names");
}

}  // namespace
}  // namespace trainer::config
