// hil scan, USB (docs/hil-io.md): the devices with the protocol's VID:PID (or the device file's)
// and their identity (the protocol's GET_IDENTITY request), the other devices with a vendor
// interface listed; the comparison with the device file's [usb] table.
#include <libusb.h>

#include <cstdio>
#include <string>
#include <vector>

#include "trainer/hal_usbproto/protocol.hpp"
#include "trainer/hil/io_parts.hpp"

namespace trainer::hil {
namespace {

namespace up = trainer::hal::usbproto;

std::string usb_scan_hex4(unsigned value) {
  char text[8];
  std::snprintf(text, sizeof text, "%04x", value & 0xFFFFU);
  return text;
}

std::string usb_scan_version(unsigned v) {
  return std::to_string(v >> 8) + "." + std::to_string(v & 0xFFU);
}

// The first vendor-specific interface of the active configuration, or -1.
int usb_scan_vendor_interface(libusb_device* dev) {
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(dev, &config) != 0 || config == nullptr) return -1;
  int found = -1;
  for (int i = 0; i < config->bNumInterfaces && found < 0; ++i) {
    const libusb_interface& itf = config->interface[i];
    for (int a = 0; a < itf.num_altsetting; ++a) {
      if (itf.altsetting[a].bInterfaceClass == up::kInterfaceClass) {
        found = itf.altsetting[a].bInterfaceNumber;
        break;
      }
    }
  }
  libusb_free_config_descriptor(config);
  return found;
}

void usb_scan_query(libusb_device* dev, const libusb_device_descriptor& desc, UsbFoundDevice& out,
                    bool ask_identity) {
  libusb_device_handle* handle = nullptr;
  if (const int rc = libusb_open(dev, &handle); rc != 0) {
    out.error = std::string("cannot open: ") + libusb_error_name(rc) +
                " (the user needs access to the device: a udev rule)";
    return;
  }
  if (desc.iSerialNumber != 0) {
    unsigned char text[128] = {};
    const int n = libusb_get_string_descriptor_ascii(handle, desc.iSerialNumber, text, sizeof text);
    if (n > 0) out.serial.assign(reinterpret_cast<const char*>(text), static_cast<std::size_t>(n));
  }
  if (ask_identity && out.vendor_interface >= 0) {
    libusb_set_auto_detach_kernel_driver(handle, 1);
    const int claimed = libusb_claim_interface(handle, out.vendor_interface);
    if (claimed != 0) {
      out.error = std::string("cannot claim interface ") + std::to_string(out.vendor_interface) +
                  ": " + libusb_error_name(claimed) + " (in use by another program: a trainer?)";
    } else {
      unsigned char bytes[up::kIdentitySize] = {};
      const int n = libusb_control_transfer(
          handle, up::kRequestTypeVendorInterfaceIn, up::kRequestGetIdentity, 0,
          static_cast<std::uint16_t>(out.vendor_interface), bytes, sizeof bytes, 500);
      if (n < 0) {
        out.error = std::string("GET_IDENTITY failed: ") + libusb_error_name(n);
      } else {
        up::Identity identity;
        const auto status = up::decode(std::span<const std::uint8_t>(bytes, static_cast<std::size_t>(n)), identity);
        if (status != up::DecodeStatus::ok) {
          out.error = std::string("GET_IDENTITY answer refused: ") + up::to_string(status) + " (" +
                      std::to_string(n) + " bytes)";
        } else {
          UsbIdentity id;
          id.protocol_version = identity.protocol_version;
          id.firmware_version = identity.firmware_version;
          id.channel_count = identity.channel_count;
          id.watchdog_ms = identity.watchdog_ms;
          id.frame_interval_us = identity.frame_interval_us;
          id.max_current_ma = identity.max_current_ma;
          out.identity = id;
        }
      }
      libusb_release_interface(handle, out.vendor_interface);
    }
  }
  libusb_close(handle);
}

std::string usb_scan_name(const UsbFoundDevice& d) {
  std::string name = usb_scan_hex4(d.vendor_id) + ":" + usb_scan_hex4(d.product_id);
  if (!d.serial.empty()) name += " serial " + d.serial;
  return name + " (bus " + std::to_string(d.bus) + " device " + std::to_string(d.address) + ")";
}

}  // namespace

