// The commissioning report: JSON fields (docs/hil.md "Report"), Markdown tables, the human line,
// exit status, SHA-256 against FIPS 180-4 test vectors, the step filter.
#include <gtest/gtest.h>

#include "trainer/hil/report.hpp"
#include "trainer/hil/step_filter.hpp"

namespace trainer::hil {
namespace {

Report sample_report() {
  Report report;
  report.run.command = "check";
  report.run.arguments = "hil --device bench.toml check";
  report.run.tool_version = "0.1.0";
  report.run.git_describe = "abc1234";
  report.run.date_utc = "2026-11-27T19:00:00Z";
  report.run.host = "bench x86_64";
  report.run.device_path = "bench.toml";
  report.run.device_sha256 = sha256_hex("x");
  report.run.torque_limit_fraction = 0.05;
  ScanSection scan;
  scan.part = "can";
  scan.found.push_back({"can_node", "node 13", {{"node_id", 13}, {"vendor_id", "0x00545252"}}});
  StepResult missing;
  missing.id = "can.scan.left.insertion";
  missing.outcome = Outcome::fail;
  missing.reason = "missing: node 3 did not answer";
  scan.comparison.push_back(missing);
  scan.corrections.push_back({"instrument.insertion", "left", "node_id", "3", "13", "node 13 answers"});
  report.scans.push_back(scan);
  CheckSection check;
  check.part = "can";
  check.bench.push_back({"can_node", "node 1 (left.pitch)", {{"serial_number", "0x00000001"}}});
  StepResult pass;
  pass.id = "can.left.pitch.heartbeat_loss";
  pass.outcome = Outcome::pass;
  pass.reason = "torque off 31 ms after the last heartbeat";
  pass.figures = {{"p50", 31.25, "ms"}, {"consumer_time", 30, "ms"}};
  check.steps.push_back(pass);
  StepResult skip;
  skip.id = "can.left.pitch.encoder_direction";
  skip.outcome = Outcome::skip;
  skip.reason = "declined | by the operator";
  check.steps.push_back(skip);
  check.corrections.push_back(
      {"instrument.yaw", "left", "encoder_direction", "1", "-1", "moved +0.06 rad, read -0.06"});
  // The same correction twice (two parts saw it) is reported once.
  check.corrections.push_back(check.corrections.back());
  report.checks.push_back(check);
  return report;
}

TEST(HilReport, JsonCarriesRunStepsFiguresAndCorrections) {
  const nlohmann::json json = to_json(sample_report());
  EXPECT_EQ(json["schema_version"], kReportSchemaVersion);
  EXPECT_EQ(json["tool"]["name"], "hil");
  EXPECT_EQ(json["tool"]["git_describe"], "abc1234");
  EXPECT_EQ(json["command"], "check");
  EXPECT_EQ(json["device_file"]["path"], "bench.toml");
  EXPECT_EQ(json["device_file"]["sha256"].get<std::string>().size(), 64U);
  EXPECT_EQ(json["scans"][0]["found"][0]["properties"]["node_id"], 13);
  EXPECT_EQ(json["scans"][0]["comparison"][0]["outcome"], "fail");
  EXPECT_EQ(json["scans"][0]["corrections"][0]["new_value"], "13");
  EXPECT_EQ(json["checks"][0]["bench"][0]["properties"]["serial_number"], "0x00000001");
  const auto& step = json["checks"][0]["steps"][0];
  EXPECT_EQ(step["id"], "can.left.pitch.heartbeat_loss");
  EXPECT_EQ(step["figures"][0]["name"], "p50");
  EXPECT_DOUBLE_EQ(step["figures"][0]["value"].get<double>(), 31.25);
  EXPECT_EQ(step["figures"][0]["unit"], "ms");
  ASSERT_EQ(json["corrections"].size(), 2U) << "node_id and encoder_direction, each once";
  EXPECT_EQ(json["corrections"][1]["key"], "encoder_direction");
  EXPECT_EQ(json["summary"]["pass"], 1);
  EXPECT_EQ(json["summary"]["fail"], 1);
  EXPECT_EQ(json["summary"]["skip"], 1);
  EXPECT_EQ(json["exit_status"], 1);
  EXPECT_TRUE(json["corrected_device_file"].is_null());
}

TEST(HilReport, MarkdownHasTheTablesAndEscapesCells) {
  const std::string md = to_markdown(sample_report());
  EXPECT_NE(md.find("# Commissioning report: hil check"), std::string::npos);
  EXPECT_NE(md.find("| `can.left.pitch.heartbeat_loss` | PASS | torque off 31 ms after the last "
                    "heartbeat | p50 31.25 ms; consumer_time 30 ms |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("declined \\| by the operator"), std::string::npos);
  EXPECT_NE(md.find("| [instrument.yaw] of left | `encoder_direction` | 1 | -1 |"), std::string::npos);
  EXPECT_NE(md.find("| node 13 |"), std::string::npos);
  EXPECT_NE(md.find("| node 1 (left.pitch) | serial_number 0x00000001 |"), std::string::npos);
}

TEST(HilReport, HumanLineAndExitStatus) {
  Report report = sample_report();
  EXPECT_EQ(human_line(report.checks[0].steps[0]),
            "PASS can.left.pitch.heartbeat_loss  torque off 31 ms after the last heartbeat  "
            "[p50 31.25 ms, consumer_time 30 ms]");
  EXPECT_EQ(exit_status(report), 1);
  report.scans.clear();
  EXPECT_EQ(exit_status(report), 0) << "skips do not fail a run";
}

TEST(HilReport, Sha256MatchesTheStandardVectors) {
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(HilStepFilter, SelectsPartsAxesAndStepNames) {
  const StepFilter all;
  EXPECT_TRUE(all.wants("can.left.pitch.torque_limit"));
  const StepFilter heartbeat({"can/heartbeat_loss"});
  EXPECT_TRUE(heartbeat.wants("can.left.pitch.heartbeat_loss"));
  EXPECT_TRUE(heartbeat.wants("can.right.grip.heartbeat_loss"));
  EXPECT_FALSE(heartbeat.wants("can.left.pitch.torque_limit"));
  EXPECT_FALSE(heartbeat.wants("can.bus.sync_jitter"));
  EXPECT_TRUE(heartbeat.wants_any_under("can.left.yaw", {"torque_limit", "heartbeat_loss"}));
  const StepFilter axis({"can/left.pitch", "can/bus"});
  EXPECT_TRUE(axis.wants("can.left.pitch.motor_polarity"));
  EXPECT_FALSE(axis.wants("can.left.pitcher.motor_polarity"));
  EXPECT_FALSE(axis.wants("can.left.yaw.motor_polarity"));
  EXPECT_TRUE(axis.wants("can.bus.pdo_round_trip"));
  EXPECT_TRUE(axis.wants_part("can"));
  EXPECT_FALSE(axis.wants_part("gpio"));
  const StepFilter part({"gpio"});
  EXPECT_FALSE(part.wants("can.left.pitch.motor_polarity"));
  EXPECT_TRUE(part.wants("gpio.estop.edge_to_latch"));
}

}  // namespace
}  // namespace trainer::hil
