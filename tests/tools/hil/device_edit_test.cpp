// The device-file line editor: a key's line edited in place (comment and alignment kept), a
// missing key added at the end of the right table, the right instrument's table, refusals; the
// edited file loads with the corrected values.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "trainer/config/device.hpp"
#include "trainer/hil/device_edit.hpp"

namespace trainer::hil {
namespace {

std::string vcan_text() {
  std::ifstream in(std::string(TRAINER_SOURCE_DIR) + "/config/devices/canopen_vcan.toml");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::size_t line_number(const std::string& text, const std::string& needle, std::size_t from = 0) {
  const std::vector<std::string> lines = lines_of(text);
  for (std::size_t i = from; i < lines.size(); ++i) {
    if (lines[i].find(needle) != std::string::npos) return i + 1;
  }
  return 0;
}

TEST(HilDeviceEdit, EditsTheKeyInPlaceKeepingItsComment) {
  const std::string text = vcan_text();
  const std::vector<Correction> corrections = {
      {"instrument.pitch", "left", "node_id", "1", "11", "node 11 answers"}};
  auto edited = apply_corrections(text, "vcan.toml", corrections);
  ASSERT_TRUE(edited) << edited.error().message;
  ASSERT_EQ(edited->changes.size(), 1U);
  const LineChange& change = edited->changes[0];
  EXPECT_EQ(change.before,
            "node_id = 1                        # CANopen node [1, 127], unique on the bus");
  EXPECT_EQ(change.after,
            "node_id = 11                       # CANopen node [1, 127], unique on the bus");
  EXPECT_EQ(change.line, line_number(text, "node_id = 1 "));
  EXPECT_EQ(change.describe("vcan.toml"),
            "vcan.toml:" + std::to_string(change.line) +
                ": [instrument.pitch] of \"left\" node_id 1 -> 11 (node 11 answers)");
  // Nothing else changed.
  const auto before = lines_of(text);
  const auto after = lines_of(edited->text);
  ASSERT_EQ(before.size(), after.size());
  for (std::size_t i = 0; i < before.size(); ++i) {
    if (i + 1 != change.line) {
      EXPECT_EQ(before[i], after[i]) << "line " << i + 1;
    }
  }
  EXPECT_EQ(edited->text.back(), '\n');
}

TEST(HilDeviceEdit, PicksTheNamedInstrumentsTableAndAddsAbsentKeys) {
  const std::string text = vcan_text();
  // The right instrument's yaw (node 7), not the left one's (node 2).
  const std::vector<Correction> corrections = {
      {"instrument.yaw", "right", "encoder_direction", "1", "-1", "moved +0.06, read -0.06"},
      {"instrument.insertion", "right", "node_id", "8", "18", "node 18 answers"}};
  auto edited = apply_corrections(text, "vcan.toml", corrections);
  ASSERT_TRUE(edited) << edited.error().message;
  ASSERT_EQ(edited->changes.size(), 2U);
  EXPECT_TRUE(edited->changes[0].inserted);
  EXPECT_EQ(edited->changes[0].after, "encoder_direction = -1");
  const std::vector<std::string> lines = lines_of(edited->text);
  const std::size_t right_yaw = line_number(edited->text, "node_id = 7");
  ASSERT_GT(right_yaw, 0U);
  EXPECT_GT(edited->changes[0].line, right_yaw) << "inside [instrument.yaw] of right";
  EXPECT_LT(edited->changes[0].line, line_number(edited->text, "[instrument.insertion]", right_yaw));
  EXPECT_EQ(lines[edited->changes[0].line - 1], "encoder_direction = -1");
  EXPECT_EQ(lines[edited->changes[1].line - 1].substr(0, 13), "node_id = 18 ");
  EXPECT_EQ(line_number(edited->text, "encoder_direction"), edited->changes[0].line)
      << "only one instrument's table got the key";

  const auto path = std::filesystem::temp_directory_path() / "hil_device_edit_test.toml";
  std::ofstream(path) << edited->text;
  auto device = config::load_device(path);
  ASSERT_TRUE(device) << device.error().message;
  const auto& right = device->instruments[1];
  EXPECT_EQ(right.joints[config::index(config::JointId::yaw)].encoder_direction, -1);
  EXPECT_EQ(device->instruments[0].joints[config::index(config::JointId::yaw)].encoder_direction, 1);
  EXPECT_EQ(right.joints[config::index(config::JointId::insertion)].canopen.node_id, 18);
  std::filesystem::remove(path);
}

TEST(HilDeviceEdit, RefusesWhatItCannotPlace) {
  const std::string text = vcan_text();
  const auto refusal = [&](std::vector<Correction> corrections) {
    auto edited = apply_corrections(text, "vcan.toml", corrections);
    return edited ? std::string("accepted") : edited.error().message;
  };
  EXPECT_EQ(refusal({{"instrument.pitch", "middle", "node_id", "1", "2", ""}}),
            "vcan.toml: [instrument.pitch] of instrument \"middle\": the file has no "
            "[[instrument]] named \"middle\": correction of node_id refused");
  EXPECT_EQ(refusal({{"instrument.wrist", "left", "node_id", "1", "2", ""}}),
            "vcan.toml: [instrument.wrist] of instrument \"left\": the file has no such table: "
            "correction of node_id refused");
  EXPECT_EQ(refusal({{"instrument.yaw", "left", "encoder_direction", "1", "-1", ""},
                     {"instrument.yaw", "left", "encoder_direction", "1", "1", ""}}),
            "vcan.toml: [instrument.yaw] of instrument \"left\": encoder_direction corrected to "
            "both -1 and 1: refused");
  const std::string multi = "[canopen]\nlist = [\n  1,\n  2]\n";
  auto edited = apply_corrections(multi, "m.toml",
                                  std::vector<Correction>{{"canopen", "", "list", "", "[3]", ""}});
  ASSERT_FALSE(edited);
  EXPECT_EQ(edited.error().message,
            "m.toml:2: list = [: a value over several lines is not edited: refused");
  // A top-level table.
  auto top = apply_corrections(text, "vcan.toml",
                               std::vector<Correction>{{"canopen", "", "digital_inputs_node", "1", "11", ""}});
  ASSERT_TRUE(top) << top.error().message;
  EXPECT_EQ(top->changes[0].after.substr(0, 26), "digital_inputs_node = 11  ");
}

}  // namespace
}  // namespace trainer::hil
