// SDO protocol basics shared by SdoClient (sdo_client.hpp) and SdoServer (sdo_server.hpp):
// abort codes with their CiA 301 v4.2 meanings (Table 22), the transfer status, and the
// command-byte layout (CiA 301 7.2.4.3) for whoever needs to read raw frames.
//
// Frames: request 0x600 + node (client -> server), response 0x580 + node; always 8 bytes:
//   byte 0 command specifier, bytes 1..2 index (little-endian), byte 3 sub-index,
//   bytes 4..7 data / size / abort code. Segments use bytes 1..7 for data.
//
// Usage:  if (client.status() == SdoStatus::aborted)
//           log(describe_sdo_abort(client.abort_code()));
#pragma once

#include <cstdint>

namespace trainer::hal::canopen {

// --- Abort codes (CiA 301 v4.2, 7.2.4.3.17, Table 22) ---------------------------------------
inline constexpr std::uint32_t kAbortToggleBit = 0x05030000;          // toggle bit not alternated
inline constexpr std::uint32_t kAbortTimeout = 0x05040000;            // SDO protocol timed out
inline constexpr std::uint32_t kAbortCommandSpecifier = 0x05040001;   // command specifier invalid
inline constexpr std::uint32_t kAbortBlockSize = 0x05040002;          // block mode only
inline constexpr std::uint32_t kAbortSequenceNumber = 0x05040003;     // block mode only
inline constexpr std::uint32_t kAbortCrc = 0x05040004;                // block mode only
inline constexpr std::uint32_t kAbortOutOfMemory = 0x05040005;
inline constexpr std::uint32_t kAbortUnsupportedAccess = 0x06010000;
inline constexpr std::uint32_t kAbortReadWriteOnly = 0x06010001;      // read of a write-only object
inline constexpr std::uint32_t kAbortWriteReadOnly = 0x06010002;      // write of a read-only object
inline constexpr std::uint32_t kAbortNoObject = 0x06020000;           // object does not exist
inline constexpr std::uint32_t kAbortNotMappable = 0x06040041;        // cannot be mapped to a PDO
inline constexpr std::uint32_t kAbortPdoLength = 0x06040042;          // mapping exceeds PDO length
inline constexpr std::uint32_t kAbortParameterIncompatible = 0x06040043;
inline constexpr std::uint32_t kAbortInternalIncompatible = 0x06040047;
inline constexpr std::uint32_t kAbortHardware = 0x06060000;
inline constexpr std::uint32_t kAbortLengthMismatch = 0x06070010;     // data type / length mismatch
inline constexpr std::uint32_t kAbortLengthTooHigh = 0x06070012;
inline constexpr std::uint32_t kAbortLengthTooLow = 0x06070013;
inline constexpr std::uint32_t kAbortNoSubIndex = 0x06090011;         // sub-index does not exist
inline constexpr std::uint32_t kAbortInvalidValue = 0x06090030;       // value range exceeded
inline constexpr std::uint32_t kAbortValueTooHigh = 0x06090031;
inline constexpr std::uint32_t kAbortValueTooLow = 0x06090032;
inline constexpr std::uint32_t kAbortMaxBelowMin = 0x06090036;
inline constexpr std::uint32_t kAbortResourceUnavailable = 0x060A0023;  // SDO connection
inline constexpr std::uint32_t kAbortGeneral = 0x08000000;
inline constexpr std::uint32_t kAbortCannotStore = 0x08000020;        // cannot transfer/store
inline constexpr std::uint32_t kAbortLocalControl = 0x08000021;       // ... because of local control
inline constexpr std::uint32_t kAbortDeviceState = 0x08000022;        // ... present device state
inline constexpr std::uint32_t kAbortNoDictionary = 0x08000023;       // OD generation failed / none
inline constexpr std::uint32_t kAbortNoData = 0x08000024;             // no data available

// Meaning of an abort code; "unknown abort code" for values outside the table. Never null.
const char* describe_sdo_abort(std::uint32_t abort_code) noexcept;

// --- Command byte (byte 0) -------------------------------------------------------------------
// Client command specifiers (bits 7..5 of a request) and server command specifiers (of a
// response). Block transfer (client 5/6, server 5/6) is not implemented: a server answers
// those with kAbortCommandSpecifier.
inline constexpr std::uint8_t kCcsDownloadSegment = 0;
inline constexpr std::uint8_t kCcsInitiateDownload = 1;
inline constexpr std::uint8_t kCcsInitiateUpload = 2;
inline constexpr std::uint8_t kCcsUploadSegment = 3;
inline constexpr std::uint8_t kScsUploadSegment = 0;
inline constexpr std::uint8_t kScsDownloadSegment = 1;
inline constexpr std::uint8_t kScsInitiateUpload = 2;
inline constexpr std::uint8_t kScsInitiateDownload = 3;
inline constexpr std::uint8_t kCsAbort = 4;
// Initiate: bits 3..2 n (bytes of 4..7 without data, valid when e and s), bit 1 e
// (expedited), bit 0 s (size indicated). Segment: bit 4 t (toggle), bits 3..1 n (bytes of
// 1..7 without data), bit 0 c (no more segments).
constexpr std::uint8_t sdo_command_specifier(std::uint8_t command_byte) noexcept {
  return static_cast<std::uint8_t>(command_byte >> 5);
}

// Where an SDO transfer stands (client and server).
enum class SdoStatus : std::uint8_t {
  idle,       // nothing started yet
  busy,       // waiting for the peer
  done,       // finished; transferred_bytes() valid
  aborted,    // an abort was received, or sent because of a protocol error; abort_code()
  timed_out,  // no response within the timeout; abort 0x05040000 sent
};
const char* to_string(SdoStatus status) noexcept;

}  // namespace trainer::hal::canopen
