// simdrive's setup: a scene and a CANopen device file become the parameters of a SimDriveBus
// (hal/simdrive), so the drives present exactly the identities, node ids, rated torques and
// mechanism the trainer's master will check against the same file. The conversion of the
// mechanism into the plant's parameters is the one the trainer's sim backend uses
// (rt/app device_wiring.cpp, sim_params_from). Setup path: allocates, returns errors that name
// the file and key.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "trainer/config/device.hpp"
#include "trainer/config/scene.hpp"
#include "trainer/core/expected.hpp"
#include "trainer/hal_simdrive/sim_drive_bus.hpp"

namespace trainer::tools::simdrive {

// Deliberate mismatches for testing a master's checks (the program's --vendor-id,
// --product-code, --rated-torque-scale): every drive reports them instead of the file's.
struct IdentityOverrides {
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  double rated_torque_scale = 1.0;  // 0x6076 = the file's rated torque times this
};

// A bench wired wrongly (the program's --miswire and --node-id-map), for testing `hil`:
//   reverse_encoder:node=N  the drive of node N reports its position (and velocity) negated
//   reverse_motor:node=N    the drive of node N turns its joint the other way
//   --node-id-map A=B       the drive the file calls node A answers as node B
// Node numbers are the device file's ids (before any map).
struct Miswiring {
  std::vector<std::uint8_t> reverse_encoder;
  std::vector<std::uint8_t> reverse_motor;
  std::vector<std::pair<std::uint8_t, std::uint8_t>> node_id_map;  // file id -> bus id
};
// Adds one --miswire SPEC / one --node-id-map A=B to `out`; errors name the text and what was
// expected.
core::Expected<void> parse_miswire(std::string_view text, Miswiring& out);
core::Expected<void> parse_node_id_map(std::string_view text, Miswiring& out);
// Applies `miswiring` to the drives of `params` (built by bus_params_from). Errors: a node the
// file does not have, a mapped id another drive already uses.
core::Expected<void> apply_miswiring(const Miswiring& miswiring,
                                     hal::simdrive::SimDriveBusParams& params);

// The drives of `device` (backend "canopen") with `trainee_script` as the simulated hand.
// Node i drives channel i = instrument * 5 + joint; identity, rated torque (rounded to mN·m)
// and node id from each joint's [instrument.<joint>] keys; revision from the file when given
// (else 1), serial number = node id. The file's encoder_direction / motor_direction are NOT
// simulated (they say how the master compensates a wiring; the simulated wiring is correct
// unless Miswiring says otherwise). Plant time per SYNC: canopen.sync_period_us, or when that
// is 0 ("SYNC every loop period") `loop_period_ns`, the trainer's loop period.
core::Expected<hal::simdrive::SimDriveBusParams> bus_params_from(
    const config::DeviceConfig& device, const std::string& trainee_script,
    std::int64_t loop_period_ns, const IdentityOverrides& overrides = {});

// The scene (its trainee script and loop period) with `device_file` in place of the device
// file it names, checked against it as the trainer's --device does (config::LoadOptions::
// device_file); without one, the scene's own. Refuses a device whose backend is not "canopen".
core::Expected<config::SceneConfig> load_scene_with_device(
    const std::filesystem::path& scene_file,
    const std::optional<std::filesystem::path>& device_file);

}  // namespace trainer::tools::simdrive
