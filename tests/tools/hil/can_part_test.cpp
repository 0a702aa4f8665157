// The CAN part of hil against the simulated drives of config/devices/canopen_vcan.toml on a
// socketpair, the drives polled in their own thread: a good bench passes; a reversed encoder
// fails encoder_direction with the encoder_direction correction (and motor_polarity still
// passes, read through the measured encoder); a drive answering under another node id makes scan
// report the missing and the extra node and propose the node_id correction; heartbeat loss is
// timed against the consumer time; an interruption while torque is on leaves the drive without
// torque.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <thread>

#include "simdrive_setup.hpp"
#include "trainer/hal_simdrive/sim_drive_bus.hpp"
#include "trainer/hil/can_part.hpp"
#include "trainer/hil/operators.hpp"
#include "trainer_master_support.hpp"

namespace trainer::hil {
namespace {

namespace sd = trainer::hal::simdrive;
namespace sc = trainer::hal::socketcan;
using sd::test_support::monotonic_now;

// The operator of the bench VM's --act script, in process: a joint moved by hand is simdrive's
// push fault on the node hil names in HIL_NODE by HIL_MOVE; releasing it clears the push.
class SimHand final : public Operator {
 public:
  explicit SimHand(sd::SimDriveBus& bus) : bus_(bus) {}
  bool request(std::string_view action, std::string_view /*instruction*/) override {
    actions.emplace_back(action);
    const std::string node = std::getenv("HIL_NODE") != nullptr ? std::getenv("HIL_NODE") : "0";
    std::string spec;
    if (action.ends_with(".move_positive")) {
      spec = "push:node=" + node + ",move=" + std::getenv("HIL_MOVE");
    } else if (action.ends_with(".release")) {
      spec = "clear:node=" + node;
    } else {
      return false;
    }
    auto parsed = sd::parse_fault_spec(spec);
    EXPECT_TRUE(parsed) << spec;
    return parsed && bus_.post(*parsed);
  }
  bool confirm(std::string_view question) override {
    questions.emplace_back(question);
    if (on_confirm) on_confirm(question);
    return true;
  }
  std::vector<std::string> actions;
  std::vector<std::string> questions;
  std::function<void(std::string_view)> on_confirm;

 private:
  sd::SimDriveBus& bus_;
};

class SimBench {
 public:
  explicit SimBench(const tools::simdrive::Miswiring& miswiring = {})
      : device_(sd::test_support::vcan_device()) {
    auto pair = sc::make_transport_pair("hil", "simdrive");
    EXPECT_TRUE(pair);
    auto params = tools::simdrive::bus_params_from(device_, "builtin:hold",
                                                   sd::test_support::kLoopPeriodNs);
    EXPECT_TRUE(params) << (params ? "" : params.error().message);
    EXPECT_TRUE(tools::simdrive::apply_miswiring(miswiring, *params));
    auto bus = sd::SimDriveBus::create(std::move(*params), std::move(pair->b));
    EXPECT_TRUE(bus) << (bus ? "" : bus.error().message);
    bus_ = std::move(*bus);
    master_ = std::make_unique<sc::CanTransport>(std::move(pair->a));
    hand_ = std::make_unique<SimHand>(*bus_);
    bus_->power_on(monotonic_now());
    thread_ = std::thread([this] {
      while (!stop_.load(std::memory_order_acquire)) {
        const std::int64_t now = monotonic_now();
        const std::int64_t deadline = bus_->poll(now);
        (void)bus_->transport().wait_readable(std::clamp<std::int64_t>(deadline - now, 0, 1'000'000));
      }
    });
  }
  ~SimBench() { stop(); }
  void stop() {
    stop_.store(true, std::memory_order_release);
    if (thread_.joinable()) thread_.join();
  }

  BenchContext context(int trials = 0) {
    BenchContext context;
    context.device = device_;
    context.op = hand_.get();
    context.trials = trials;
    return context;
  }
  sc::CanTransport& master() { return *master_; }
  sd::SimDriveBus& bus() { return *bus_; }  // after stop()
  SimHand& hand() { return *hand_; }
  config::DeviceConfig& device() { return device_; }

