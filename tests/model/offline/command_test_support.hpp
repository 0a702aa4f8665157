// Fixture for tests that run a real command-line tool (modelc) and read its JSON report: a
// per-test temporary directory, the run with its combined output captured, the report parsed.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

namespace trainer::model::offline::testing {

class CommandTest : public ::testing::Test {
 protected:
  void SetUp() override {
    directory_ = std::filesystem::temp_directory_path() /
                 ("command_test_" + std::to_string(::getpid()) + "_" +
                  ::testing::UnitTest::GetInstance()->current_test_info()->test_suite_name() +
                  "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(directory_);
  }
  void TearDown() override { std::filesystem::remove_all(directory_); }

  // Runs `program arguments`; returns its exit status, stdout+stderr in `output_`.
  int run(const std::string& program, const std::string& arguments) {
    const std::filesystem::path log = directory_ / "output.txt";
    const std::string command = program + " " + arguments + " > " + log.string() + " 2>&1";
    const int status = std::system(command.c_str());
    std::ifstream file(log);
    std::ostringstream text;
    text << file.rdbuf();
    output_ = text.str();
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  nlohmann::json report() const {
    std::ifstream file(report_path());
    return nlohmann::json::parse(file);
  }
  std::string report_path() const { return (directory_ / "report.json").string(); }

  std::filesystem::path directory_;
  std::string output_;
};

}  // namespace trainer::model::offline::testing
