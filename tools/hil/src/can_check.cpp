// hil check, CAN part: per drive torque limit, encoder direction and scale, motor polarity,
// heartbeat loss; then SYNC jitter and PDO round trip on the bus. docs/hil.md lists what each
// step measures and its pass criterion.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "can_common.hpp"
#include "can_master.hpp"
#include "trainer/app/device_wiring.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/hal_canopen/emcy.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_socketcan/canopen_setup.hpp"
#include "trainer/hil/can_part.hpp"
#include "trainer/hil/operators.hpp"

namespace trainer::hil::can {

namespace co = trainer::hal::canopen;
namespace sc = trainer::hal::socketcan;

namespace {

constexpr std::int64_t kMs = 1'000'000;

StepResult make_step(const std::string& id, const std::string& title) {
  StepResult step;
  step.id = id;
  step.title = title;
  return step;
}

StepResult skipped(const std::string& id, const std::string& title, const std::string& why) {
  StepResult step = make_step(id, title);
  step.outcome = Outcome::skip;
  step.reason = why;
  return step;
}

std::string unit_of(const config::JointConfig& joint) {
  return joint.kind == hal::JointKind::prismatic ? "m" : "rad";
}
std::string effort_unit_of(const config::JointConfig& joint) {
  return joint.kind == hal::JointKind::prismatic ? "N" : "N·m";
}

// A drive's torque figures: per-mille of 0x6076 <-> joint-side effort (as CanopenDevice).
struct TorqueScale {
  double effort_per_permille = 0.0;
  std::int32_t full_permille = 0;   // the current limit
  std::int32_t small_permille = 0;  // the check's limit
};

TorqueScale torque_scale(const sc::DriveParams& drive, double fraction) {
  TorqueScale t;
  t.effort_per_permille = drive.motor_rated_torque_nm * 1e-3 * drive.scale.effort_per_amp() /
                          drive.scale.torque_constant_nm_per_a;
  t.full_permille = static_cast<std::int32_t>(
      std::floor(drive.scale.current_limit_a * drive.scale.torque_constant_nm_per_a /
                 drive.motor_rated_torque_nm * 1000.0));
  t.full_permille = std::clamp(t.full_permille, 1, 32767);
  t.small_permille = std::clamp(
      static_cast<std::int32_t>(std::floor(fraction * static_cast<double>(t.full_permille))), 1,
      t.full_permille);
  return t;
}

// NMT reset communication + boot-up, the trainer's configuration of the drive with max torque
// `max_permille`, fault reset, NMT start.
core::Expected<void> bring_up(sc::detail::SetupBus& sdo, sc::CanTransport& bus,
                              const sc::CanopenDeviceParams& params, std::size_t index,
                              std::int32_t max_permille, std::int64_t slow) {
  sc::CanopenDeviceParams one = params;
  one.drives = {params.drives[index]};
  one.boot_timeout_ns *= slow;
  if (auto booted = sc::detail::reset_and_wait_for_boot(sdo, one); !booted) return booted;
  if (auto configured = sc::detail::configure_drive(sdo, one, 0, max_permille); !configured)
    return configured;
  if (auto cleared = sc::detail::clear_drive_fault(sdo, one, 0); !cleared) return cleared;
  if (!bus.send_one(co::encode_nmt(co::NmtCommand::start, one.drives[0].node_id))) {
    return core::make_error(sc::detail::drive_who(one, 0) + ": NMT start could not be sent on " +
                            bus.name());
  }
  return {};
}

// Mean TPDO1 position over `count` cycles.
double mean_position(Master& master, std::size_t drive, std::int64_t count) {
  double sum = 0.0;
  for (std::int64_t i = 0; i < count; ++i) {
    master.cycle();
    sum += static_cast<double>(master.drives[drive].position);
  }
  return sum / static_cast<double>(count);
}

std::int64_t cycles_for(std::int64_t duration_ns, std::int64_t period_ns) {
  return std::max<std::int64_t>(1, duration_ns / period_ns);
}

struct AxisContext {
  const BenchContext& bench;
  const StepFilter& filter;
  const FileDrive& file;
  const sc::DriveParams& drive;
  TorqueScale torque;
  Master& master;
  std::string prefix;  // "can.left.pitch"
  CheckSection& out;
  int measured_encoder_sign = 0;  // relative to the file: +1 agrees, -1 reversed, 0 unknown
};

void settle_disabled(AxisContext& a, std::int64_t duration_ns) {
  a.master.drives[0].enable = false;
  a.master.drives[0].target_permille = 0;
  a.master.cycles(cycles_for(duration_ns, a.master.period_ns()));
}

bool enable_drive(AxisContext& a, std::int16_t permille) {
  MasterDrive& d = a.master.drives[0];
  d.enable = true;
  d.target_permille = permille;
  return a.master.cycle_until([&] { return operation_enabled(d.statusword); }, 1000 * kMs);
}

// What the report records of a checked drive: node, axis, identity, firmware.
ScanItem identity_of(sc::detail::SetupBus& sdo, const FileDrive& file, std::uint8_t node,
                     const std::string& bus) {
  ScanItem item;
  item.kind = "can_node";
  item.name = "node " + std::to_string(node) + " (" + file.axis + ")";
  nlohmann::json& p = item.properties;
  p["node_id"] = node;
  p["axis"] = file.axis;
  p["bus"] = bus;
  const std::string who = "node " + std::to_string(node) + " (" + file.axis + ")";
  const std::pair<std::uint8_t, const char*> fields[] = {
      {co::kIdentityVendorId, "vendor_id"},
      {co::kIdentityProductCode, "product_code"},
      {co::kIdentityRevision, "revision"},
      {co::kIdentitySerialNumber, "serial_number"}};
  for (const auto& [sub, name] : fields) {
    if (auto value = sdo.read(who, node, co::kObjectIdentity, sub)) p[name] = hex32(*value);
  }
  if (auto firmware = sdo.read_bytes(who, node, kObjectSoftwareVersion, 0, 64)) {
    std::string text(firmware->begin(), firmware->end());
    while (!text.empty() && text.back() == '\0') text.pop_back();
    p["firmware"] = text;
  }
  return item;
}

void step_torque_limit(AxisContext& a, sc::detail::SetupBus& sdo) {
  StepResult step = make_step(a.prefix + ".torque_limit", a.file.axis + ": torque limit 0x6072");
  auto read = sdo.read("node " + std::to_string(a.drive.node_id) + " (" + a.file.axis + ")",
                       a.drive.node_id, co::kObjectMaxTorque, 0);
  const double effort = a.torque.small_permille * a.torque.effort_per_permille;
  step.figures = {{"written", static_cast<double>(a.torque.small_permille), "permille"},
                  {"limit", effort, effort_unit_of(a.file.joint)},
                  {"current_limit", static_cast<double>(a.torque.full_permille), "permille"}};
  if (!read) {
    step.outcome = Outcome::fail;
    step.reason = read.error().message;
  } else {
    step.figures.push_back({"read_back", static_cast<double>(*read), "permille"});
    if (*read == static_cast<std::uint32_t>(a.torque.small_permille)) {
      step.outcome = Outcome::pass;
      step.reason = "0x6072 = " + std::to_string(*read) + " permille written and read back (" +
                    format_double(a.bench.max_torque_fraction * 100.0) + " % of the current limit)";
    } else {
      step.outcome = Outcome::fail;
      step.reason = "0x6072 read back " + std::to_string(*read) + " permille, " +
                    std::to_string(a.torque.small_permille) +
                    " written: the drive does not keep the torque limit";
    }
  }
  a.out.steps.push_back(std::move(step));
}

// The operator moves the joint positive by hand (the drive off); the counts must follow with
// the file's direction and about the file's scale.
void step_encoder(AxisContext& a) {
  const std::string id = a.prefix + ".encoder_direction";
  const std::string title = a.file.axis + ": encoder direction and scale";
  const config::JointConfig& joint = a.file.joint;
  const double move = 0.05 * (joint.max_position - joint.min_position);
  const std::string unit = unit_of(joint);
  settle_disabled(a, 100 * kMs);
  const double before = mean_position(a.master, 0, 10);
  // For --act scripts: which node and how far (docs/hil.md).
  ::setenv("HIL_NODE", std::to_string(a.drive.node_id).c_str(), 1);
  ::setenv("HIL_MOVE", format_double(move, "%.6g").c_str(), 1);
  if (a.bench.op == nullptr ||
      !a.bench.op->request(a.prefix + ".move_positive",
                           "Move " + a.file.axis + " by hand about +" + format_double(move) + " " +
                               unit + " (its positive direction) and hold it there")) {
    a.out.steps.push_back(skipped(id, title, "the operator did not move the joint (declined, or no "
                                             "terminal and no --act)"));
    return;
  }
  settle_disabled(a, 300 * kMs);
  const double after = mean_position(a.master, 0, 10);
  (void)a.bench.op->request(a.prefix + ".release", "Let go of " + a.file.axis);
  settle_disabled(a, 200 * kMs);
  const double delta_counts = after - before;
  const double measured = a.drive.scale.position_from_counts(std::llround(delta_counts));
  const double ratio = measured / move;
  StepResult step = make_step(id, title);
  step.figures = {{"moved_by_hand", move, unit},
                  {"counts", delta_counts, "counts"},
                  {"measured", measured, unit},
                  {"ratio", ratio, ""}};
  const int file_direction = joint.encoder_direction;
  if (std::fabs(ratio) < 0.2) {
    step.outcome = Outcome::fail;
    step.reason = "the counts hardly changed (" + format_double(delta_counts, "%.1f") +
                  " counts for a move of " + format_double(move) + " " + unit +
                  "): encoder not counting, or the joint did not move";
  } else if (ratio < 0.0) {
    a.measured_encoder_sign = -1;
    step.outcome = Outcome::fail;
    step.reason = "reversed: the joint moved positive, the position went " +
                  format_double(measured) + " " + unit + " (encoder_direction = " +
                  std::to_string(file_direction) + " in the file)";
    a.out.corrections.push_back(
        {"instrument." + a.file.joint_name, a.file.instrument, "encoder_direction",
         std::to_string(file_direction), std::to_string(-file_direction),
         "moving " + a.file.axis + " by +" + format_double(move) + " " + unit + " read " +
             format_double(measured) + " " + unit});
  } else if (ratio < 0.5 || ratio > 2.0) {
    a.measured_encoder_sign = 1;
    step.outcome = Outcome::fail;
    step.reason = "scale: the counts say " + format_double(measured) + " " + unit + " for about " +
                  format_double(move) + " " + unit + " (ratio " + format_double(ratio) +
                  "): check counts_per_rev and gear_ratio";
  } else {
    a.measured_encoder_sign = 1;
    step.outcome = Outcome::pass;
    step.reason = "positive move read " + format_double(measured) + " " + unit + " (" +
                  format_double(delta_counts, "%.0f") + " counts, ratio " + format_double(ratio) +
                  ")";
  }
  a.out.steps.push_back(std::move(step));
}

// A small positive joint torque with the drive enabled: the joint must move positive.
void step_motor_polarity(AxisContext& a) {
  const std::string id = a.prefix + ".motor_polarity";
  const std::string title = a.file.axis + ": motor polarity";
  if (a.bench.op != nullptr &&
      !a.bench.op->confirm("Apply a small torque (" +
                           format_double(a.bench.max_torque_fraction * 100.0) +
                           " % of the current limit) to " + a.file.axis + "?")) {
    a.out.steps.push_back(skipped(id, title, "torque not confirmed"));
    return;
  }
  MasterDrive& d = a.master.drives[0];
  if (!enable_drive(a, 0)) {
    StepResult step = make_step(id, title);
    step.outcome = Outcome::fail;
    step.reason = "the drive did not reach Operation enabled within 1 s (statusword " +
                  hex16(d.statusword) + ", " +
                  co::to_string(co::decode_statusword(d.statusword)) + ")";
    a.out.steps.push_back(std::move(step));
    settle_disabled(a, 50 * kMs);
    return;
  }
  a.master.cycles(cycles_for(50 * kMs, a.master.period_ns()));
  const double before = mean_position(a.master, 0, 10);
  // A positive JOINT torque: the file's motor_direction decides the sign on the wire.
  const auto permille = static_cast<std::int16_t>(
      std::lround(0.8 * a.torque.small_permille * a.drive.scale.motor_sign()));
  d.target_permille = permille;
  a.master.cycles(cycles_for(250 * kMs, a.master.period_ns()));
  const double after = mean_position(a.master, 0, 10);
  const bool still_enabled = operation_enabled(d.statusword);
  d.target_permille = 0;
  settle_disabled(a, 200 * kMs);
  const double delta_counts = after - before;
  const int encoder = a.measured_encoder_sign != 0 ? a.measured_encoder_sign : 1;
  const double moved = a.drive.scale.position_from_counts(std::llround(delta_counts)) * encoder;
  const std::string unit = unit_of(a.file.joint);
  StepResult step = make_step(id, title);
  step.figures = {{"torque", std::fabs(permille * a.torque.effort_per_permille),
                   effort_unit_of(a.file.joint)},
                  {"counts", delta_counts, "counts"},
                  {"moved", moved, unit}};
  const std::string encoder_note =
      a.measured_encoder_sign == -1  ? " (counts read with the encoder reversed, as measured)"
      : a.measured_encoder_sign == 0 ? " (encoder direction not measured: the file's assumed)"
                                     : "";
  const int file_direction = a.file.joint.motor_direction;
  if (!still_enabled) {
    step.outcome = Outcome::fail;
    step.reason = "the drive left Operation enabled under the test torque (statusword " +
                  std::string(co::to_string(co::decode_statusword(d.statusword))) + ")";
  } else if (std::fabs(delta_counts) < 3.0) {
    step.outcome = Outcome::fail;
    step.reason = "the joint did not move under " +
                  format_double(std::fabs(permille * a.torque.effort_per_permille)) + " " +
                  effort_unit_of(a.file.joint) +
                  " (friction or a hand holding it? raise --torque-limit)";
  } else if (moved < 0.0) {
    step.outcome = Outcome::fail;
    step.reason = "reversed: a positive torque moved the joint " + format_double(moved) + " " +
                  unit + encoder_note;
    a.out.corrections.push_back(
        {"instrument." + a.file.joint_name, a.file.instrument, "motor_direction",
         std::to_string(file_direction), std::to_string(-file_direction),
         "a positive torque on " + a.file.axis + " moved it " + format_double(moved) + " " + unit});
  } else {
    step.outcome = Outcome::pass;
    step.reason = "a positive torque moved the joint +" + format_double(moved) + " " + unit +
                  encoder_note;
  }
  a.out.steps.push_back(std::move(step));
}

// The master's heartbeat stops while the drive holds a small torque: time from the last
// heartbeat sent to the first evidence of torque off, against the drive's consumer time.
void step_heartbeat_loss(AxisContext& a, sc::detail::SetupBus& sdo, sc::CanTransport& bus,
                         const sc::CanopenDeviceParams& params, std::size_t index) {
  const std::string id = a.prefix + ".heartbeat_loss";
  const std::string title = a.file.axis + ": torque off on heartbeat loss";
  if (a.bench.op != nullptr &&
      !a.bench.op->confirm("Enable " + a.file.axis +
                           " with a small torque and stop the master's heartbeat?")) {
    a.out.steps.push_back(skipped(id, title, "torque not confirmed"));
    return;
  }
  const std::int64_t consumer_ns = params.drive_heartbeat_consumer_ns;
  const std::int64_t period = a.master.period_ns();
  const std::int64_t allowance = 2 * period + 10 * kMs;
  const int trials = a.bench.trials > 0 ? a.bench.trials : 1;
  MasterDrive& d = a.master.drives[0];
  std::vector<double> times_ms;
  std::vector<std::string> evidence_kinds;
  std::string failure;
  // A trial whose torque went off early for another reason than the heartbeat (the drive's
  // EMCY says which, e.g. 0x8250 RPDO deadline after a hiccup of this program) is disturbed:
  // counted, reported and run again, a bounded number of times.
  int disturbed = 0;
  std::vector<std::string> disturbances;
  const int max_disturbed = 3 + trials / 10;
  for (int trial = 0; trial < trials && failure.empty(); ++trial) {
    a.master.heartbeat_on = true;
    const auto small = static_cast<std::int16_t>(
        std::lround(0.5 * a.torque.small_permille * a.drive.scale.motor_sign()));
    if (!enable_drive(a, small)) {
      // The drive may want a fresh start after a loss (e.g. abort option "fault" that stays).
      a.master.torque_off();
      if (auto up = bring_up(sdo, bus, params, index, a.torque.small_permille,
                             std::max<std::int64_t>(a.bench.slow_motion, 1));
          !up) {
        failure = "trial " + std::to_string(trial + 1) + ": " + up.error().message;
        break;
      }
      d.controlword = 0;
      if (!enable_drive(a, small)) {
        failure = "trial " + std::to_string(trial + 1) +
                  ": the drive did not reach Operation enabled within 1 s (" +
                  co::to_string(co::decode_statusword(d.statusword)) + ")";
        break;
      }
    }
    // Several heartbeats with torque on, then silence.
    a.master.cycles(cycles_for(std::max<std::int64_t>(3 * params.master_heartbeat_ns, 50 * kMs), period));
    a.master.clear_events();
    a.master.heartbeat_on = false;
    // The heartbeat may be due in this very cycle: the last one is the one sent last.
    a.master.cycle();
    const std::int64_t last_heartbeat = a.master.last_heartbeat_ns();
    std::int64_t evidence_ns = 0;
    std::string kind;
    const bool off = a.master.cycle_until(
        [&] {
          if (d.emcy_code && *d.emcy_code == co::kEmcyHeartbeatError) {
            evidence_ns = d.emcy_ns;
            kind = "emcy 0x8130";
          } else if (d.tpdo_ns > last_heartbeat && !operation_enabled(d.statusword)) {
            evidence_ns = d.tpdo_ns;
            kind = std::string("statusword ") + co::to_string(co::decode_statusword(d.statusword));
          } else if (d.tpdo_ns > last_heartbeat && d.torque_permille == 0) {
            evidence_ns = d.tpdo_ns;
            kind = "torque actual 0";
          }
          return evidence_ns != 0;
        },
        consumer_ns + 20 * period + 500 * kMs);
    if (!off) {
      failure = "trial " + std::to_string(trial + 1) + ": the torque stayed on " +
                std::to_string((consumer_ns + 20 * period + 500 * kMs) / kMs) +
                " ms after the last heartbeat (consumer time " + std::to_string(consumer_ns / kMs) +
                " ms): the drive does not watch the master";
      break;
    }
    const bool other_cause = d.emcy_code && *d.emcy_code != co::kEmcyHeartbeatError &&
                             evidence_ns - last_heartbeat < consumer_ns - period;
    if (other_cause && disturbed < max_disturbed) {
      ++disturbed;
      disturbances.push_back("EMCY " + hex16(*d.emcy_code) +
                             " (" + co::describe_emcy_code(*d.emcy_code) + ") after " +
                             format_double(static_cast<double>(evidence_ns - last_heartbeat) / 1e6) + " ms");
      --trial;
      a.master.heartbeat_on = true;
      settle_disabled(a, 100 * kMs);
      continue;
    }
    times_ms.push_back(static_cast<double>(evidence_ns - last_heartbeat) / 1e6);
    evidence_kinds.push_back(other_cause ? kind + " (EMCY " + hex16(*d.emcy_code) + ")"
                                         : kind);
    // Back to a quiet drive for the next trial (heartbeat on again, torque off).
    a.master.heartbeat_on = true;
    settle_disabled(a, 100 * kMs);
  }
  a.master.heartbeat_on = true;
  settle_disabled(a, 50 * kMs);
  StepResult step = make_step(id, title);
  const double consumer_ms = static_cast<double>(consumer_ns) / 1e6;
  const double limit_ms = static_cast<double>(consumer_ns + allowance) / 1e6;
  step.figures.push_back({"consumer_time", consumer_ms, "ms"});
  step.figures.push_back({"trials", static_cast<double>(times_ms.size()), ""});
  step.figures.push_back({"disturbed", static_cast<double>(disturbed), ""});
  step.details["disturbed"] = disturbances;
  if (!times_ms.empty()) {
    step.figures.push_back({"p50", percentile(times_ms, 50), "ms"});
    step.figures.push_back({"p90", percentile(times_ms, 90), "ms"});
    step.figures.push_back({"p99", percentile(times_ms, 99), "ms"});
    step.figures.push_back({"max", percentile(times_ms, 100), "ms"});
    step.figures.push_back({"min", *std::min_element(times_ms.begin(), times_ms.end()), "ms"});
  }
  step.details["torque_off_ms"] = times_ms;
  step.details["evidence"] = evidence_kinds;
  step.details["allowed_ms"] = limit_ms;
  const double worst = times_ms.empty() ? 0.0 : percentile(times_ms, 100);
  const double earliest = times_ms.empty() ? 0.0 : *std::min_element(times_ms.begin(), times_ms.end());
  if (!failure.empty()) {
    step.outcome = Outcome::fail;
    step.reason = failure;
  } else if (worst > limit_ms) {
    step.outcome = Outcome::fail;
    step.reason = "torque off after up to " + format_double(worst) + " ms, more than the consumer time " +
                  format_double(consumer_ms) + " ms + " + format_double(static_cast<double>(allowance) / 1e6) +
                  " ms (two SYNC periods + 10 ms)";
  } else if (earliest < consumer_ms - static_cast<double>(period) / 1e6) {
    step.outcome = Outcome::fail;
    step.reason = "torque off already after " + format_double(earliest) +
                  " ms, before the consumer time " + format_double(consumer_ms) +
                  " ms: something else than the heartbeat loss removed it";
  } else {
    step.outcome = Outcome::pass;
    step.reason = "torque off " + format_double(percentile(times_ms, 50)) + " ms (median of " +
                  std::to_string(times_ms.size()) + ", max " + format_double(worst) +
                  ") after the last heartbeat; consumer time " + format_double(consumer_ms) +
                  " ms (" + evidence_kinds.front() + ")";
  }
  a.out.steps.push_back(std::move(step));
}

void bus_statistics(const BenchContext& bench, const StepFilter& filter, sc::detail::SetupBus& sdo,
                    sc::CanTransport& bus, const sc::CanopenDeviceParams& params,
                    const std::vector<FileDrive>& drives, const CanOptions& options,
                    CheckSection& out) {
  const bool want_jitter = filter.wants("can.bus.sync_jitter");
  const bool want_round_trip = filter.wants("can.bus.pdo_round_trip");
  if (!want_jitter && !want_round_trip) return;
  const std::int64_t slow = std::max<std::int64_t>(bench.slow_motion, 1);
  Master master(bus, slow, params.sync_period_ns, params.master_node_id, params.master_heartbeat_ns);
  std::string setup_error;
  for (std::size_t i = 0; i < drives.size() && setup_error.empty(); ++i) {
    const TorqueScale torque = torque_scale(params.drives[drives[i].channel], bench.max_torque_fraction);
    if (auto up = bring_up(sdo, bus, params, drives[i].channel, torque.small_permille, slow); !up) {
      setup_error = up.error().message;
    }
    MasterDrive drive;
    drive.node = drives[i].config.node_id;
    drive.who = drives[i].axis;
    master.drives.push_back(drive);
  }
  const auto fail_all = [&](const std::string& why) {
    for (const char* name : {"sync_jitter", "pdo_round_trip"}) {
      if (!filter.wants(std::string("can.bus.") + name)) continue;
      StepResult step = make_step(std::string("can.bus.") + name, std::string("bus: ") + name);
      step.outcome = Outcome::fail;
      step.reason = why;
      out.steps.push_back(std::move(step));
    }
  };
  if (!setup_error.empty()) {
    fail_all(setup_error);
    return;
  }
  master.cycles(cycles_for(100 * kMs, master.period_ns()));  // first TPDOs in
  master.record = true;
  master.cycles(options.jitter_syncs);
  master.record = false;
  master.torque_off();
  const BusRecord& r = master.recorded;
  const double period_ms = static_cast<double>(master.period_ns()) / 1e6;
  const auto ms = [](std::vector<double> values) {
    for (double& v : values) v /= 1e6;
    return values;
  };
  if (want_jitter) {
    const std::vector<double> jitter = ms(r.sync_interval_error_ns);
    StepResult step = make_step("can.bus.sync_jitter", "bus: SYNC period jitter");
    const double p99 = percentile(jitter, 99);
    step.figures = {{"period", period_ms, "ms"},
                    {"syncs", static_cast<double>(r.syncs), ""},
                    {"p50", percentile(jitter, 50), "ms"},
                    {"p99", p99, "ms"},
                    {"max", percentile(jitter, 100), "ms"}};
    step.details["criterion"] = "p99 of |SYNC interval - period| <= 25 % of the period";
    step.details["interval_error_ms"] = jitter;
    if (p99 <= 0.25 * period_ms) {
      step.outcome = Outcome::pass;
      step.reason = "SYNC interval within " + format_double(p99) + " ms of " +
                    format_double(period_ms) + " ms (p99 of " + std::to_string(r.syncs) + ")";
    } else {
      step.outcome = Outcome::fail;
      step.reason = "SYNC interval off by " + format_double(p99) + " ms (p99) at a " +
                    format_double(period_ms) + " ms period: more than 25 %";
    }
    out.steps.push_back(std::move(step));
  }
  if (want_round_trip) {
    const std::vector<double> trip = ms(r.round_trip_ns);
    StepResult step = make_step("can.bus.pdo_round_trip", "bus: SYNC to TPDO1 round trip");
    const double p99 = percentile(trip, 99);
    step.figures = {{"drives", static_cast<double>(master.drives.size()), ""},
                    {"samples", static_cast<double>(trip.size()), ""},
                    {"missing", static_cast<double>(r.missing_tpdos), ""},
                    {"p50", percentile(trip, 50), "ms"},
                    {"p99", p99, "ms"},
                    {"max", percentile(trip, 100), "ms"}};
    step.details["criterion"] =
        "TPDO1 answers its SYNC within the period (p99), at most 1 % of the answers missing";
    step.details["round_trip_ms"] = trip;
    if (trip.empty()) {
      step.outcome = Outcome::fail;
      step.reason = "no TPDO1 came back";
    } else if (p99 < period_ms && static_cast<double>(r.missing_tpdos) <=
                                      0.01 * static_cast<double>(r.syncs * master.drives.size())) {
      step.outcome = Outcome::pass;
      step.reason = "TPDO1 " + format_double(percentile(trip, 50)) + " ms after the SYNC (p50; p99 " +
                    format_double(p99) + " ms < period " + format_double(period_ms) + " ms)";
    } else {
      step.outcome = Outcome::fail;
      step.reason = "TPDO1 p99 " + format_double(p99) + " ms against a " + format_double(period_ms) +
                    " ms period, " + std::to_string(r.missing_tpdos) + " missing";
    }
    out.steps.push_back(std::move(step));
  }
}

}  // namespace

CheckSection check(const BenchContext& context, sc::CanTransport& bus, const StepFilter& filter,
                   const CanOptions& options) {
  CheckSection section;
  section.part = "can";
  if (!context.device || context.device->backend != "canopen") {
    section.steps.push_back(skipped("can.setup", "CAN checks",
                                    "no CANopen device file (--device with backend \"canopen\")"));
    return section;
  }
  const config::DeviceConfig& device = *context.device;
  const std::int64_t slow = std::max<std::int64_t>(context.slow_motion, 1);
  config::SceneConfig scene;
  scene.device = device;
  scene.loop.period_ns = device.canopen.sync_period_ns > 0 ? device.canopen.sync_period_ns : options.period_ns;
  const sc::CanopenDeviceParams params = app::canopen_params_from(scene);
  sc::detail::SetupBus sdo(bus, bus.name(), params.sdo_timeout_ns * slow);
  const std::vector<FileDrive> drives = file_drives(device);
  for (const FileDrive& file : drives) {
    const std::string prefix = "can." + file.axis;
    if (!filter.wants_any_under(prefix, {"setup", "torque_limit", "encoder_direction", "motor_polarity", "heartbeat_loss"})) continue;
    const sc::DriveParams& drive = params.drives[file.channel];
    const TorqueScale torque = torque_scale(drive, context.max_torque_fraction);
    Master master(bus, slow, params.sync_period_ns, params.master_node_id, params.master_heartbeat_ns);
    MasterDrive md;
    md.node = drive.node_id;
    md.who = file.axis;
    md.scale = drive.scale;
    master.drives.push_back(md);
    AxisContext axis{context, filter, file, drive, torque, master, prefix, section};
    if (auto up = bring_up(sdo, bus, params, file.channel, torque.small_permille, slow); !up) {
      StepResult step = make_step(prefix + ".setup", file.axis + ": configure the drive");
      step.outcome = Outcome::fail;
      step.reason = up.error().message;
      section.steps.push_back(std::move(step));
      for (const char* name : {"torque_limit", "encoder_direction", "motor_polarity", "heartbeat_loss"}) {
        if (filter.wants(prefix + "." + name))
          section.steps.push_back(skipped(prefix + "." + name, file.axis + ": " + name,
                                          "the drive could not be configured (" + prefix + ".setup)"));
      }
      master.torque_off();
      continue;
    }
    section.bench.push_back(identity_of(sdo, file, drive.node_id, bus.name()));
    if (filter.wants(prefix + ".torque_limit")) step_torque_limit(axis, sdo);
    settle_disabled(axis, 100 * kMs);
    if (filter.wants(prefix + ".encoder_direction")) step_encoder(axis);
    if (filter.wants(prefix + ".motor_polarity")) step_motor_polarity(axis);
    if (filter.wants(prefix + ".heartbeat_loss")) step_heartbeat_loss(axis, sdo, bus, params, file.channel);
    master.torque_off();
  }
  bus_statistics(context, filter, sdo, bus, params, drives, options, section);
  return section;
}

}  // namespace trainer::hil::can
