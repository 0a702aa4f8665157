// SdoClient: one SDO transfer at a time to one server node (CiA 301 v4.2, 7.2.4), the
// master's way to read and write a drive's object dictionary. Expedited (1..4 bytes) and
// segmented transfers in both directions; block transfer is not implemented.
//
// Usage (master, per cycle; no I/O here: you send and receive the frames):
//   SdoClient sdo;                                       // response timeout 200 ms default
//   const std::uint8_t mode[1] = {10};                   // CST
//   sdo.start_download(node, 0x6060, 0, mode, now_ns);   // copies nothing: `mode` must
//                                                        // outlive the transfer
//   each cycle:
//     while (auto tx = sdo.next_tx()) send(*tx);
//     for each received frame: sdo.on_frame(frame, now_ns);   // ignores other frames
//     sdo.on_time(now_ns);
//     if (sdo.status() == SdoStatus::done) ...;  if aborted/timed_out: sdo.abort_code()
//   Upload: std::array<std::uint8_t, 64> buf; sdo.start_upload(node, 0x1008, 0, buf, now_ns);
//           ... done -> buf[0 .. sdo.transferred_bytes())
//
// Protocol errors detected by the client (wrong toggle, unexpected command, mismatched
// index, a response larger than the upload buffer, size mismatch) end the transfer as
// `aborted` with the code, and queue the abort frame for next_tx(). A response that does
// not come within the timeout after the last request ends it as `timed_out` and queues an
// abort 0x05040000. An abort received from the server ends it as `aborted`
// (aborted_by_server() true). The timer runs from the now_ns passed with the call that
// queued the request; frames must be 8 bytes long (CiA 301), shorter ones are ignored.
#pragma once

#include <linux/can.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>

#include "trainer/core/status.hpp"
#include "trainer/hal_canopen/sdo.hpp"

namespace trainer::hal::canopen {

class SdoClient {
 public:
  static constexpr std::int64_t kDefaultResponseTimeoutNs = 200'000'000;

  // > 0; used from the next request on.
  void set_response_timeout_ns(std::int64_t timeout_ns) noexcept;
  std::int64_t response_timeout_ns() const noexcept { return timeout_ns_; }

  // Write `data` (0 .. 2^32-1 bytes; 1..4 expedited, else segmented with the size
  // indicated) to node's object index:sub. `data` must stay valid until the transfer ends.
  // not_ready while busy; invalid_argument for a node id outside 1..127.
  core::Status start_download(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data, std::int64_t now_ns) noexcept;
  // Read node's index:sub into `buffer` (must stay valid until the transfer ends). A value
  // larger than the buffer aborts with 0x05040005 (out of memory).
  core::Status start_upload(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                            std::span<std::uint8_t> buffer, std::int64_t now_ns) noexcept;

  // The next frame to send (request or abort), once.
  std::optional<can_frame> next_tx() noexcept;
  // Feeds a received frame; true when it was a response from the server of the current
  // transfer (id 0x580 + node) and was used.
  bool on_frame(const can_frame& frame, std::int64_t now_ns) noexcept;
  // Checks the response deadline.
  void on_time(std::int64_t now_ns) noexcept;
  // Ends the current transfer (if busy) as aborted with `abort_code` and queues the abort
  // frame (e.g. kAbortGeneral when the master gives up).
  void abort(std::uint32_t abort_code) noexcept;

  SdoStatus status() const noexcept { return status_; }
  bool busy() const noexcept { return status_ == SdoStatus::busy; }
  // The code of the abort sent or received (0 unless aborted / timed_out).
  std::uint32_t abort_code() const noexcept { return abort_code_; }
  bool aborted_by_server() const noexcept { return aborted_by_server_; }
  // Bytes acknowledged by the server (download) or received (upload) so far.
  std::size_t transferred_bytes() const noexcept { return transferred_; }
  // Upload: the size the server announced, when it did.
  std::optional<std::uint32_t> indicated_size() const noexcept { return indicated_size_; }
  std::uint8_t node_id() const noexcept { return node_id_; }
  std::uint16_t index() const noexcept { return index_; }
  std::uint8_t sub_index() const noexcept { return sub_; }
  // Frames on the server's COB-ID that could not be used (wrong length, while idle).
  std::uint32_t ignored_frames() const noexcept { return ignored_frames_; }

 private:
  enum class Phase : std::uint8_t { none, download_initiate, download_segment, upload_initiate, upload_segment };

  core::Status check_start(std::uint8_t node_id) const noexcept;
  void begin(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub, std::int64_t now_ns) noexcept;
  void queue_request(const can_frame& frame, std::int64_t now_ns) noexcept;
  void send_download_segment(std::int64_t now_ns) noexcept;
  void send_upload_segment_request(std::int64_t now_ns) noexcept;
  void fail(std::uint32_t abort_code) noexcept;  // local protocol error: abort sent
  void finish() noexcept;
  void on_download_initiate(const can_frame& frame, std::int64_t now_ns) noexcept;
  void on_download_segment(const can_frame& frame, std::int64_t now_ns) noexcept;
  void on_upload_initiate(const can_frame& frame, std::int64_t now_ns) noexcept;
  void on_upload_segment(const can_frame& frame, std::int64_t now_ns) noexcept;
  std::uint16_t request_cob_id() const noexcept;
  std::uint16_t response_cob_id() const noexcept;

  std::int64_t timeout_ns_ = kDefaultResponseTimeoutNs;
  SdoStatus status_ = SdoStatus::idle;
  Phase phase_ = Phase::none;
  std::uint8_t node_id_ = 0;
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::span<const std::uint8_t> download_data_;
  std::span<std::uint8_t> upload_buffer_;
  std::size_t transferred_ = 0;  // acknowledged (download) / received (upload)
  std::size_t in_flight_ = 0;    // bytes of the download segment awaiting its response
  bool last_segment_sent_ = false;
  std::uint8_t toggle_ = 0;
  std::optional<std::uint32_t> indicated_size_;
  std::uint32_t abort_code_ = 0;
  bool aborted_by_server_ = false;
  std::int64_t request_time_ns_ = 0;
  std::optional<can_frame> pending_tx_;
  std::uint32_t ignored_frames_ = 0;
};

}  // namespace trainer::hal::canopen
