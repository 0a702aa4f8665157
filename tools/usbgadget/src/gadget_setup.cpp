#include "gadget_setup.hpp"

#include <fcntl.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace trainer::tools::usbgadget {
namespace fs = std::filesystem;

namespace {

std::string errno_text(int error) { return std::strerror(error); }

std::string hex4(std::uint16_t value) {
  char text[8];
  std::snprintf(text, sizeof(text), "0x%04x", static_cast<unsigned>(value));
  return text;
}

}  // namespace

void write_attribute(const fs::path& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    throw std::runtime_error(path.string() + ": open for writing: " + errno_text(error));
  }
  const ssize_t written = ::write(fd, text.data(), text.size());
  const int error = errno;
  ::close(fd);
  if (written < 0) {
    throw std::runtime_error(path.string() + ": write \"" + text + "\": " + errno_text(error));
  }
  if (static_cast<std::size_t>(written) != text.size()) {
    throw std::runtime_error(path.string() + ": short write of \"" + text + "\"");
  }
}

std::vector<std::string> list_udcs(const fs::path& class_dir) {
  std::vector<std::string> names;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(class_dir, error)) {
    names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

namespace {

bool is_mount_point(const fs::path& path) {
  std::ifstream mounts("/proc/self/mounts");
  std::string device;
  std::string mount_point;
  std::string rest;
  while (mounts >> device >> mount_point && std::getline(mounts, rest)) {
    if (mount_point == path.string()) return true;
  }
  return false;
}

void remove_or_throw(const fs::path& path, bool is_link) {
  if ((is_link ? ::unlink(path.c_str()) : ::rmdir(path.c_str())) != 0) {
    const int error = errno;
    throw std::runtime_error(path.string() + (is_link ? ": unlink: " : ": rmdir: ") + errno_text(error));
  }
}

std::vector<fs::path> entries_of(const fs::path& dir) {
  std::vector<fs::path> entries;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(dir, error)) entries.push_back(entry.path());
  return entries;
}

}  // namespace

void remove_stale_gadget(const fs::path& gadget_dir, const fs::path& ffs_dir) {
  std::error_code error;
  if (!fs::is_directory(gadget_dir, error)) return;
  {
    std::ifstream udc_file(gadget_dir / "UDC");
    std::string udc;
    std::getline(udc_file, udc);
    if (!udc.empty()) write_attribute(gadget_dir / "UDC", "\n");
  }
  if (is_mount_point(ffs_dir) && ::umount2(ffs_dir.c_str(), 0) != 0) {
    const int e = errno;
    throw std::runtime_error(ffs_dir.string() + ": umount: " + errno_text(e) +
                             " (is another usbgadget still running?)");
  }
  for (const fs::path& config : entries_of(gadget_dir / "configs")) {
    for (const fs::path& entry : entries_of(config)) {
      if (fs::is_symlink(fs::symlink_status(entry, error))) remove_or_throw(entry, true);
    }
    for (const fs::path& strings : entries_of(config / "strings")) remove_or_throw(strings, false);
    remove_or_throw(config, false);
  }
  for (const fs::path& function : entries_of(gadget_dir / "functions")) remove_or_throw(function, false);
  for (const fs::path& strings : entries_of(gadget_dir / "strings")) remove_or_throw(strings, false);
  remove_or_throw(gadget_dir, false);
}

ConfigfsGadget::ConfigfsGadget(fs::path configfs_root, std::string name, fs::path ffs_dir)
    : root_(std::move(configfs_root)), name_(std::move(name)), gadget_dir_(root_ / name_),
      ffs_dir_(std::move(ffs_dir)) {}

ConfigfsGadget::~ConfigfsGadget() { (void)remove(); }

void ConfigfsGadget::make_dir(const fs::path& path) {
  if (::mkdir(path.c_str(), 0755) != 0) {
    const int error = errno;
    throw std::runtime_error(path.string() + ": mkdir: " + errno_text(error));
  }
  undo_.push_back({Undo::Kind::rmdir, path});
}

