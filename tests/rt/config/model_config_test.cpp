// Model definition files: the repository's duct and catheter load with their SI values, a scene
// names and places them with [[model]], and mistakes give their specific messages.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

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
using core::Expected;

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

TEST(ModelDefinition, RepositoryCatheterLoads) {
  auto model = load_model_definition(repo_path("config/models/catheter.toml"));
  ASSERT_TRUE(model) << model.error().message;
  EXPECT_EQ(model->name, "catheter");
  EXPECT_EQ(model->kind, ModelKind::catheter);
  EXPECT_TRUE(model->image_path.is_absolute());  // where modelc writes the chain's image
  EXPECT_EQ(model->image_path.filename(), "catheter.img");
  EXPECT_EQ(model->image_path.parent_path().filename(), "models");
  const CatheterConfig& c = model->catheter;
  EXPECT_DOUBLE_EQ(c.length_m, 0.3);
  EXPECT_DOUBLE_EQ(c.outer_radius_m, 0.0008);
  EXPECT_DOUBLE_EQ(c.bending_stiffness_n_m2, 3.9e-5);
  EXPECT_DOUBLE_EQ(c.axial_stiffness_n, 157.0);
  EXPECT_DOUBLE_EQ(c.linear_density_kg_per_m, 1.65e-3);
  EXPECT_DOUBLE_EQ(c.damping_n_s_per_m, 5.0e-4);
  EXPECT_EQ(c.particle_count, 21U);
  EXPECT_EQ(c.max_substeps, 64U);
  EXPECT_EQ(c.start_m, (Vec3{0.0, 0.03, -0.06}));
  EXPECT_EQ(c.direction, (Vec3{1.0, 0.0, 0.0}));
  EXPECT_TRUE(c.hold_start);
  EXPECT_EQ(c.gravity_m_per_s2, (Vec3{0.0, 0.0, 0.0}));
}

class CatheterDefinition : public ConfigFileTest {
 protected:
  std::string text() { return read_text(repo_path("config/models/catheter.toml")); }
  Expected<ModelDefinition> load_edited(std::string_view from, std::string_view to, int* line = nullptr) {
    const auto edited = replace_first(text(), from, to);
    if (line != nullptr) *line = edited.line;
    return load_model_definition(write("models/catheter.toml", edited.text));
  }
  std::string message_for(std::string_view from, std::string_view to, int* line = nullptr) {
    auto model = load_edited(from, to, line);
    EXPECT_FALSE(model) << "accepted: " << to;
    return model ? std::string() : model.error().message;
  }
};