 private:
  config::DeviceConfig device_;
  std::unique_ptr<sd::SimDriveBus> bus_;
  std::unique_ptr<sc::CanTransport> master_;
  std::unique_ptr<SimHand> hand_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
};

can::CanOptions quick() {
  can::CanOptions options;
  options.listen_ns = 20'000'000;
  options.jitter_syncs = 100;
  return options;
}

const StepResult* find(const std::vector<StepResult>& steps, const std::string& id) {
  for (const StepResult& step : steps) {
    if (step.id == id) return &step;
  }
  return nullptr;
}

// The outcome of step `id` (skip, with a failure, when it is not there).
Outcome outcome(const std::vector<StepResult>& steps, const std::string& id) {
  const StepResult* step = find(steps, id);
  if (step == nullptr) {
    ADD_FAILURE() << "no step " << id;
    return Outcome::skip;
  }
  return step->outcome;
}

double figure(const StepResult& step, const std::string& name) {
  for (const Figure& f : step.figures) {
    if (f.name == name) return f.value;
  }
  ADD_FAILURE() << step.id << " has no figure " << name;
  return 0.0;
}

std::string dump(const std::vector<StepResult>& steps) {
  std::string out;
  for (const StepResult& step : steps) out += step.id + " " + std::string(to_string(step.outcome)) + ": " + step.reason + "\n";
  return out;
}

TEST(HilCan, ScanOfAGoodBenchFindsEveryDriveWithItsIdentity) {
  SimBench bench;
  const ScanSection scan = can::scan(bench.context(), bench.master(), quick());
  ASSERT_EQ(scan.found.size(), 10U);
  EXPECT_EQ(scan.found[2].properties["node_id"], 3);
  EXPECT_EQ(scan.found[2].properties["vendor_id"], "0x00545252");
  EXPECT_EQ(scan.found[2].properties["device_type"], "0x00020192");
  EXPECT_EQ(scan.found[2].properties["serial_number"], "0x00000003");
  EXPECT_EQ(scan.found[2].properties["firmware"], "simdrive 1.0");
  ASSERT_EQ(scan.comparison.size(), 10U) << dump(scan.comparison);
  for (const StepResult& step : scan.comparison) EXPECT_EQ(step.outcome, Outcome::pass) << dump(scan.comparison);
  EXPECT_TRUE(scan.corrections.empty());
}

TEST(HilCan, ScanOfADriveUnderAnotherNodeIdProposesTheNodeIdCorrection) {
  tools::simdrive::Miswiring miswiring;
  ASSERT_TRUE(tools::simdrive::parse_node_id_map("3=13", miswiring));
  SimBench bench(miswiring);
  const ScanSection scan = can::scan(bench.context(), bench.master(), quick());
  const StepResult* missing = find(scan.comparison, "can.scan.left.insertion");
  ASSERT_NE(missing, nullptr) << dump(scan.comparison);
  EXPECT_EQ(missing->outcome, Outcome::fail);
  EXPECT_EQ(missing->reason.substr(0, 16), "missing: node 3 ");
  const StepResult* extra = find(scan.comparison, "can.scan.extra.node13");
  ASSERT_NE(extra, nullptr) << dump(scan.comparison);
  EXPECT_EQ(extra->outcome, Outcome::fail);
  ASSERT_EQ(scan.corrections.size(), 1U);
  const Correction& c = scan.corrections[0];
  EXPECT_EQ(c.table, "instrument.insertion");
  EXPECT_EQ(c.instrument, "left");
  EXPECT_EQ(c.key, "node_id");
  EXPECT_EQ(c.old_value, "3");
  EXPECT_EQ(c.new_value, "13");
  EXPECT_EQ(std::count_if(scan.comparison.begin(), scan.comparison.end(),
                          [](const StepResult& s) { return s.outcome == Outcome::pass; }),
            9);
}

TEST(HilCan, CheckOfAGoodAxisPassesEveryStepAndTheBusStatistics) {
  SimBench bench;
  const StepFilter filter({"can/left.pitch", "can/bus"});
  const CheckSection check = can::check(bench.context(), bench.master(), filter, quick());
  for (const char* id : {"can.left.pitch.torque_limit", "can.left.pitch.encoder_direction",
                         "can.left.pitch.motor_polarity", "can.left.pitch.heartbeat_loss"}) {
    const StepResult* step = find(check.steps, id);
    ASSERT_NE(step, nullptr) << id << "\n" << dump(check.steps);
    EXPECT_EQ(step->outcome, Outcome::pass) << dump(check.steps);
  }
  // The bus statistics are measured (their pass criterion, a SYNC interval within 25 % of the
  // period, is for a bench: a shared 2-core CI machine descheduling either thread may miss it).
  const StepResult* jitter = find(check.steps, "can.bus.sync_jitter");
  const StepResult* trip = find(check.steps, "can.bus.pdo_round_trip");
  ASSERT_TRUE(jitter != nullptr && trip != nullptr) << dump(check.steps);
  EXPECT_NE(jitter->outcome, Outcome::skip);
  EXPECT_EQ(figure(*jitter, "syncs"), 100.0);
  EXPECT_EQ(figure(*trip, "drives"), 10.0);
  EXPECT_GT(figure(*trip, "samples"), 500.0);
  EXPECT_GT(figure(*trip, "p50"), 0.0);
  EXPECT_LT(figure(*trip, "p50"), 4.0);
  EXPECT_EQ(check.steps.size(), 6U) << dump(check.steps);
  ASSERT_EQ(check.bench.size(), 1U) << "the identity of the drive checked";
  EXPECT_EQ(check.bench[0].name, "node 1 (left.pitch)");
  EXPECT_EQ(check.bench[0].properties["serial_number"], "0x00000001");
  EXPECT_EQ(check.bench[0].properties["firmware"], "simdrive 1.0");
  EXPECT_TRUE(check.corrections.empty());
  // 5 % of 3 A * 0.03 N·m/A / 0.060 N·m = 75 permille.
  const StepResult* limit = find(check.steps, "can.left.pitch.torque_limit");
  const StepResult* encoder = find(check.steps, "can.left.pitch.encoder_direction");
  ASSERT_TRUE(limit != nullptr && encoder != nullptr);
  EXPECT_EQ(figure(*limit, "read_back"), 75.0);
  const double ratio = figure(*encoder, "ratio");
  EXPECT_GT(ratio, 0.7);
  EXPECT_LT(ratio, 1.3);
  EXPECT_EQ(bench.hand().actions,
            (std::vector<std::string>{"can.left.pitch.move_positive", "can.left.pitch.release"}));
  const StepResult* loss = find(check.steps, "can.left.pitch.heartbeat_loss");
  ASSERT_NE(loss, nullptr);
  EXPECT_GE(figure(*loss, "max"), 195.0) << "the widened consumer time is 200 ms";
  EXPECT_LE(figure(*loss, "max"), 200.0 + 18.0);
  bench.stop();
  // Never left with torque: every drive pre-operational and off.
  for (std::size_t i = 0; i < bench.bus().node_count(); ++i) {
    EXPECT_NE(bench.bus().node(i).power_state(), hal::canopen::PowerState::operation_enabled);
  }
}

TEST(HilCan, AReversedEncoderFailsWithTheEncoderDirectionCorrection) {
  tools::simdrive::Miswiring miswiring;
  ASSERT_TRUE(tools::simdrive::parse_miswire("reverse_encoder:node=2", miswiring));
  SimBench bench(miswiring);
  const StepFilter filter({"can/left.yaw.encoder_direction", "can/left.yaw.motor_polarity"});
  const CheckSection check = can::check(bench.context(), bench.master(), filter, quick());
  const StepResult* encoder = find(check.steps, "can.left.yaw.encoder_direction");
  ASSERT_NE(encoder, nullptr) << dump(check.steps);
  EXPECT_EQ(encoder->outcome, Outcome::fail);
  EXPECT_EQ(encoder->reason.substr(0, 9), "reversed:");
  EXPECT_LT(figure(*encoder, "ratio"), -0.7);
  const StepResult* polarity = find(check.steps, "can.left.yaw.motor_polarity");
  ASSERT_NE(polarity, nullptr);
  EXPECT_EQ(polarity->outcome, Outcome::pass) << polarity->reason;
  ASSERT_EQ(check.corrections.size(), 1U);
  EXPECT_EQ(check.corrections[0].table, "instrument.yaw");
  EXPECT_EQ(check.corrections[0].instrument, "left");
  EXPECT_EQ(check.corrections[0].key, "encoder_direction");
  EXPECT_EQ(check.corrections[0].old_value, "1");
  EXPECT_EQ(check.corrections[0].new_value, "-1");
}

TEST(HilCan, TheCorrectedFileMakesTheReversedEncoderPass) {
  tools::simdrive::Miswiring miswiring;
  ASSERT_TRUE(tools::simdrive::parse_miswire("reverse_encoder:node=2", miswiring));
  ASSERT_TRUE(tools::simdrive::parse_miswire("reverse_motor:node=2", miswiring));
  SimBench bench(miswiring);
  auto& yaw = bench.device().instruments[0].joints[config::index(config::JointId::yaw)];
  yaw.encoder_direction = -1;  // as hil would have written it
  const StepFilter filter({"can/left.yaw.encoder_direction", "can/left.yaw.motor_polarity"});
  CheckSection check = can::check(bench.context(), bench.master(), filter, quick());
  EXPECT_EQ(outcome(check.steps, "can.left.yaw.encoder_direction"), Outcome::pass)
      << dump(check.steps);
  EXPECT_EQ(outcome(check.steps, "can.left.yaw.motor_polarity"), Outcome::fail)
      << "the motor is reversed too";
  ASSERT_EQ(check.corrections.size(), 1U);
  EXPECT_EQ(check.corrections[0].key, "motor_direction");
  EXPECT_EQ(check.corrections[0].new_value, "-1");
  yaw.motor_direction = -1;
  check = can::check(bench.context(), bench.master(), filter, quick());
  EXPECT_EQ(outcome(check.steps, "can.left.yaw.motor_polarity"), Outcome::pass)
      << dump(check.steps);
}

TEST(HilCan, HeartbeatLossIsTimedOverTrials) {
  SimBench bench;
  bench.device().canopen.drive_heartbeat_consumer_ns = 60'000'000;
  const StepFilter filter({"can/left.roll.heartbeat_loss"});
  const CheckSection check = can::check(bench.context(5), bench.master(), filter, quick());
  ASSERT_EQ(check.steps.size(), 1U) << dump(check.steps);
  const StepResult& loss = check.steps[0];
  EXPECT_EQ(loss.outcome, Outcome::pass) << loss.reason;
  EXPECT_EQ(figure(loss, "trials"), 5.0);
  EXPECT_EQ(figure(loss, "disturbed"), 0.0);
  EXPECT_EQ(figure(loss, "consumer_time"), 60.0);
  EXPECT_GE(figure(loss, "min"), 56.0);
  EXPECT_LE(figure(loss, "max"), 60.0 + 18.0);
  EXPECT_EQ(loss.details["torque_off_ms"].size(), 5U);
  EXPECT_EQ(loss.details["evidence"][0], "emcy 0x8130");
}

TEST(HilCan, AnInterruptionWithTorqueOnLeavesTheDriveWithoutTorque) {
  SimBench bench;
  std::thread interrupter;
  bench.hand().on_confirm = [&](std::string_view question) {
    if (question.find("small torque") == std::string_view::npos) return;
    // The polarity step holds its torque from about 150 to 450 ms after this question.
    interrupter = std::thread([] {
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      set_interrupted(true);
    });
  };
  const StepFilter filter({"can/left.pitch.motor_polarity"});
  EXPECT_THROW((void)can::check(bench.context(), bench.master(), filter, quick()), Interrupted);
  const std::int64_t thrown = monotonic_now();
  interrupter.join();
  set_interrupted(false);
  // Well before the drive's own deadlines (200 ms) could have removed the torque.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  bench.stop();
  EXPECT_LT(monotonic_now() - thrown, 150'000'000);
  EXPECT_NE(bench.bus().node(0).power_state(), hal::canopen::PowerState::operation_enabled);
  EXPECT_EQ(bench.bus().node(0).nmt_state(), hal::canopen::NmtState::pre_operational);
  EXPECT_EQ(bench.bus().plant().applied_effort(0), 0.0);
}

}  // namespace
}  // namespace trainer::hil
