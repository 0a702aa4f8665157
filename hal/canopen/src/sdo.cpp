// SDO abort code texts (CiA 301 v4.2, Table 22).
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen {

const char* describe_sdo_abort(std::uint32_t abort_code) noexcept {
  switch (abort_code) {
    case 0: return "no abort";
    case kAbortToggleBit: return "toggle bit not alternated";
    case kAbortTimeout: return "SDO protocol timed out";
    case kAbortCommandSpecifier: return "client/server command specifier not valid or unknown";
    case kAbortBlockSize: return "invalid block size (block mode only)";
    case kAbortSequenceNumber: return "invalid sequence number (block mode only)";
    case kAbortCrc: return "CRC error (block mode only)";
    case kAbortOutOfMemory: return "out of memory";
    case kAbortUnsupportedAccess: return "unsupported access to an object";
    case kAbortReadWriteOnly: return "attempt to read a write-only object";
    case kAbortWriteReadOnly: return "attempt to write a read-only object";
    case kAbortNoObject: return "object does not exist in the object dictionary";
    case kAbortNotMappable: return "object cannot be mapped to the PDO";
    case kAbortPdoLength: return "number and length of the mapped objects would exceed the PDO length";
    case kAbortParameterIncompatible: return "general parameter incompatibility";
    case kAbortInternalIncompatible: return "general internal incompatibility in the device";
    case kAbortHardware: return "access failed due to a hardware error";
    case kAbortLengthMismatch: return "data type does not match: length of service parameter does not match";
    case kAbortLengthTooHigh: return "data type does not match: length of service parameter too high";
    case kAbortLengthTooLow: return "data type does not match: length of service parameter too low";
    case kAbortNoSubIndex: return "sub-index does not exist";
    case kAbortInvalidValue: return "invalid value for parameter (value range exceeded)";
    case kAbortValueTooHigh: return "value of parameter written too high";
    case kAbortValueTooLow: return "value of parameter written too low";
    case kAbortMaxBelowMin: return "maximum value is less than minimum value";
    case kAbortResourceUnavailable: return "resource not available: SDO connection";
    case kAbortGeneral: return "general error";
    case kAbortCannotStore: return "data cannot be transferred or stored to the application";
    case kAbortLocalControl:
      return "data cannot be transferred or stored to the application because of local control";
    case kAbortDeviceState:
      return "data cannot be transferred or stored to the application because of the present device state";
    case kAbortNoDictionary:
      return "object dictionary dynamic generation failed or no object dictionary is present";
    case kAbortNoData: return "no data available";
    default: return "unknown abort code";
  }
}

const char* to_string(SdoStatus status) noexcept {
  switch (status) {
    case SdoStatus::idle: return "idle";
    case SdoStatus::busy: return "busy";
    case SdoStatus::done: return "done";
    case SdoStatus::aborted: return "aborted";
    case SdoStatus::timed_out: return "timed out";
  }
  return "?";
}

}  // namespace trainer::hal::canopen