TEST_F(CatheterDefinition, EachBadValueNamesFileLineKeyAndExpectation) {
  struct Case {
    const char* from;
    const char* to;
    const char* expected;
  };
  const Case cases[] = {
      {"length_m = 0.3", "length_m = 0.0",
       "catheter.length_m = 0.0 is out of range: expected more than 0 and at most 10 (metres)"},
      {"outer_radius_m = 0.0008", "outer_radius_m = 0.06",
       "catheter.outer_radius_m = 0.06 is out of range: expected more than 0 and at most 0.05"},
      {"bending_stiffness_n_m2 = 3.9e-5", "bending_stiffness_n_m2 = -3.9e-5",
       "catheter.bending_stiffness_n_m2 = -3.9e-05 is out of range"},
      {"axial_stiffness_n = 157.0", "axial_stiffness_n = 0",
       "catheter.axial_stiffness_n = 0 is out of range: expected more than 0 and at most 10000000 (EA, newtons)"},
      {"linear_density_kg_per_m = 1.65e-3", "linear_density_kg_per_m = nan",
       "catheter.linear_density_kg_per_m = nan is not a finite number"},
      {"damping_n_s_per_m = 5.0e-4", "damping_n_s_per_m = -1.0",
       "catheter.damping_n_s_per_m = -1.0 is out of range: expected 0 to 1000"},
      {"particle_count = 21", "particle_count = 2",
       "catheter.particle_count = 2 is out of range: expected 3 to 256 (particles)"},
      {"particle_count = 21", "particle_count = 21.0",
       "catheter.particle_count = 21.0 has type float: expected integer (particles)"},
      {"max_substeps = 64", "max_substeps = 0",
       "catheter.max_substeps = 0 is out of range: expected 1 to 10000"},
      {"start_m = [0.0, 0.03, -0.06]", "start_m = [0.0, 0.03]",
       "pose.start_m = [0.0, 0.03] has 2 elements: expected an array of 3 numbers (metres)"},
      {"direction = [1.0, 0.0, 0.0]", "direction = [0.0, 0.0, 0.0]",
       "pose.direction = [0.0, 0.0, 0.0] is a zero vector"},
      {"hold_start = true", "hold_start = \"yes\"",
       "pose.hold_start = \"yes\" has type string: expected boolean (true or false)"},
      {"gravity_m_per_s2 = [0.0, 0.0, 0.0]", "gravity_m_per_s2 = [0.0, 0.0, -981.0]",
       "pose.gravity_m_per_s2[2] = -981.0 is out of range: expected -100 to 100"},
      {"kind = \"catheter\"", "kind = \"cathter\"",
       "model.kind = \"cathter\": expected one of: modal_shell, catheter"},
  };
  for (const Case& c : cases) {
    int line = 0;
    const std::string m = message_for(c.from, c.to, &line);
    expect_contains(m, "catheter.toml:" + std::to_string(line) + ": ");
    expect_contains(m, c.expected);
  }
}

TEST_F(CatheterDefinition, UnknownAndMissingKeysAreRefused) {
  int line = 0;
  std::string m = message_for("length_m = 0.3", "lenght_m = 0.3", &line);
  expect_contains(m, "catheter.toml:" + std::to_string(line) + ": unknown key 'catheter.lenght_m'");
  expect_contains(m, "did you mean 'length_m'?");

  // A catheter has an image like every model (modelc writes it), but no mesh: a [mesh] table is
  // an unknown key.
  m = message_for("image = \"../../out/models/catheter.img\"", "", &line);
  expect_contains(m, "catheter.toml: missing required key 'model.image'");
  m = message_for("[pose]", "[mesh]\nrings = 3\n[pose]", &line);
  expect_contains(m, "catheter.toml:" + std::to_string(line) + ": unknown key 'mesh'");

  m = message_for("max_substeps = 64", "", &line);
  expect_contains(m, "catheter.toml: missing required key 'catheter.max_substeps' (integer");
  m = message_for("[pose]", "[placement]", &line);
  expect_contains(m, "unknown key 'placement'");
}

TEST_F(CatheterDefinition, OptionalPoseKeysDefaultAndDirectionIsNormalised) {
  std::string edited = replace_first(text(), "hold_start = true", "").text;
  edited = replace_first(edited, "gravity_m_per_s2 = [0.0, 0.0, 0.0]", "").text;
  edited = replace_first(edited, "direction = [1.0, 0.0, 0.0]", "direction = [0.0, -3.0, 4.0]").text;
  auto model = load_model_definition(write("models/catheter.toml", edited));
  ASSERT_TRUE(model) << model.error().message;
  EXPECT_TRUE(model->catheter.hold_start);
  EXPECT_EQ(model->catheter.gravity_m_per_s2, (Vec3{0.0, 0.0, 0.0}));
  EXPECT_DOUBLE_EQ(model->catheter.direction[0], 0.0);
  EXPECT_DOUBLE_EQ(model->catheter.direction[1], -0.6);
  EXPECT_DOUBLE_EQ(model->catheter.direction[2], 0.8);

  auto gravity = load_edited("gravity_m_per_s2 = [0.0, 0.0, 0.0]", "gravity_m_per_s2 = [0, 0, -9.81]");
  ASSERT_TRUE(gravity) << gravity.error().message;
  EXPECT_EQ(gravity->catheter.gravity_m_per_s2, (Vec3{0.0, 0.0, -9.81}));
  auto free_start = load_edited("hold_start = true", "hold_start = false");
  ASSERT_TRUE(free_start) << free_start.error().message;
  EXPECT_FALSE(free_start->catheter.hold_start);
}

