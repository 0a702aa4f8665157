// Object dictionary storage, lookup (binary search over (index, sub)) and the remote
// access rules of CiA 301 v4.2 (access types, length and value-range aborts).
#include "trainer/hal_canopen/object_dictionary.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>
#include <string>

#include "bytes.hpp"
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen {

namespace {

std::string object_name(std::uint16_t index, std::uint8_t sub) {
  char text[32];
  std::snprintf(text, sizeof(text), "object 0x%04X:%02X", static_cast<unsigned>(index),
                static_cast<unsigned>(sub));
  return text;
}

struct TypeRange {
  std::int64_t low;
  std::int64_t high;
};

TypeRange type_range(DataType type) noexcept {
  switch (type) {
    case DataType::i8: return {std::numeric_limits<std::int8_t>::min(), std::numeric_limits<std::int8_t>::max()};
    case DataType::i16: return {std::numeric_limits<std::int16_t>::min(), std::numeric_limits<std::int16_t>::max()};
    case DataType::i32: return {std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()};
    case DataType::u8: return {0, std::numeric_limits<std::uint8_t>::max()};
    case DataType::u16: return {0, std::numeric_limits<std::uint16_t>::max()};
    case DataType::u32: return {0, std::numeric_limits<std::uint32_t>::max()};
    default: return {0, 0};
  }
}

bool fits_type(DataType type, std::int64_t value) noexcept {
  const TypeRange range = type_range(type);
  return value >= range.low && value <= range.high;
}

// Little-endian bytes of a numeric type -> value, sign-extended for signed types.
std::int64_t decode_numeric(DataType type, const std::uint8_t* bytes) noexcept {
  const std::size_t size = data_type_size(type);
  const std::uint64_t raw = detail::get_le(bytes, size);
  if (is_signed(type) && size < 8) {
    const std::uint64_t sign_bit = std::uint64_t{1} << (8 * size - 1);
    if ((raw & sign_bit) != 0) {
      return static_cast<std::int64_t>(raw | ~((sign_bit << 1) - 1));
    }
  }
  return static_cast<std::int64_t>(raw);
}

}  // namespace

const char* to_string(DataType type) noexcept {
  switch (type) {
    case DataType::i8: return "INTEGER8";
    case DataType::i16: return "INTEGER16";
    case DataType::i32: return "INTEGER32";
    case DataType::u8: return "UNSIGNED8";
    case DataType::u16: return "UNSIGNED16";
    case DataType::u32: return "UNSIGNED32";
    case DataType::visible_string: return "VISIBLE_STRING";
    case DataType::domain: return "DOMAIN";
  }
  return "?";
}

std::size_t data_type_size(DataType type) noexcept {
  switch (type) {
    case DataType::i8:
    case DataType::u8: return 1;
    case DataType::i16:
    case DataType::u16: return 2;
    case DataType::i32:
    case DataType::u32: return 4;
    default: return 0;
  }
}

bool is_signed(DataType type) noexcept {
  return type == DataType::i8 || type == DataType::i16 || type == DataType::i32;
}
bool is_numeric(DataType type) noexcept { return data_type_size(type) != 0; }

const char* to_string(Access access) noexcept {
  switch (access) {
    case Access::ro: return "ro";
    case Access::wo: return "wo";
    case Access::rw: return "rw";
    case Access::constant: return "const";
  }
  return "?";
}

// --- ObjectEntry ---------------------------------------------------------------------------

std::span<const std::uint8_t> ObjectEntry::bytes() const noexcept { return {storage(), size_}; }

std::size_t ObjectEntry::capacity() const noexcept {
  if (is_numeric(type_)) return data_type_size(type_);
  return external_ != nullptr ? external_capacity_ : kMaxStringBytes;
}

std::int64_t ObjectEntry::as_int() const noexcept {
  return is_numeric(type_) ? decode_numeric(type_, storage()) : 0;
}

std::string_view ObjectEntry::as_string() const noexcept {
  return {reinterpret_cast<const char*>(storage()), size_};
}

// --- setup -----------------------------------------------------------------------------------

core::Expected<ObjectEntry*> ObjectDictionary::insert(std::uint16_t index, std::uint8_t sub) {
  if (count_ == entries_.size()) {
    return core::make_error(object_name(index, sub) + ": object dictionary full (" +
                            std::to_string(entries_.size()) + " entries)");
  }
  const std::uint32_t key = (static_cast<std::uint32_t>(index) << 8) | sub;
  auto* end = entries_.data() + count_;
  auto* position = std::lower_bound(entries_.data(), end, key,
                                    [](const ObjectEntry& entry, std::uint32_t value) { return entry.key() < value; });
  if (position != end && position->key() == key) {
    return core::make_error(object_name(index, sub) + ": defined twice");
  }
  std::move_backward(position, end, end + 1);
  ++count_;
  *position = ObjectEntry{};
  position->index_ = index;
  position->sub_ = sub;
  return position;
}

core::Expected<void> ObjectDictionary::add(const ObjectDefinition& definition) {
  const std::string name = object_name(definition.index, definition.sub);
  if (!is_numeric(definition.type)) {
    return core::make_error(name + ": add() takes numeric types; use add_string / add_domain");
  }
  if (!fits_type(definition.type, definition.value)) {
    return core::make_error(name + ": initial value " + std::to_string(definition.value) +
                            " does not fit " + to_string(definition.type));
  }
  if (definition.min && definition.max && *definition.min > *definition.max) {
    return core::make_error(name + ": min " + std::to_string(*definition.min) + " > max " +
                            std::to_string(*definition.max));
  }
  if ((definition.min && definition.value < *definition.min) ||
      (definition.max && definition.value > *definition.max)) {
    return core::make_error(name + ": initial value " + std::to_string(definition.value) +
                            " outside its min/max");
  }
  auto inserted = insert(definition.index, definition.sub);
  if (!inserted) return std::move(inserted).error();
  ObjectEntry& entry = **inserted;
  entry.type_ = definition.type;
  entry.access_ = definition.access;
  entry.pdo_mappable_ = definition.pdo_mappable;
  entry.has_min_ = definition.min.has_value();
  entry.min_ = definition.min.value_or(0);
  entry.has_max_ = definition.max.has_value();
  entry.max_ = definition.max.value_or(0);
  entry.size_ = static_cast<std::uint32_t>(data_type_size(definition.type));
  detail::put_le(entry.inline_.data(), entry.size_, static_cast<std::uint64_t>(definition.value));
  return {};
}

core::Expected<void> ObjectDictionary::add_string(std::uint16_t index, std::uint8_t sub, Access access,
                                                  std::string_view value) {
  if (value.size() > kMaxStringBytes) {
    return core::make_error(object_name(index, sub) + ": string of " + std::to_string(value.size()) +
                            " bytes; at most " + std::to_string(kMaxStringBytes));
  }
  auto inserted = insert(index, sub);
  if (!inserted) return std::move(inserted).error();
  ObjectEntry& entry = **inserted;
  entry.type_ = DataType::visible_string;
  entry.access_ = access;
  entry.size_ = static_cast<std::uint32_t>(value.size());
  std::copy(value.begin(), value.end(), entry.inline_.begin());
  return {};
}

core::Expected<void> ObjectDictionary::add_domain(std::uint16_t index, std::uint8_t sub, Access access,
                                                  std::span<std::uint8_t> storage, std::size_t size) {
  if (storage.empty() || storage.size() > std::numeric_limits<std::uint32_t>::max() || size > storage.size()) {
    return core::make_error(object_name(index, sub) + ": domain storage empty, too large, or size beyond it");
  }
  auto inserted = insert(index, sub);
  if (!inserted) return std::move(inserted).error();
  ObjectEntry& entry = **inserted;
  entry.type_ = DataType::domain;
  entry.access_ = access;
  entry.external_ = storage.data();
  entry.external_capacity_ = static_cast<std::uint32_t>(storage.size());
  entry.size_ = static_cast<std::uint32_t>(size);
  return {};
}

// --- lookup ------------------------------------------------------------------------------

std::uint32_t ObjectDictionary::locate(std::uint16_t index, std::uint8_t sub,
                                       const ObjectEntry** entry) const noexcept {
  const std::uint32_t key = (static_cast<std::uint32_t>(index) << 8) | sub;
  const ObjectEntry* end = entries_.data() + count_;
  const ObjectEntry* position = std::lower_bound(
      entries_.data(), end, key, [](const ObjectEntry& e, std::uint32_t value) { return e.key() < value; });
  if (position != end && position->key() == key) {
    *entry = position;
    return 0;
  }
  *entry = nullptr;
  // The index exists when the first entry at or after (index, 0) has that index.
  const ObjectEntry* first = std::lower_bound(
      entries_.data(), end, static_cast<std::uint32_t>(index) << 8,
      [](const ObjectEntry& e, std::uint32_t value) { return e.key() < value; });
  return (first != end && first->index() == index) ? kAbortNoSubIndex : kAbortNoObject;
}

const ObjectEntry* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const noexcept {
  const ObjectEntry* entry = nullptr;
  return locate(index, sub, &entry) == 0 ? entry : nullptr;
}

ObjectEntry* ObjectDictionary::find_mutable(std::uint16_t index, std::uint8_t sub) noexcept {
  const ObjectEntry* entry = find(index, sub);
  return entry == nullptr ? nullptr : entries_.data() + (entry - entries_.data());
}

// --- remote access -----------------------------------------------------------------------

std::uint32_t ObjectDictionary::check_length(const ObjectEntry& entry, std::size_t size) noexcept {
  if (is_numeric(entry.type())) {
    const std::size_t expected = data_type_size(entry.type());
    if (size < expected) return kAbortLengthTooLow;
    if (size > expected) return kAbortLengthTooHigh;
    return 0;
  }
  return size > entry.capacity() ? kAbortLengthTooHigh : 0;
}

std::uint32_t ObjectDictionary::read(std::uint16_t index, std::uint8_t sub, std::span<std::uint8_t> out,
                                     std::size_t& size) const noexcept {
  size = 0;
  const ObjectEntry* entry = nullptr;
  if (const std::uint32_t code = locate(index, sub, &entry); code != 0) return code;
  if (!entry->readable()) return kAbortReadWriteOnly;
  const std::span<const std::uint8_t> value = entry->bytes();
  if (value.size() > out.size()) return kAbortOutOfMemory;
  std::copy(value.begin(), value.end(), out.begin());
  size = value.size();
  return 0;
}

std::uint32_t ObjectDictionary::write(std::uint16_t index, std::uint8_t sub,
                                      std::span<const std::uint8_t> value) noexcept {
  const ObjectEntry* found = nullptr;
  if (const std::uint32_t code = locate(index, sub, &found); code != 0) return code;
  ObjectEntry& entry = entries_[static_cast<std::size_t>(found - entries_.data())];
  if (!entry.writable()) return kAbortWriteReadOnly;
  if (const std::uint32_t code = check_length(entry, value.size()); code != 0) return code;
  if (is_numeric(entry.type())) {
    const std::int64_t number = decode_numeric(entry.type(), value.data());
    if (entry.has_max_ && number > entry.max_) return kAbortValueTooHigh;
    if (entry.has_min_ && number < entry.min_) return kAbortValueTooLow;
  }
  if (observer_ != nullptr) {
    if (const std::uint32_t code = observer_->validate_write(entry, value); code != 0) return code;
  }
  std::copy(value.begin(), value.end(), entry.storage());
  entry.size_ = static_cast<std::uint32_t>(value.size());
  if (observer_ != nullptr) observer_->on_written(entry);
  return 0;
}

// --- local access ------------------------------------------------------------------------

std::optional<std::int64_t> ObjectDictionary::get_int(std::uint16_t index, std::uint8_t sub) const noexcept {
  const ObjectEntry* entry = find(index, sub);
  if (entry == nullptr || !is_numeric(entry->type())) return std::nullopt;
  return entry->as_int();
}

core::Status ObjectDictionary::set_int(std::uint16_t index, std::uint8_t sub, std::int64_t value) noexcept {
  ObjectEntry* entry = find_mutable(index, sub);
  if (entry == nullptr || !is_numeric(entry->type())) {
    return {core::StatusCode::invalid_argument, "object dictionary: no numeric entry"};
  }
  if (!fits_type(entry->type(), value)) {
    return {core::StatusCode::invalid_argument, "object dictionary: value does not fit the type"};
  }
  detail::put_le(entry->storage(), entry->size_, static_cast<std::uint64_t>(value));
  return core::Status::ok();
}

core::Status ObjectDictionary::set_bytes(std::uint16_t index, std::uint8_t sub,
                                         std::span<const std::uint8_t> value) noexcept {
  ObjectEntry* entry = find_mutable(index, sub);
  if (entry == nullptr) return {core::StatusCode::invalid_argument, "object dictionary: no entry"};
  if (check_length(*entry, value.size()) != 0) {
    return {core::StatusCode::invalid_argument, "object dictionary: length does not fit the entry"};
  }
  std::copy(value.begin(), value.end(), entry->storage());
  entry->size_ = static_cast<std::uint32_t>(value.size());
  return core::Status::ok();
}

}  // namespace trainer::hal::canopen