std::vector<UsbFoundDevice> list_usb_devices(std::uint16_t vendor_id, std::uint16_t product_id,
                                             std::string* error) {
  std::vector<UsbFoundDevice> found;
  libusb_context* context = nullptr;
  if (const int rc = libusb_init(&context); rc != 0) {
    if (error != nullptr) *error = std::string("libusb_init: ") + libusb_error_name(rc);
    return found;
  }
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context, &list);
  if (count < 0 && error != nullptr) {
    *error = std::string("libusb_get_device_list: ") + libusb_error_name(static_cast<int>(count));
  }
  for (ssize_t i = 0; i < count; ++i) {
    libusb_device* dev = list[i];
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(dev, &desc) != 0) continue;
    UsbFoundDevice d;
    d.vendor_id = desc.idVendor;
    d.product_id = desc.idProduct;
    d.bus = libusb_get_bus_number(dev);
    d.address = libusb_get_device_address(dev);
    d.vendor_interface = usb_scan_vendor_interface(dev);
    d.protocol_ids = desc.idVendor == vendor_id && desc.idProduct == product_id;
    if (!d.protocol_ids && d.vendor_interface < 0) continue;
    // Only a device with the protocol's VID:PID is asked for its identity: a vendor request
    // means something else to another vendor's device.
    usb_scan_query(dev, desc, d, d.protocol_ids);
    found.push_back(std::move(d));
  }
  if (list != nullptr) libusb_free_device_list(list, 1);
  libusb_exit(context);
  return found;
}

std::vector<StepResult> compare_usb(const std::vector<UsbFoundDevice>& found,
                                    const config::DeviceConfig& device) {
  std::vector<StepResult> steps;
  const config::UsbConfig& usb = device.usb;
  const std::string ids = usb_scan_hex4(usb.vendor_id) + ":" + usb_scan_hex4(usb.product_id);
  const std::string wanted = ids + (usb.serial.empty() ? "" : " serial '" + usb.serial + "'");
  std::vector<const UsbFoundDevice*> candidates;
  std::vector<const UsbFoundDevice*> others;
  for (const UsbFoundDevice& d : found) {
    if (!d.protocol_ids) continue;
    if (usb.serial.empty() || d.serial == usb.serial) {
      candidates.push_back(&d);
    } else {
      others.push_back(&d);
    }
  }
  StepResult present;
  present.id = "usb.scan.device";
  present.title = "USB interface " + wanted;
  present.outcome = Outcome::fail;
  std::string on_bus;
  for (const UsbFoundDevice& d : found) {
    if (d.protocol_ids) on_bus += (on_bus.empty() ? "" : ", ") + usb_scan_name(d);
  }
  if (candidates.empty()) {
    present.reason = "no USB device " + wanted + " (with " + ids + " on the bus: " +
                     (on_bus.empty() ? "none" : on_bus) + ")";
    steps.push_back(std::move(present));
  } else if (candidates.size() > 1) {
    present.reason = std::to_string(candidates.size()) + " devices " + ids +
                     " and usb.serial is empty: name one (" + on_bus + ")";
    steps.push_back(std::move(present));
  } else {
    const UsbFoundDevice& d = *candidates.front();
    present.details = {{"bus", d.bus}, {"address", d.address}, {"serial", d.serial}};
    if (!d.identity) {
      present.reason = usb_scan_name(d) + ": no identity: " +
                       (d.error.empty() ? "no vendor-specific interface" : d.error);
      steps.push_back(std::move(present));
    } else {
      present.outcome = Outcome::pass;
      present.reason = "found " + usb_scan_name(d);
      steps.push_back(std::move(present));
      const UsbIdentity& id = *d.identity;
      StepResult version;
      version.id = "usb.scan.protocol_version";
      version.title = "protocol version";
      version.outcome = id.protocol_version == usb.protocol_version ? Outcome::pass : Outcome::fail;
      version.reason = "the device reports protocol " + std::to_string(id.protocol_version) +
                       ", usb.protocol_version = " + std::to_string(usb.protocol_version);
      steps.push_back(std::move(version));
      StepResult firmware;
      firmware.id = "usb.scan.firmware_version";
      firmware.title = "firmware version";
      if (!usb.min_firmware_version) {
        firmware.outcome = Outcome::pass;
        firmware.reason = "firmware " + usb_scan_version(id.firmware_version) +
                          " (usb.min_firmware_version not set)";
      } else {
        firmware.outcome =
            id.firmware_version >= *usb.min_firmware_version ? Outcome::pass : Outcome::fail;
        firmware.reason = "firmware " + usb_scan_version(id.firmware_version) +
                          ", usb.min_firmware_version = " +
                          usb_scan_version(*usb.min_firmware_version);
      }
      steps.push_back(std::move(firmware));
      StepResult channels;
      channels.id = "usb.scan.channels";
      channels.title = "channel count";
      const std::size_t joints = device.instruments.size() * config::kJointCount;
      channels.outcome = id.channel_count == joints ? Outcome::pass : Outcome::fail;
      channels.reason = "the device has " + std::to_string(id.channel_count) +
                        " channels, the device file " + std::to_string(joints) + " joints (" +
                        std::to_string(device.instruments.size()) + " instruments x 5)";
      steps.push_back(std::move(channels));
    }
  }
  for (const UsbFoundDevice* d : others) {
    StepResult extra;
    extra.id = "usb.scan.extra." + (d->serial.empty() ? std::to_string(d->bus) + "-" + std::to_string(d->address) : d->serial);
    extra.title = "another " + ids + " on the bus";
    extra.outcome = Outcome::fail;
    extra.reason = usb_scan_name(*d) + " is not in the device file (usb.serial = '" + usb.serial +
                   "'): unplug it or name it";
    steps.push_back(std::move(extra));
  }
  return steps;
}