TEST(ModelDefinition, RepositoryCatheterSceneNamesTheCatheter) {
  auto scene = load_scene(repo_path("config/scenes/catheter.toml"));
  ASSERT_TRUE(scene) << scene.error().message;
  EXPECT_EQ(scene->name, "catheter");
  ASSERT_EQ(scene->models.size(), 1U);
  EXPECT_EQ(scene->models[0].name, "catheter");
  EXPECT_EQ(scene->models[0].definition.kind, ModelKind::catheter);
  EXPECT_EQ(scene->models[0].definition.catheter.particle_count, 21U);
  EXPECT_TRUE(scene->trainee.end_run_with_script);
  // The wall scene's content is kept: one instrument, the wall.
  ASSERT_EQ(scene->objects.size(), 1U);
  EXPECT_EQ(scene->objects[0].name, "wall");
}

// ---- tet_tensor (Cotin's precomputed model) ----

TEST(ModelDefinition, RepositoryLiverLoads) {
  auto model = load_model_definition(repo_path("config/models/liver.toml"));
  ASSERT_TRUE(model) << model.error().message;
  EXPECT_EQ(model->kind, ModelKind::tet_tensor);
  EXPECT_EQ(model->mesh_source, MeshSource::box);
  EXPECT_EQ(model->box.divisions, (std::array<int, 3>{16, 12, 8}));
  EXPECT_DOUBLE_EQ(model->box.size_m[0], 0.15);
  EXPECT_DOUBLE_EQ(model->material.young_modulus_pa, 1.5e4);
  EXPECT_DOUBLE_EQ(model->material.thickness_m, 0.0);
  ASSERT_EQ(model->fixes.size(), 1U);
  EXPECT_EQ(model->fixes[0].dofs, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(model->tensor.contact_set, "surface");
  EXPECT_EQ(model->tensor.stored, TensorStorage::surface);
  EXPECT_EQ(model->tensor.max_contacts, 8U);
  EXPECT_TRUE(model->tensor.nonlinear);
  EXPECT_EQ(model->tensor.force_colinear.coefficients, (std::vector<double>{0.0, 1.0, 0.5, 0.1}));
  EXPECT_DOUBLE_EQ(model->tensor.force_colinear.max_amplitude, 5.0);
  EXPECT_DOUBLE_EQ(model->tensor.displacement_orthogonal.max_amplitude, 0.01);
  // Maps not configured stay the identity (max_amplitude 0 = not configured).
  EXPECT_DOUBLE_EQ(model->tensor.force_orthogonal.max_amplitude, 0.0);
  EXPECT_EQ(model->image_path.filename(), "liver.img");
}

class TensorDefinitionErrors : public ConfigFileTest {
 protected:
  std::string message_for(std::string_view from, std::string_view to, int* line = nullptr) {
    const auto edited = replace_first(read_text(repo_path("config/models/liver.toml")), from, to);
    if (line != nullptr) *line = edited.line;
    const auto path = write("models/liver.toml", edited.text);
    auto model = load_model_definition(path);
    EXPECT_FALSE(model);
    return model ? std::string() : model.error().message;
  }
};

TEST_F(TensorDefinitionErrors, EachMistakeHasItsMessage) {
  int line = 0;
  std::string m = message_for("divisions = [16, 12, 8]", "divisions = [16, 0, 8]", &line);
  expect_contains(m, "liver.toml:" + std::to_string(line) + ":");
  expect_contains(m, "mesh.divisions[1] = 0 is out of range");

  m = message_for("divisions = [16, 12, 8]", "divisions = [16, 12.5, 8]");
  expect_contains(m, "whole numbers of hexahedra");

  m = message_for("generator = \"box\"", "generator = \"tube\"");
  expect_contains(m, "mesh.generator");

  m = message_for("dofs = [\"x\", \"y\", \"z\"]", "dofs = [\"x\", \"rx\"]");
  expect_contains(m, "a solid node has no rotations");

  m = message_for("max_contacts = 8", "max_contacts = 65");
  expect_contains(m, "tensor.max_contacts = 65 is out of range");

  m = message_for("stored = \"surface\"", "stored = \"interior\"");
  expect_contains(m, "surface (boundary nodes) or all (every node)");

  m = message_for("coefficients = [0.0, 1.0, 0.5, 0.1]", "coefficients = [0.1, 1.0, 0.5, 0.1]", &line);
  expect_contains(m, "liver.toml:" + std::to_string(line) + ":");
  expect_contains(m, "nonlinear.force_colinear.coefficients");
  expect_contains(m, "c0 must be 0");

  m = message_for("coefficients = [0.0, 1.0, 0.5, 0.1]", "coefficients = [0.0]");
  expect_contains(m, "2 to 8 numbers");

  m = message_for("max_amplitude = 5.0", "max_amplitude = 0.0");
  expect_contains(m, "nonlinear.force_colinear.max_amplitude = 0.0 is out of range");
}

TEST_F(TensorDefinitionErrors, ShellOnlyKeysAndUnknownMapsAreRefused) {
  std::string m = message_for("density_kg_per_m3 = 1060.0",
                              "density_kg_per_m3 = 1060.0\nthickness_m = 0.001");
  expect_contains(m, "material.thickness_m");
  m = message_for("[nonlinear.force_colinear]", "[nonlinear.force_along]");
  expect_contains(m, "nonlinear.force_along");
  m = message_for("[tensor]", "[modal]");
  expect_contains(m, "modal");
}

// ---------------------------------------------------------------- model placement in a scene

// The wall scene with a second instrument and one [[model]] whose extra lines are `placement`.
class ScenePlacement : public ConfigFileTest {
 protected:
  struct Written {
    std::filesystem::path path;
    std::string text;
  };
  Written write_scene(std::string_view placement) {
    write("models/duct.toml", read_text(repo_path("config/models/duct.toml")));
    write("devices/sim.toml", read_text(repo_path("config/devices/sim.toml")));
    std::string scene = replace_first(read_text(repo_path("config/scenes/wall.toml")),
                                      "script = \"../trajectories/wall_press.csv\"",
                                      "script = \"builtin:hold\"")
                            .text;
    scene += "\n[[instrument]]\nname = \"assist\"\ndevice_instrument = \"right\"\n";
    scene += "\n[[model]]\nname = \"duct\"\ndefinition = \"../models/duct.toml\"\n";
    scene += placement;
    return {write("scenes/scene.toml", scene), scene};
  }
  // The message for a placement that must be refused, checked to start at file:line of `key`.
  std::string refused(std::string_view placement, std::string_view key) {
    const Written scene = write_scene(placement);
    auto loaded = load_scene(scene.path);
    EXPECT_FALSE(loaded) << "accepted: " << placement;
    if (loaded) return {};
    const std::size_t model_table = scene.text.find("[[model]]");
    const std::size_t key_position = scene.text.find(key, model_table);
    EXPECT_NE(key_position, std::string::npos);
    expect_contains(loaded.error().message,
                    scene.path.string() + ":" +
                        std::to_string(testing::line_at(scene.text, key_position)) + ": ");
    return loaded.error().message;
  }
};

TEST_F(ScenePlacement, DefaultsPlaceAtTheOriginForEveryInstrument) {
  auto loaded = load_scene(write_scene("").path);
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_EQ(loaded->models.size(), 1U);
  EXPECT_EQ(loaded->models[0].position_m, (Vec3{0.0, 0.0, 0.0}));
  EXPECT_EQ(loaded->models[0].rotation_deg, (Vec3{0.0, 0.0, 0.0}));
  EXPECT_EQ(loaded->models[0].touched_by, (std::vector<std::size_t>{0, 1}));
}

TEST_F(ScenePlacement, ReadsPositionRotationAndTouchedBy) {
  auto loaded = load_scene(write_scene("position_m = [0.01, -0.02, -0.08]\n"
                                       "rotation_deg = [90, -30.5, 360]\n"
                                       "touched_by = [\"assist\"]\n")
                               .path);
  ASSERT_TRUE(loaded) << loaded.error().message;
  const SceneModelConfig& model = loaded->models[0];
  EXPECT_EQ(model.position_m, (Vec3{0.01, -0.02, -0.08}));
  EXPECT_EQ(model.rotation_deg, (Vec3{90.0, -30.5, 360.0}));
  EXPECT_EQ(model.touched_by, (std::vector<std::size_t>{1}));
}

TEST_F(ScenePlacement, MistakesNameFileLineKeyAndExpectation) {
  expect_contains(refused("position_m = [0.0, 11.0, 0.0]\n", "position_m"),
                  "model[0].position_m[1] = 11.0 is out of range: expected -10 to 10 (metres)");
  expect_contains(refused("position_m = [0.0, 0.0]\n", "position_m"), "model[0].position_m");
  expect_contains(refused("rotation_deg = [0, 0, 361]\n", "rotation_deg"),
                  "model[0].rotation_deg[2] = 361 is out of range: expected -360 to 360 (degrees, "
                  "intrinsic: about x, then the turned y, then the turned z)");
  expect_contains(refused("rotation_deg = [nan, 0, 0]\n", "rotation_deg"),
                  "model[0].rotation_deg[0] = nan is not a finite number");
  expect_contains(refused("touched_by = [\"left\", \"rigth\"]\n", "touched_by"),
                  "model[0].touched_by[1] = \"rigth\": expected the name of an instrument in "
                  "this scene (left, assist)");
  expect_contains(refused("touched_by = [\"assist\", \"assist\"]\n", "touched_by"),
                  "model[0].touched_by[1] = \"assist\": expected each instrument at most once");
  expect_contains(refused("touched_by = []\n", "touched_by"),
                  "model[0].touched_by = [] has 0 elements: expected an array of 1 to 4 strings");
  expect_contains(refused("rotaton_deg = [0, 0, 90]\n", "rotaton_deg"),
                  "unknown key 'model[0].rotaton_deg' (known: name, definition, position_m, "
                  "rotation_deg, touched_by, insertion); did you mean 'rotation_deg'?");
  // [model.insertion] belongs to catheters: under the duct it is refused, naming its line.
  expect_contains(refused("[model.insertion]\nentry_m = [0, 0, 0]\ndirection = [1, 0, 0]\n"
                          "radius_m = 0.004\ntarget_depth_m = 0.01\n",
                          "[model.insertion]"),
                  "model 'duct': [model.insertion] is for catheters");
}

TEST(CatheterScene, TheCbdSceneReadsItsInsertionGoalAndContactTable) {
  auto loaded = load_scene(repo_path("config/scenes/cbd.toml"));
  ASSERT_TRUE(loaded) << loaded.error().message;
  ASSERT_EQ(loaded->models.size(), 2U);
  const SceneModelConfig& catheter = loaded->models[1];
  ASSERT_TRUE(catheter.insertion.has_value());
  EXPECT_EQ(catheter.insertion->entry_m, (Vec3{-0.02, 0.0, -0.1}));
  EXPECT_NEAR(catheter.insertion->direction[0], 0.9945, 1e-4);  // normalised
  EXPECT_DOUBLE_EQ(catheter.insertion->target_depth_m, 0.010);
  EXPECT_EQ(catheter.touched_by, (std::vector<std::size_t>{0}));
  EXPECT_DOUBLE_EQ(catheter.definition.catheter.grasp_friction, 0.6);
  EXPECT_DOUBLE_EQ(catheter.definition.catheter.tool_stiffness_n_per_m, 300.0);
  EXPECT_FALSE(catheter.definition.catheter.hold_start);
  EXPECT_FALSE(loaded->models[0].insertion.has_value());
}

}  // namespace
}  // namespace trainer::config