void ConfigfsGadget::create(const GadgetIdentity& identity) {
  std::error_code error;
  if (!fs::is_directory(root_, error)) {
    throw std::runtime_error(root_.string() +
                             ": not a directory: is configfs mounted on /sys/kernel/config and "
                             "libcomposite loaded? (bench VM: tools/benchvm/usb-gadget-modules)");
  }
  if (fs::exists(gadget_dir_, error)) {
    throw std::runtime_error(gadget_dir_.string() +
                             ": a gadget of this name exists (another program's, or left by a "
                             "killed usbgadget): choose another --gadget-name, or remove it "
                             "(--remove-stale, or by hand: docs/usb.md \"Removing a stale "
                             "gadget\")");
  }
  make_dir(gadget_dir_);
  write_attribute(gadget_dir_ / "idVendor", hex4(identity.vendor_id));
  write_attribute(gadget_dir_ / "idProduct", hex4(identity.product_id));
  write_attribute(gadget_dir_ / "bcdDevice", hex4(identity.bcd_device));
  write_attribute(gadget_dir_ / "bcdUSB", "0x0200");
  const fs::path strings = gadget_dir_ / "strings" / "0x409";
  make_dir(strings);
  write_attribute(strings / "manufacturer", identity.manufacturer);
  write_attribute(strings / "product", identity.product);
  write_attribute(strings / "serialnumber", identity.serial);
  const fs::path config = gadget_dir_ / "configs" / "c.1";
  make_dir(config);
  write_attribute(config / "MaxPower", std::to_string(identity.max_power_ma));
  make_dir(config / "strings" / "0x409");
  write_attribute(config / "strings" / "0x409" / "configuration", identity.configuration);
  const fs::path function = gadget_dir_ / "functions" / ("ffs." + name_);
  make_dir(function);
  const fs::path link = config / ("ffs." + name_);
  if (::symlink(function.c_str(), link.c_str()) != 0) {
    const int e = errno;
    throw std::runtime_error(link.string() + ": symlink to " + function.string() + ": " + errno_text(e));
  }
  undo_.push_back({Undo::Kind::unlink, link});

  if (!fs::is_directory(ffs_dir_, error)) {
    fs::create_directories(ffs_dir_, error);
    if (error) throw std::runtime_error(ffs_dir_.string() + ": mkdir: " + error.message());
    undo_.push_back({Undo::Kind::rmdir, ffs_dir_});
  }
  if (::mount(name_.c_str(), ffs_dir_.c_str(), "functionfs", 0, nullptr) != 0) {
    const int e = errno;
    throw std::runtime_error(ffs_dir_.string() + ": mount -t functionfs " + name_ + ": " +
                             errno_text(e) + (e == ENODEV ? " (usb_f_fs not loaded?)" : ""));
  }
  undo_.push_back({Undo::Kind::umount, ffs_dir_});
}

void ConfigfsGadget::bind(const std::string& udc) {
  write_attribute(gadget_dir_ / "UDC", udc);
  bound_ = true;
}

std::string ConfigfsGadget::unbind() noexcept {
  if (!bound_) return {};
  bound_ = false;
  try {
    write_attribute(gadget_dir_ / "UDC", "\n");
  } catch (const std::exception& e) {
    return e.what();
  }
  return {};
}

std::vector<std::string> ConfigfsGadget::remove() noexcept {
  std::vector<std::string> failures;
  if (std::string failed = unbind(); !failed.empty()) failures.push_back(std::move(failed));
  while (!undo_.empty()) {
    const Undo step = undo_.back();
    undo_.pop_back();
    int result = 0;
    const char* what = "";
    switch (step.kind) {
      case Undo::Kind::rmdir: result = ::rmdir(step.path.c_str()); what = "rmdir"; break;
      case Undo::Kind::unlink: result = ::unlink(step.path.c_str()); what = "unlink"; break;
      case Undo::Kind::umount: result = ::umount2(step.path.c_str(), 0); what = "umount"; break;
    }
    if (result != 0) failures.push_back(step.path.string() + ": " + what + ": " + errno_text(errno));
  }
  return failures;
}

}  // namespace trainer::tools::usbgadget