ScanSection make_usb_scan_section(const std::vector<UsbFoundDevice>& found,
                                  const std::optional<config::DeviceConfig>& device) {
  ScanSection section;
  section.part = "usb";
  for (const UsbFoundDevice& d : found) {
    ScanItem item;
    item.kind = "usb_device";
    item.name = usb_scan_name(d);
    item.properties = {{"vendor_id", usb_scan_hex4(d.vendor_id)},
                       {"product_id", usb_scan_hex4(d.product_id)},
                       {"serial", d.serial},
                       {"bus", d.bus},
                       {"address", d.address},
                       {"vendor_interface", d.vendor_interface},
                       {"protocol", d.protocol_ids}};
    if (d.identity) {
      item.properties["identity"] = {{"protocol_version", d.identity->protocol_version},
                                     {"firmware_version", usb_scan_version(d.identity->firmware_version)},
                                     {"channels", d.identity->channel_count},
                                     {"watchdog_ms", d.identity->watchdog_ms},
                                     {"frame_interval_us", d.identity->frame_interval_us},
                                     {"max_current_ma", d.identity->max_current_ma}};
    }
    if (!d.error.empty()) item.properties["error"] = d.error;
    section.found.push_back(std::move(item));
  }
  if (!device) return section;
  if (device->backend != "usb") {
    StepResult step;
    step.id = "usb.scan.device_file";
    step.title = "device file's USB interface";
    step.outcome = Outcome::skip;
    step.reason = device->source_path.string() + " has backend \"" + device->backend +
                  "\", not \"usb\": nothing to compare";
    section.comparison.push_back(std::move(step));
    return section;
  }
  section.comparison = compare_usb(found, *device);
  return section;
}

ScanSection scan_usb(const BenchContext& bench) {
  std::uint16_t vid = up::kVendorId;
  std::uint16_t pid = up::kProductId;
  if (bench.device && bench.device->backend == "usb") {
    vid = bench.device->usb.vendor_id;
    pid = bench.device->usb.product_id;
  }
  std::string error;
  ScanSection section = make_usb_scan_section(list_usb_devices(vid, pid, &error), bench.device);
  if (!error.empty()) {
    StepResult step;
    step.id = "usb.scan.bus";
    step.title = "USB bus readable";
    step.outcome = Outcome::fail;
    step.reason = error;
    section.comparison.insert(section.comparison.begin(), std::move(step));
  }
  return section;
}

}  // namespace trainer::hil
