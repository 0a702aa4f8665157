// hil scan, CAN part: listen, probe, read the identities, compare with the device file.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <map>
#include <set>

#include "can_common.hpp"
#include "trainer/hal_canopen/frame.hpp"
#include "trainer/hal_canopen/heartbeat.hpp"
#include "trainer/hal_canopen/nmt.hpp"
#include "trainer/hal_canopen/objects.hpp"
#include "trainer/hal_socketcan/canopen_setup.hpp"
#include "trainer/hil/can_part.hpp"
#include "trainer/hil/operators.hpp"
#include "trainer/hil/report.hpp"

namespace trainer::hil::can {

namespace co = trainer::hal::canopen;
namespace sc = trainer::hal::socketcan;

namespace {

struct FoundNode {
  std::uint8_t node = 0;
  std::optional<std::string> heard;  // NMT state of a boot-up / heartbeat heard
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor, product, revision, serial;
  std::optional<std::uint32_t> error_register;
  std::optional<std::string> firmware;
  std::vector<std::string> problems;  // SDO reads that failed
};

bool same_identity(const FoundNode& found, const FileDrive& drive) {
  return found.vendor == drive.config.vendor_id && found.product == drive.config.product_code &&
         (!drive.config.revision || found.revision == *drive.config.revision);
}

std::string identity_text(const FoundNode& found) {
  const auto field = [](const std::optional<std::uint32_t>& value) {
    return value ? hex32(*value) : std::string("?");
  };
  return "vendor " + field(found.vendor) + ", product " + field(found.product) + ", revision " +
         field(found.revision) + ", serial " + field(found.serial);
}

// Listens `listen_ns` (bench) and collects boot-ups and heartbeats.
void listen(sc::CanTransport& bus, std::int64_t listen_real_ns, std::map<std::uint8_t, FoundNode>& nodes) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(listen_real_ns);
  std::array<can_frame, sc::kMaxFramesPerCall> frames{};
  while (std::chrono::steady_clock::now() < deadline) {
    throw_if_interrupted();
    const std::size_t count = bus.receive(frames);
    for (std::size_t i = 0; i < count; ++i) {
      const auto beat = co::decode_heartbeat(frames[i]);
      if (!beat) continue;
      FoundNode& node = nodes[beat->node_id];
      node.node = beat->node_id;
      node.heard = co::to_string(beat->state);
    }
    if (count == 0) {
      const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
                            deadline - std::chrono::steady_clock::now())
                            .count();
      if (left > 0) (void)bus.wait_readable(std::min<std::int64_t>(left, 10'000'000));
    }
  }
}

// One SDO upload request of 0x1000 to every node id at once; the ids that answer (with data or
// an abort) within the timeout are present.
std::set<std::uint8_t> probe_all(sc::CanTransport& bus, std::int64_t timeout_real_ns,
                                 std::map<std::uint8_t, FoundNode>& heard) {
  std::set<std::uint8_t> answered;
  std::array<can_frame, sc::kMaxFramesPerCall> in{};
  const auto drain = [&] {
    const std::size_t count = bus.receive(in);
    for (std::size_t i = 0; i < count; ++i) {
      const co::FrameClass kind = co::classify(in[i]);
      if (kind.kind == co::FrameKind::sdo_response && kind.ok()) answered.insert(kind.node_id);
      if (const auto beat = co::decode_heartbeat(in[i])) {
        heard[beat->node_id].node = beat->node_id;
        heard[beat->node_id].heard = co::to_string(beat->state);
      }
    }
    return count;
  };
  for (unsigned node = 1; node <= 127; ++node) {
    // CiA 301 initiate upload request: command 0x40, index, sub-index, 4 reserved bytes.
    const std::array<std::uint8_t, 8> request = {
        0x40, static_cast<std::uint8_t>(co::kObjectDeviceType & 0xFFU),
        static_cast<std::uint8_t>(co::kObjectDeviceType >> 8), 0, 0, 0, 0, 0};
    const can_frame frame = co::make_frame(
        co::cob_id(co::FrameKind::sdo_request, static_cast<std::uint8_t>(node)), request);
    while (!bus.send_one(frame)) {  // the queue is full: let the answers come in
      (void)drain();
      (void)bus.wait_readable(1'000'000);
    }
    (void)drain();
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_real_ns);
  while (std::chrono::steady_clock::now() < deadline) {
    throw_if_interrupted();
    if (drain() == 0) (void)bus.wait_readable(2'000'000);
  }
  return answered;
}

