// PDO mapping checks against the object dictionary and dictionary-backed pack/unpack.
#include "trainer/hal_canopen/pdo_dictionary.hpp"

#include <array>

#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen {

std::uint32_t map_from_dictionary(std::span<const std::uint32_t> raw_entries, PdoDirection direction,
                                  const ObjectDictionary& dictionary, PdoMapping& out) noexcept {
  out.clear();
  if (raw_entries.size() > PdoMapping::kMaxEntries) return kAbortPdoLength;
  for (const std::uint32_t raw : raw_entries) {
    const PdoMappingEntry entry = decode_mapping_entry(raw);
    const ObjectEntry* object = nullptr;
    if (const std::uint32_t code = dictionary.locate(entry.index, entry.sub, &object); code != 0) {
      out.clear();
      return code;
    }
    if (!object->pdo_mappable() || !is_numeric(object->type()) ||
        entry.bits != 8 * data_type_size(object->type())) {
      out.clear();
      return kAbortNotMappable;
    }
    if (direction == PdoDirection::receive && !object->writable()) {
      out.clear();
      return kAbortWriteReadOnly;
    }
    if (direction == PdoDirection::transmit && !object->readable()) {
      out.clear();
      return kAbortReadWriteOnly;
    }
    if (!out.add(entry.index, entry.sub, entry.bits, is_signed(object->type()))) {
      out.clear();
      return kAbortPdoLength;
    }
  }
  return 0;
}

core::Status pack_from_dictionary(const PdoMapping& mapping, const ObjectDictionary& dictionary,
                                  can_frame& frame) noexcept {
  std::array<std::int64_t, PdoMapping::kMaxEntries> values{};
  for (std::size_t i = 0; i < mapping.size(); ++i) {
    const PdoField& field = mapping[i];
    const auto value = dictionary.get_int(field.object.index, field.object.sub);
    if (!value) return {core::StatusCode::invalid_argument, "TPDO: a mapped object is missing"};
    values[i] = *value;
  }
  return mapping.pack({values.data(), mapping.size()}, frame);
}

core::Status unpack_to_dictionary(const PdoMapping& mapping, const can_frame& frame,
                                  ObjectDictionary& dictionary) noexcept {
  std::array<std::int64_t, PdoMapping::kMaxEntries> values{};
  if (const core::Status status = mapping.unpack(frame, {values.data(), mapping.size()}); !status) return status;
  for (std::size_t i = 0; i < mapping.size(); ++i) {
    const PdoField& field = mapping[i];
    if (const core::Status status = dictionary.set_int(field.object.index, field.object.sub, values[i]); !status) {
      return status;
    }
  }
  return core::Status::ok();
}

}  // namespace trainer::hal::canopen
