// The Linux side of the emulated interface, setup path only (exceptions, no RT): a configfs
// USB gadget (/sys/kernel/config/usb_gadget/<name>: ids, strings with the serial, one
// configuration, one FunctionFS function ffs.<name>), the functionfs mount that carries it, and
// binding to a UDC. Every step that succeeded is remembered and undone in reverse order by
// remove(), also after a partial create(), so that an interrupted start leaves nothing behind.
// Errors are std::runtime_error naming the path and the errno text.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace trainer::tools::usbgadget {

struct GadgetIdentity {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::uint16_t bcd_device = 0;
  std::string manufacturer;
  std::string product;
  std::string serial;
  std::string configuration;  // configuration string
  int max_power_ma = 100;
};

class ConfigfsGadget {
 public:
  // `configfs_root`: /sys/kernel/config/usb_gadget; `ffs_dir`: where functionfs is mounted.
  ConfigfsGadget(std::filesystem::path configfs_root, std::string name,
                 std::filesystem::path ffs_dir);
  ~ConfigfsGadget();
  ConfigfsGadget(const ConfigfsGadget&) = delete;
  ConfigfsGadget& operator=(const ConfigfsGadget&) = delete;

  // Creates the gadget and its function and mounts functionfs on ffs_dir. Refuses a gadget
  // directory that already exists (another program's, or a stale one: the message says how to
  // remove it).
  void create(const GadgetIdentity& identity);
  // Writes the UDC name to <gadget>/UDC (the descriptors must be on ep0 already).
  void bind(const std::string& udc);
  // Writes an empty line to <gadget>/UDC; errors are returned as text, never thrown.
  std::string unbind() noexcept;
  // Unbinds and undoes create() in reverse order; returns one line per step that failed.
  std::vector<std::string> remove() noexcept;

  const std::filesystem::path& gadget_dir() const noexcept { return gadget_dir_; }
  const std::filesystem::path& ffs_dir() const noexcept { return ffs_dir_; }
  bool bound() const noexcept { return bound_; }

 private:
  struct Undo {
    enum class Kind { rmdir, unlink, umount } kind;
    std::filesystem::path path;
  };
  void make_dir(const std::filesystem::path& path);
  std::filesystem::path root_;
  std::string name_;
  std::filesystem::path gadget_dir_;
  std::filesystem::path ffs_dir_;
  std::vector<Undo> undo_;
  bool bound_ = false;
};

// Takes apart a gadget left by a usbgadget that could not clean up (SIGKILL): unbinds it,
// unmounts `ffs_dir` if functionfs is mounted there, removes the configuration links and
// directories, functions, strings and the gadget directory. Does nothing when `gadget_dir`
// does not exist. Throws at the first step that fails, naming the path.
void remove_stale_gadget(const std::filesystem::path& gadget_dir,
                         const std::filesystem::path& ffs_dir);

// Writes `text` to an existing sysfs/configfs attribute; throws naming the path.
void write_attribute(const std::filesystem::path& path, const std::string& text);
// The UDCs in /sys/class/udc (sorted).
std::vector<std::string> list_udcs(const std::filesystem::path& class_dir = "/sys/class/udc");

}  // namespace trainer::tools::usbgadget
