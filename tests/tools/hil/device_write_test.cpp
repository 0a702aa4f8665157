// The program's --write-device / --fix path: corrections listed, every change shown and
// confirmed, the input overwritten only when confirmed, nothing written that would not load.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "trainer/config/device.hpp"
#include "trainer/hil/device_write.hpp"

namespace trainer::hil {
namespace {

class Answers final : public Operator {
 public:
  explicit Answers(std::vector<bool> answers) : answers_(std::move(answers)) {}
  bool request(std::string_view, std::string_view) override { return false; }
  bool confirm(std::string_view question) override {
    questions.emplace_back(question);
    if (next_ >= answers_.size()) return false;
    return answers_[next_++];
  }
  std::vector<std::string> questions;

 private:
  std::vector<bool> answers_;
  std::size_t next_ = 0;
};

class DeviceWriteTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("hil_write_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    input_ = (dir_ / "bench.toml").string();
    std::filesystem::copy_file(std::string(TRAINER_SOURCE_DIR) + "/config/devices/canopen_vcan.toml",
                               input_, std::filesystem::copy_options::overwrite_existing);
    original_ = read_whole_file(input_);
    CheckSection check;
    check.part = "can";
    check.corrections.push_back(
        {"instrument.yaw", "left", "encoder_direction", "1", "-1", "moved +0.06 rad, read -0.06"});
    report_.checks.push_back(check);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path dir_;
  std::string input_;
  std::string original_;
  Report report_;
  std::ostringstream out_;
  std::ostringstream err_;
};

TEST_F(DeviceWriteTest, WithoutATargetTheCorrectionsAreOnlyListed) {
  Answers op({true});
  EXPECT_TRUE(write_corrections({input_, ""}, op, report_, out_, err_));
  EXPECT_NE(out_.str().find("encoder_direction 1 -> -1"), std::string::npos) << out_.str();
  EXPECT_NE(out_.str().find("not written"), std::string::npos);
  EXPECT_TRUE(op.questions.empty());
  EXPECT_FALSE(report_.corrected_file);
}

TEST_F(DeviceWriteTest, ANewFileGetsTheCorrectedKeyAfterConfirmation) {
  const std::string target = (dir_ / "fixed.toml").string();
  Answers op({true});
  ASSERT_TRUE(write_corrections({input_, target}, op, report_, out_, err_)) << err_.str();
  ASSERT_EQ(op.questions.size(), 1U);
  EXPECT_EQ(op.questions[0], "Write 1 change(s) to " + target + "?");
  EXPECT_NE(out_.str().find("+ encoder_direction = -1"), std::string::npos) << out_.str();
  auto device = config::load_device(target);
  ASSERT_TRUE(device) << device.error().message;
  EXPECT_EQ(device->instruments[0].joints[config::index(config::JointId::yaw)].encoder_direction, -1);
  EXPECT_EQ(read_whole_file(input_), original_) << "the input is untouched";
  ASSERT_TRUE(report_.corrected_file);
  EXPECT_EQ(*report_.corrected_file, target);
  ASSERT_EQ(report_.applied_changes.size(), 1U);
}

TEST_F(DeviceWriteTest, TheInputIsOverwrittenOnlyWhenConfirmed) {
  Answers no({false});
  EXPECT_FALSE(write_corrections({input_, input_}, no, report_, out_, err_));
  EXPECT_EQ(no.questions.at(0), "Overwrite the input device file " + input_ + "?");
  EXPECT_NE(err_.str().find("not overwritten without confirmation"), std::string::npos);
  EXPECT_EQ(read_whole_file(input_), original_);
  Answers yes({true, true});
  EXPECT_TRUE(write_corrections({input_, input_}, yes, report_, out_, err_)) << err_.str();
  EXPECT_NE(read_whole_file(input_), original_);
  EXPECT_NE(read_whole_file(input_).find("encoder_direction = -1"), std::string::npos);
}

TEST_F(DeviceWriteTest, ACorrectionThatWouldNotLoadWritesNothing) {
  report_.checks[0].corrections = {{"instrument.yaw", "left", "node_id", "2", "1", "clash"}};
  const std::string target = (dir_ / "fixed.toml").string();
  Answers op({true});
  EXPECT_FALSE(write_corrections({input_, target}, op, report_, out_, err_));
  EXPECT_NE(err_.str().find("would not load, nothing written"), std::string::npos) << err_.str();
  EXPECT_FALSE(std::filesystem::exists(target));
  EXPECT_FALSE(std::filesystem::exists(target + ".hil-tmp"));
}

}  // namespace
}  // namespace trainer::hil
