#include "ffs_descriptors.hpp"

#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>

#include "trainer/hal_usbproto/protocol.hpp"

namespace trainer::tools::usbgadget {
namespace {

namespace up = hal::usbproto;

void ffs_put_le32(std::vector<std::uint8_t>& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU));
}
void ffs_put_le32_at(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t value) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>((value >> (8 * i)) & 0xFFU);
}

// One speed's set: interface, IN endpoint, OUT endpoint (3 descriptors).
void ffs_speed_set(std::vector<std::uint8_t>& out, std::uint8_t interval) {
  const std::uint8_t interface[USB_DT_INTERFACE_SIZE] = {
      USB_DT_INTERFACE_SIZE, USB_DT_INTERFACE,
      0,                        // bInterfaceNumber (FunctionFS renumbers)
      0,                        // bAlternateSetting
      2,                        // bNumEndpoints
      up::kInterfaceClass, up::kInterfaceSubClass, up::kInterfaceProtocol,
      1};                       // iInterface: string 1 of ffs_strings()
  out.insert(out.end(), std::begin(interface), std::end(interface));
  for (const std::uint8_t address : {std::uint8_t{1 | USB_DIR_IN}, std::uint8_t{1 | USB_DIR_OUT}}) {
    const std::uint8_t endpoint[USB_DT_ENDPOINT_SIZE] = {
        USB_DT_ENDPOINT_SIZE, USB_DT_ENDPOINT, address, USB_ENDPOINT_XFER_INT,
        static_cast<std::uint8_t>(up::kMaxPacketSize & 0xFFU),
        static_cast<std::uint8_t>(up::kMaxPacketSize >> 8), interval};
    out.insert(out.end(), std::begin(endpoint), std::end(endpoint));
  }
}

}  // namespace

std::vector<std::uint8_t> ffs_descriptors() {
  std::vector<std::uint8_t> out;
  ffs_put_le32(out, FUNCTIONFS_DESCRIPTORS_MAGIC_V2);
  ffs_put_le32(out, 0);  // length, below
  ffs_put_le32(out, FUNCTIONFS_HAS_FS_DESC | FUNCTIONFS_HAS_HS_DESC);
  ffs_put_le32(out, 3);  // fs_count
  ffs_put_le32(out, 3);  // hs_count
  ffs_speed_set(out, up::kIntervalFullSpeed);
  ffs_speed_set(out, up::kIntervalHighSpeed);
  ffs_put_le32_at(out, 4, static_cast<std::uint32_t>(out.size()));
  return out;
}

std::vector<std::uint8_t> ffs_strings(const std::string& interface_string) {
  std::vector<std::uint8_t> out;
  ffs_put_le32(out, FUNCTIONFS_STRINGS_MAGIC);
  ffs_put_le32(out, 0);  // length, below
  ffs_put_le32(out, 1);  // str_count
  ffs_put_le32(out, 1);  // lang_count
  out.push_back(0x09);   // 0x0409 US English, LE16
  out.push_back(0x04);
  out.insert(out.end(), interface_string.begin(), interface_string.end());
  out.push_back(0);
  ffs_put_le32_at(out, 4, static_cast<std::uint32_t>(out.size()));
  return out;
}

}  // namespace trainer::tools::usbgadget
