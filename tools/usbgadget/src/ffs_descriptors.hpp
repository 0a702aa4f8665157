// The FunctionFS blobs the gadget writes to ep0 (Documentation/usb/functionfs.rst,
// <linux/usb/functionfs.h>): the descriptors (v2 format, full-speed and high-speed sets of
// docs/usb-protocol.md: one vendor interface, interrupt IN then interrupt OUT, 64 bytes,
// bInterval 1) and the strings (the interface string, US English). Built byte by byte,
// little-endian, so that they do not depend on the host's struct packing.
//
// FunctionFS names the endpoint files in descriptor order: ep1 = IN, ep2 = OUT.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace trainer::tools::usbgadget {

inline constexpr const char* kInEndpointFile = "ep1";
inline constexpr const char* kOutEndpointFile = "ep2";
inline constexpr const char* kInterfaceString = "trainer haptic v1";

std::vector<std::uint8_t> ffs_descriptors();
std::vector<std::uint8_t> ffs_strings(const std::string& interface_string = kInterfaceString);

}  // namespace trainer::tools::usbgadget
