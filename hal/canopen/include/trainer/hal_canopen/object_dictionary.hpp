// ObjectDictionary: the slave's fixed-capacity object dictionary (CiA 301 v4.2, 7.4):
// entries by index and sub-index with a data type, access, PDO-mappable flag, value
// storage, optional min/max, and an observer through which the drive logic validates
// remote writes (returning an SDO abort code) and reacts to them.
//
// Setup (allocates nothing; may return errors with context):
//   ObjectDictionary od;
//   od.add({.index = 0x6060, .sub = 0, .type = DataType::i8, .access = Access::rw,
//           .pdo_mappable = true, .value = 0});
//   od.add({.index = 0x6071, .sub = 0, .type = DataType::i16, .access = Access::rw,
//           .pdo_mappable = true, .min = -1000, .max = 1000});
//   od.add_string(0x1008, 0, Access::constant, "haptic drive");
//   od.set_observer(&drive);                 // validate_write() / on_written()
// Per cycle (drive logic, local access: no access check, no observer):
//   std::int16_t target = 0; od.get(0x6071, 0, target);
//   od.set<std::uint16_t>(0x6041, 0, statusword);
// Remote access (SdoServer, PDOs): read() / write() return 0 or an SDO abort code.
//
// Records and arrays are plain entries: add sub-index 0 ("highest sub-index supported",
// u8) yourself. Numeric values are stored little-endian in their CiA 301 size; a visible
// string holds up to kMaxStringBytes; a domain entry reads and writes caller storage.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <type_traits>

#include "trainer/core/expected.hpp"
#include "trainer/core/status.hpp"

namespace trainer::hal::canopen {

enum class DataType : std::uint8_t { i8, i16, i32, u8, u16, u32, visible_string, domain };
const char* to_string(DataType type) noexcept;
// Bytes of a numeric type; 0 for visible_string and domain (variable length).
std::size_t data_type_size(DataType type) noexcept;
bool is_signed(DataType type) noexcept;
bool is_numeric(DataType type) noexcept;

enum class Access : std::uint8_t {
  ro,        // read only; may change (e.g. statusword)
  wo,        // write only
  rw,        // read and write
  constant,  // read only, never changes
};
const char* to_string(Access access) noexcept;

inline constexpr std::size_t kMaxStringBytes = 32;
inline constexpr std::size_t kObjectDictionaryCapacity = 256;

struct ObjectDefinition {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  DataType type = DataType::u8;  // numeric types only (add_string / add_domain for the rest)
  Access access = Access::rw;
  bool pdo_mappable = false;
  std::int64_t value = 0;  // initial value; must fit the type and the range
  std::optional<std::int64_t> min = std::nullopt;  // remote writes below -> abort 0x06090032
  std::optional<std::int64_t> max = std::nullopt;  // remote writes above -> abort 0x06090031
};

class ObjectEntry {
 public:
  std::uint16_t index() const noexcept { return index_; }
  std::uint8_t sub() const noexcept { return sub_; }
  DataType type() const noexcept { return type_; }
  Access access() const noexcept { return access_; }
  bool pdo_mappable() const noexcept { return pdo_mappable_; }
  bool readable() const noexcept { return access_ != Access::wo; }
  bool writable() const noexcept { return access_ == Access::wo || access_ == Access::rw; }
  // Current value bytes (numeric: the type's size; string/domain: current length).
  std::span<const std::uint8_t> bytes() const noexcept;
  // Largest value in bytes (numeric: the type's size).
  std::size_t capacity() const noexcept;
  // Numeric value sign- or zero-extended; 0 for strings and domains.
  std::int64_t as_int() const noexcept;
  std::string_view as_string() const noexcept;  // visible_string / domain bytes as text
  std::optional<std::int64_t> min() const noexcept { return has_min_ ? std::optional(min_) : std::nullopt; }
  std::optional<std::int64_t> max() const noexcept { return has_max_ ? std::optional(max_) : std::nullopt; }

 private:
  friend class ObjectDictionary;
  std::uint32_t key() const noexcept { return (static_cast<std::uint32_t>(index_) << 8) | sub_; }
  std::uint8_t* storage() noexcept { return external_ != nullptr ? external_ : inline_.data(); }
  const std::uint8_t* storage() const noexcept { return external_ != nullptr ? external_ : inline_.data(); }

  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  DataType type_ = DataType::u8;
  Access access_ = Access::rw;
  bool pdo_mappable_ = false;
  bool has_min_ = false;
  bool has_max_ = false;
  std::uint32_t size_ = 0;
  std::uint32_t external_capacity_ = 0;
  std::uint8_t* external_ = nullptr;  // domain storage (caller's)
  std::int64_t min_ = 0;
  std::int64_t max_ = 0;
  std::array<std::uint8_t, kMaxStringBytes> inline_{};
};

// The drive logic's hook on remote writes (SDO, not PDO: RPDO data is stored without
// validation, the drive reads it every cycle and judges it there).
class ObjectDictionaryObserver {
 public:
  // Before storing: return 0 to accept, or the abort code to answer (e.g. kAbortInvalidValue,
  // kAbortDeviceState when the value may not change in the present state).
  virtual std::uint32_t validate_write(const ObjectEntry& entry,
                                       std::span<const std::uint8_t> value) noexcept = 0;
  // After storing.
  virtual void on_written(const ObjectEntry& entry) noexcept = 0;