void read_node(sc::detail::SetupBus& sdo, FoundNode& found) {
  const std::string who = "node " + std::to_string(found.node);
  const auto read = [&](std::uint16_t index, std::uint8_t sub, std::optional<std::uint32_t>& out) {
    auto value = sdo.read(who, found.node, index, sub);
    if (value) {
      out = *value;
    } else {
      found.problems.push_back(value.error().message);
    }
  };
  read(co::kObjectDeviceType, 0, found.device_type);
  read(co::kObjectIdentity, co::kIdentityVendorId, found.vendor);
  read(co::kObjectIdentity, co::kIdentityProductCode, found.product);
  read(co::kObjectIdentity, co::kIdentityRevision, found.revision);
  read(co::kObjectIdentity, co::kIdentitySerialNumber, found.serial);
  read(co::kObjectErrorRegister, 0, found.error_register);
  // 0x100A manufacturer software version: optional in CiA 301 (an abort = not there).
  auto firmware = sdo.read_bytes(who, found.node, kObjectSoftwareVersion, 0, 64);
  if (firmware) {
    std::string text(firmware->begin(), firmware->end());
    while (!text.empty() && text.back() == '\0') text.pop_back();
    found.firmware = text;
  }
}

}  // namespace

ScanSection scan(const BenchContext& context, sc::CanTransport& bus, const CanOptions& options) {
  ScanSection section;
  section.part = "can";
  const std::int64_t slow = std::max<std::int64_t>(context.slow_motion, 1);
  std::map<std::uint8_t, FoundNode> nodes;
  if (options.nmt_reset && context.op != nullptr &&
      context.op->confirm("Send NMT reset communication to every node on " + bus.name() +
                          " (drives drop torque and restart their communication)?")) {
    (void)bus.send_one(co::encode_nmt(co::NmtCommand::reset_communication, 0));
  }
  listen(bus, options.listen_ns * slow, nodes);
  const std::set<std::uint8_t> answered = probe_all(bus, options.probe_timeout_ns * slow, nodes);
  for (const std::uint8_t id : answered) nodes[id].node = id;
  const std::int64_t sdo_timeout =
      (context.device ? context.device->canopen.sdo_timeout_ns : 100'000'000) * slow;
  sc::detail::SetupBus sdo(bus, bus.name(), sdo_timeout);
  for (auto& [id, found] : nodes) {
    if (answered.count(id) != 0) read_node(sdo, found);
    ScanItem item;
    item.kind = "can_node";
    item.name = "node " + std::to_string(id);
    nlohmann::json& p = item.properties;
    p["node_id"] = id;
    p["bus"] = bus.name();
    if (found.heard) p["heard"] = *found.heard;
    p["sdo"] = answered.count(id) != 0;
    if (found.device_type) p["device_type"] = hex32(*found.device_type);
    if (found.vendor) p["vendor_id"] = hex32(*found.vendor);
    if (found.product) p["product_code"] = hex32(*found.product);
    if (found.revision) p["revision"] = hex32(*found.revision);
    if (found.serial) p["serial_number"] = hex32(*found.serial);
    if (found.error_register) p["error_register"] = hex8(*found.error_register);
    if (found.firmware) p["firmware"] = *found.firmware;
    if (!found.problems.empty()) p["problems"] = found.problems;
    section.found.push_back(std::move(item));
  }
  if (!context.device) return section;

  // --- comparison with the device file ---------------------------------------------------
  const std::vector<FileDrive> drives = file_drives(*context.device);
  std::set<std::uint8_t> claimed;
  std::vector<const FileDrive*> missing;
  for (const FileDrive& drive : drives) {
    StepResult step;
    step.id = "can.scan." + drive.axis;
    step.title = drive.axis + ": drive on node " + std::to_string(drive.config.node_id);
    const std::uint8_t id = drive.config.node_id;
    claimed.insert(id);
    const auto it = nodes.find(id);
    if (it == nodes.end() || answered.count(id) == 0) {
      step.outcome = Outcome::fail;
      step.reason = "missing: node " + std::to_string(id) + " (" + drive.key +
                    ".node_id) did not answer an SDO read of 0x1000 within " +
                    std::to_string(options.probe_timeout_ns / 1'000'000) + " ms" +
                    (it != nodes.end() && it->second.heard ? " (its heartbeat was heard)" : "");
      missing.push_back(&drive);
      section.comparison.push_back(std::move(step));
      continue;
    }
    const FoundNode& found = it->second;
    step.details["identity"] = identity_text(found);
    const bool drive_profile =
        found.device_type && (*found.device_type & 0xFFFFU) == co::kDeviceProfileDrive;
    if (!drive_profile) {
      step.outcome = Outcome::fail;
      step.reason = "node " + std::to_string(id) + ": device type 0x1000 = " +
                    (found.device_type ? hex32(*found.device_type) : std::string("unreadable")) +
                    ", expected a CiA 402 drive (low 16 bits 402 = 0x0192)";
    } else if (!same_identity(found, drive)) {
      step.outcome = Outcome::fail;
      step.reason = "wrong identity: node " + std::to_string(id) + " reports " +
                    identity_text(found) + "; the file expects vendor " +
                    hex32(drive.config.vendor_id) + ", product " + hex32(drive.config.product_code) +
                    (drive.config.revision ? ", revision " + hex32(*drive.config.revision) : "") +
                    " (" + drive.key + ")";
    } else {
      step.outcome = Outcome::pass;
      step.reason = "node " + std::to_string(id) + ": " + identity_text(found) +
                    (found.firmware ? ", firmware \"" + *found.firmware + "\"" : "");
    }
    section.comparison.push_back(std::move(step));
  }
  std::vector<const FoundNode*> extra;
  for (const auto& [id, found] : nodes) {
    if (claimed.count(id) != 0) continue;
    extra.push_back(&found);
    StepResult step;
    step.id = "can.scan.extra.node" + std::to_string(id);
    step.title = "node " + std::to_string(id) + ": not in the device file";
    step.outcome = Outcome::fail;
    step.reason = "extra: node " + std::to_string(id) + " answers (" + identity_text(found) +
                  ") but the device file has no drive with this id";
    section.comparison.push_back(std::move(step));
  }
  // node_id corrections: a missing drive and exactly one extra node with its identity, that
  // identity matching no other missing drive.
  for (const FileDrive* drive : missing) {
    std::vector<const FoundNode*> candidates;
    for (const FoundNode* found : extra) {
      if (same_identity(*found, *drive)) candidates.push_back(found);
    }
    if (candidates.size() != 1) continue;
    const std::size_t rivals = static_cast<std::size_t>(std::count_if(
        missing.begin(), missing.end(),
        [&](const FileDrive* other) { return same_identity(*candidates[0], *other); }));
    if (rivals != 1) continue;
    const std::string old_id = std::to_string(drive->config.node_id);
    const std::string new_id = std::to_string(candidates[0]->node);
    const std::string why = "node " + old_id + " did not answer; node " + new_id +
                            " answers with the identity the file expects of " + drive->axis +
                            " (" + identity_text(*candidates[0]) + ") and is not in the file";
    Correction correction{"instrument." + drive->joint_name, drive->instrument, "node_id", old_id,
                          new_id, why};
    for (StepResult& step : section.comparison) {
      if (step.id == "can.scan." + drive->axis) step.details["correction"] = correction_to_json(correction);
    }
    section.corrections.push_back(correction);
    for (const auto& [key, value] : {std::pair{"digital_inputs_node", context.device->canopen.digital_inputs_node},
                                     std::pair{"digital_outputs_node", context.device->canopen.digital_outputs_node}}) {
      if (value == drive->config.node_id) {
        section.corrections.push_back(
            Correction{"canopen", "", key, old_id, new_id, "follows " + drive->axis + ".node_id: " + why});
      }
    }
  }
  return section;
}

}  // namespace trainer::hil::can
