// SdoServer: the slave's default SDO server (CiA 301 v4.2, 7.2.4) over an ObjectDictionary.
// Expedited and segmented download (write) and upload (read); block transfer requests are
// answered with abort 0x05040001.
//
// Usage (simulated drive, per received frame / per cycle):
//   SdoServer sdo(dictionary, node_id);
//   if (nmt.sdo_allowed()) sdo.on_frame(frame, now_ns);   // ignores frames for others
//   sdo.on_time(now_ns);                                  // segmented-transfer timeout
//   while (auto tx = sdo.next_tx()) send(*tx);
//
// Aborts it answers with: object does not exist 0x06020000, sub-index does not exist
// 0x06090011, write of read-only 0x06010002, read of write-only 0x06010001, length
// 0x06070010/12/13, value too high/low 0x06090031/32 (the entry's min/max), whatever the
// dictionary's observer returns, toggle bit 0x05030000, command specifier 0x05040001,
// timeout 0x05040000, a value beyond kMaxTransferBytes 0x05040005 (out of memory).
// A segmented download is stored only when its last segment arrived and every check
// passed; an upload sends the value as it was when the upload started.
// Requests must be 8-byte data frames (CiA 301); others are ignored. A new initiate while
// a segmented transfer runs starts the new transfer (the client gave up on the old one).
#pragma once

#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "trainer/hal_canopen/object_dictionary.hpp"
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen {

class SdoServer {
 public:
  static constexpr std::size_t kMaxTransferBytes = 1024;
  static constexpr std::int64_t kDefaultTimeoutNs = 1'000'000'000;

  // `dictionary` must outlive the server.
  SdoServer(ObjectDictionary& dictionary, std::uint8_t node_id) noexcept
      : dictionary_(dictionary), node_id_(node_id) {}

  void set_node_id(std::uint8_t node_id) noexcept;  // ends any transfer
  void set_timeout_ns(std::int64_t timeout_ns) noexcept;

  // True when the frame was a request to this server (id 0x600 + node, 8 bytes).
  bool on_frame(const can_frame& frame, std::int64_t now_ns) noexcept;
  // Aborts a segmented transfer the client left waiting longer than the timeout.
  void on_time(std::int64_t now_ns) noexcept;
  // The response (or abort) to send, once. A response not taken before the next request
  // is replaced (counted in overwritten_responses()).
  std::optional<can_frame> next_tx() noexcept;
  // Ends any transfer silently (NMT reset communication).
  void reset() noexcept;

  bool busy() const noexcept { return phase_ != Phase::idle; }
  std::uint32_t last_abort_code() const noexcept { return last_abort_code_; }
  std::uint32_t aborts_sent() const noexcept { return aborts_sent_; }
  std::uint32_t overwritten_responses() const noexcept { return overwritten_; }

 private:
  enum class Phase : std::uint8_t { idle, download_segment, upload_segment };

  void respond(const can_frame& frame) noexcept;
  void send_abort(std::uint16_t index, std::uint8_t sub, std::uint32_t code) noexcept;
  void on_initiate_download(const can_frame& frame) noexcept;
  void on_download_segment(const can_frame& frame) noexcept;
  void on_initiate_upload(const can_frame& frame) noexcept;
  void on_upload_segment(const can_frame& frame) noexcept;
  std::uint16_t response_cob_id() const noexcept;

  ObjectDictionary& dictionary_;
  std::uint8_t node_id_;
  std::int64_t timeout_ns_ = kDefaultTimeoutNs;
  Phase phase_ = Phase::idle;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::uint8_t toggle_ = 0;
  std::optional<std::uint32_t> indicated_size_;
  std::size_t size_ = 0;      // bytes received (download) / of the value (upload)
  std::size_t offset_ = 0;    // upload: bytes sent
  std::size_t capacity_ = 0;  // download: most bytes the entry takes
  std::int64_t last_request_ns_ = 0;
  std::array<std::uint8_t, kMaxTransferBytes> buffer_{};
  std::optional<can_frame> pending_tx_;
  std::uint32_t last_abort_code_ = 0;
  std::uint32_t aborts_sent_ = 0;
  std::uint32_t overwritten_ = 0;
};

}  // namespace trainer::hal::canopen
