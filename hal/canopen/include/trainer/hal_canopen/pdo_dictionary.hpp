// PDOs against an ObjectDictionary (slave side): build a PdoMapping from the raw entries of
// 0x1600../0x1A00.. with the checks CiA 301 asks for, fill a TPDO from the dictionary and
// store a received RPDO into it.
//
// Usage (simulated drive):
//   PdoMapping rpdo1;
//   if (std::uint32_t abort = map_from_dictionary(raw_entries, PdoDirection::receive, od, rpdo1))
//     return abort;                                   // answer the SDO write of 0x1600 sub 0
//   per cycle, operational:
//     unpack_to_dictionary(rpdo1, received_frame, od);   // RPDO -> 0x6040, 0x6071 ...
//     can_frame tpdo = make_frame(cob_id(FrameKind::tpdo, node, 1), {});
//     pack_from_dictionary(tpdo1, od, tpdo);             // 0x6041, 0x6077 ... -> TPDO
#pragma once

#include <linux/can.h>

#include <cstdint>
#include <span>

#include "trainer/core/status.hpp"
#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/pdo.hpp"

namespace trainer::hal::canopen {

// 0 and `out` filled, or the SDO abort code for the first bad entry: object / sub-index
// does not exist (0x06020000 / 0x06090011), not PDO-mappable or a bit length other than the
// object's size (0x06040041), RPDO object not writable (0x06010002) / TPDO object not
// readable (0x06010001), more than 8 entries or 64 bits (0x06040042). `out` is cleared
// first and left empty on failure.
std::uint32_t map_from_dictionary(std::span<const std::uint32_t> raw_entries, PdoDirection direction,
                                  const ObjectDictionary& dictionary, PdoMapping& out) noexcept;

// TPDO: every mapped object's current value into the frame (data and len; can_id untouched).
core::Status pack_from_dictionary(const PdoMapping& mapping, const ObjectDictionary& dictionary,
                                  can_frame& frame) noexcept;
// RPDO: every mapped object from the frame into the dictionary (local writes: no access
// check, no observer). invalid_argument for a frame shorter than the mapping (EMCY 0x8210).
core::Status unpack_to_dictionary(const PdoMapping& mapping, const can_frame& frame,
                                  ObjectDictionary& dictionary) noexcept;

}  // namespace trainer::hal::canopen
