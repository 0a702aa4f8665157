// Object indices of the CiA 301 v4.2 communication profile area used by the master and
// the simulated drive (the CiA 402 ones are in cia402.hpp).
//
// Usage: sdo.start_upload(node, kObjectIdentity, kIdentityVendorId, buffer, now_ns);
#pragma once

#include <cstdint>

namespace trainer::hal::canopen {

inline constexpr std::uint16_t kObjectDeviceType = 0x1000;         // u32: profile (402) | additional info
inline constexpr std::uint16_t kObjectErrorRegister = 0x1001;      // u8, bits in emcy.hpp
inline constexpr std::uint16_t kObjectPreDefinedErrorField = 0x1003;  // error history
inline constexpr std::uint16_t kObjectCobIdSync = 0x1005;          // u32
inline constexpr std::uint16_t kObjectCommunicationCyclePeriod = 0x1006;  // u32, us
inline constexpr std::uint16_t kObjectDeviceName = 0x1008;         // visible string
inline constexpr std::uint16_t kObjectCobIdEmcy = 0x1014;          // u32
inline constexpr std::uint16_t kObjectInhibitTimeEmcy = 0x1015;    // u16, 100 us
inline constexpr std::uint16_t kObjectConsumerHeartbeatTime = 0x1016;  // u32 array: node << 16 | ms
inline constexpr std::uint16_t kObjectProducerHeartbeatTime = 0x1017;  // u16, ms
inline constexpr std::uint16_t kObjectIdentity = 0x1018;           // record, sub 1..4
inline constexpr std::uint16_t kObjectSyncCounterOverflow = 0x1019;  // u8, 0 or 2..240
inline constexpr std::uint16_t kObjectRpdoCommunicationFirst = 0x1400;
inline constexpr std::uint16_t kObjectRpdoMappingFirst = 0x1600;
inline constexpr std::uint16_t kObjectTpdoCommunicationFirst = 0x1800;
inline constexpr std::uint16_t kObjectTpdoMappingFirst = 0x1A00;

inline constexpr std::uint8_t kIdentityVendorId = 1;
inline constexpr std::uint8_t kIdentityProductCode = 2;
inline constexpr std::uint8_t kIdentityRevision = 3;
inline constexpr std::uint8_t kIdentitySerialNumber = 4;

// 0x1000 low 16 bits for a drive: device profile 402.
inline constexpr std::uint32_t kDeviceProfileDrive = 402;

}  // namespace trainer::hal::canopen