 protected:
  ~ObjectDictionaryObserver() = default;
};

class ObjectDictionary {
 public:
  // --- setup ---
  core::Expected<void> add(const ObjectDefinition& definition);
  core::Expected<void> add_string(std::uint16_t index, std::uint8_t sub, Access access, std::string_view value);
  // A domain entry reads and writes `storage` (which must outlive the dictionary); its
  // current length starts at `size` bytes.
  core::Expected<void> add_domain(std::uint16_t index, std::uint8_t sub, Access access,
                                  std::span<std::uint8_t> storage, std::size_t size);
  void set_observer(ObjectDictionaryObserver* observer) noexcept { observer_ = observer; }

  // --- lookup ---
  const ObjectEntry* find(std::uint16_t index, std::uint8_t sub) const noexcept;
  // 0, kAbortNoObject (no entry with this index) or kAbortNoSubIndex.
  std::uint32_t locate(std::uint16_t index, std::uint8_t sub, const ObjectEntry** entry) const noexcept;
  std::span<const ObjectEntry> entries() const noexcept { return {entries_.data(), count_}; }
  std::size_t size() const noexcept { return count_; }

  // --- remote access (SDO server, PDO mapping checks): 0 or an SDO abort code ---
  // Copies the value into `out` (kAbortOutOfMemory when it does not fit), `size` = bytes.
  std::uint32_t read(std::uint16_t index, std::uint8_t sub, std::span<std::uint8_t> out,
                     std::size_t& size) const noexcept;
  // Checks existence, access, length, range, then the observer, then stores.
  std::uint32_t write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> value) noexcept;
  // The length check alone (for an SDO initiate that announces `size` bytes).
  static std::uint32_t check_length(const ObjectEntry& entry, std::size_t size) noexcept;

  // --- local access (drive logic): no access check, no observer ---
  std::optional<std::int64_t> get_int(std::uint16_t index, std::uint8_t sub) const noexcept;
  // invalid_argument when the entry is missing, not numeric, or the value does not fit.
  core::Status set_int(std::uint16_t index, std::uint8_t sub, std::int64_t value) noexcept;
  core::Status set_bytes(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> value) noexcept;

  // Typed helpers: T must have the entry's size (e.g. std::uint16_t for u16 / i16).
  template <class T>
  core::Status get(std::uint16_t index, std::uint8_t sub, T& out) const noexcept {
    static_assert(std::is_integral_v<T>, "integral types only");
    const ObjectEntry* entry = find(index, sub);
    if (entry == nullptr || data_type_size(entry->type()) != sizeof(T)) {
      return {core::StatusCode::invalid_argument, "object dictionary: no entry of that size"};
    }
    out = static_cast<T>(entry->as_int());
    return core::Status::ok();
  }
  template <class T>
  core::Status set(std::uint16_t index, std::uint8_t sub, T value) noexcept {
    static_assert(std::is_integral_v<T>, "integral types only");
    const ObjectEntry* entry = find(index, sub);
    if (entry == nullptr || data_type_size(entry->type()) != sizeof(T)) {
      return {core::StatusCode::invalid_argument, "object dictionary: no entry of that size"};
    }
    // Reinterpret through the entry's signedness (an i16 set from a std::uint16_t bit pattern).
    const std::int64_t as_entry = is_signed(entry->type())
                                      ? static_cast<std::int64_t>(static_cast<std::make_signed_t<T>>(value))
                                      : static_cast<std::int64_t>(static_cast<std::make_unsigned_t<T>>(value));
    return set_int(index, sub, as_entry);
  }

 private:
  ObjectEntry* find_mutable(std::uint16_t index, std::uint8_t sub) noexcept;
  core::Expected<ObjectEntry*> insert(std::uint16_t index, std::uint8_t sub);

  std::array<ObjectEntry, kObjectDictionaryCapacity> entries_{};  // sorted by (index, sub)
  std::size_t count_ = 0;
  ObjectDictionaryObserver* observer_ = nullptr;
};

}  // namespace trainer::hal::canopen
