// SDO client: expedited and segmented download/upload (CiA 301 v4.2, 7.2.4.3.3 - 7.2.4.3.8).
#include "trainer/hal_canopen/sdo_client.hpp"

#include <algorithm>
#include <limits>

#include "sdo_frames.hpp"
#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

using detail::kBitExpedited;
using detail::kBitLastSegment;
using detail::kBitSizeIndicated;
using detail::kExpeditedDataBytes;
using detail::kSdoFrameLength;
using detail::kSegmentDataBytes;

void SdoClient::set_response_timeout_ns(std::int64_t timeout_ns) noexcept {
  if (timeout_ns > 0) timeout_ns_ = timeout_ns;
}

std::uint16_t SdoClient::request_cob_id() const noexcept {
  return static_cast<std::uint16_t>(kCobSdoRxBase + node_id_);
}
std::uint16_t SdoClient::response_cob_id() const noexcept {
  return static_cast<std::uint16_t>(kCobSdoTxBase + node_id_);
}

core::Status SdoClient::check_start(std::uint8_t node_id) const noexcept {
  if (status_ == SdoStatus::busy) return {core::StatusCode::not_ready, "SDO client: a transfer is running"};
  if (!is_valid_node_id(node_id)) return {core::StatusCode::invalid_argument, "SDO client: node id outside 1..127"};
  return core::Status::ok();
}

void SdoClient::begin(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub, std::int64_t now_ns) noexcept {
  node_id_ = node_id;
  index_ = index;
  sub_ = sub;
  status_ = SdoStatus::busy;
  transferred_ = 0;
  in_flight_ = 0;
  last_segment_sent_ = false;
  toggle_ = 0;
  indicated_size_.reset();
  abort_code_ = 0;
  aborted_by_server_ = false;
  request_time_ns_ = now_ns;
  pending_tx_.reset();
}

void SdoClient::queue_request(const can_frame& frame, std::int64_t now_ns) noexcept {
  pending_tx_ = frame;
  request_time_ns_ = now_ns;
}

core::Status SdoClient::start_download(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                                       std::span<const std::uint8_t> data, std::int64_t now_ns) noexcept {
  if (const core::Status status = check_start(node_id); !status) return status;
  if (data.size() > std::numeric_limits<std::uint32_t>::max()) {
    return {core::StatusCode::invalid_argument, "SDO client: more than 2^32-1 bytes"};
  }
  begin(node_id, index, sub, now_ns);
  download_data_ = data;
  upload_buffer_ = {};
  if (!data.empty() && data.size() <= kExpeditedDataBytes) {
    queue_request(detail::sdo_expedited_frame(request_cob_id(), kCcsInitiateDownload, index, sub, data), now_ns);
  } else {
    // Segmented (also for 0 bytes: an expedited transfer cannot say "no data").
    queue_request(detail::sdo_segmented_initiate_frame(request_cob_id(), kCcsInitiateDownload, index, sub,
                                                       static_cast<std::uint32_t>(data.size())),
                  now_ns);
  }
  phase_ = Phase::download_initiate;
  return core::Status::ok();
}

core::Status SdoClient::start_upload(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                                     std::span<std::uint8_t> buffer, std::int64_t now_ns) noexcept {
  if (const core::Status status = check_start(node_id); !status) return status;
  begin(node_id, index, sub, now_ns);
  download_data_ = {};
  upload_buffer_ = buffer;
  queue_request(detail::sdo_initiate_frame(request_cob_id(), static_cast<std::uint8_t>(kCcsInitiateUpload << 5),
                                           index, sub),
                now_ns);
  phase_ = Phase::upload_initiate;
  return core::Status::ok();
}

std::optional<can_frame> SdoClient::next_tx() noexcept {
  std::optional<can_frame> frame = pending_tx_;
  pending_tx_.reset();
  return frame;
}

void SdoClient::fail(std::uint32_t abort_code) noexcept {
  pending_tx_ = detail::sdo_abort_frame(request_cob_id(), index_, sub_, abort_code);
  abort_code_ = abort_code;
  aborted_by_server_ = false;
  status_ = SdoStatus::aborted;
  phase_ = Phase::none;
}

void SdoClient::finish() noexcept {
  status_ = SdoStatus::done;
  phase_ = Phase::none;
}

void SdoClient::abort(std::uint32_t abort_code) noexcept {
  if (status_ != SdoStatus::busy) return;
  fail(abort_code);
}

void SdoClient::on_time(std::int64_t now_ns) noexcept {
  if (status_ != SdoStatus::busy) return;
  if (now_ns - request_time_ns_ > timeout_ns_) {
    fail(kAbortTimeout);
    status_ = SdoStatus::timed_out;
  }
}

bool SdoClient::on_frame(const can_frame& frame, std::int64_t now_ns) noexcept {
  if (node_id_ == 0 || !is_data_frame_with_id(frame, response_cob_id())) return false;
  if (status_ != SdoStatus::busy || frame.len != kSdoFrameLength) {
    ++ignored_frames_;
    return false;
  }
  const std::uint8_t specifier = sdo_command_specifier(frame.data[0]);
  if (specifier == kCsAbort) {
    abort_code_ = detail::get_u32(frame.data + 4);
    aborted_by_server_ = true;
    status_ = SdoStatus::aborted;
    phase_ = Phase::none;
    pending_tx_.reset();  // never answer an abort
    return true;
  }
  switch (phase_) {
    case Phase::download_initiate: on_download_initiate(frame, now_ns); break;
    case Phase::download_segment: on_download_segment(frame, now_ns); break;
    case Phase::upload_initiate: on_upload_initiate(frame, now_ns); break;
    case Phase::upload_segment: on_upload_segment(frame, now_ns); break;
    case Phase::none: break;
  }
  return true;
}

void SdoClient::send_download_segment(std::int64_t now_ns) noexcept {
  const std::size_t remaining = download_data_.size() - transferred_;
  in_flight_ = std::min(remaining, kSegmentDataBytes);
  last_segment_sent_ = in_flight_ == remaining;
  queue_request(detail::sdo_segment_frame(request_cob_id(), kCcsDownloadSegment, toggle_,
                                          download_data_.subspan(transferred_, in_flight_), last_segment_sent_),
                now_ns);
}

void SdoClient::send_upload_segment_request(std::int64_t now_ns) noexcept {
  can_frame request = detail::sdo_frame(request_cob_id());
  request.data[0] = static_cast<std::uint8_t>((kCcsUploadSegment << 5) | (toggle_ << 4));
  queue_request(request, now_ns);
}

void SdoClient::on_download_initiate(const can_frame& frame, std::int64_t now_ns) noexcept {
  if (sdo_command_specifier(frame.data[0]) != kScsInitiateDownload) return fail(kAbortCommandSpecifier);
  if (detail::sdo_index(frame) != index_ || detail::sdo_sub(frame) != sub_) return fail(kAbortGeneral);
  if (!download_data_.empty() && download_data_.size() <= kExpeditedDataBytes) {
    transferred_ = download_data_.size();
    return finish();
  }
  phase_ = Phase::download_segment;
  toggle_ = 0;  // the first segment has t = 0
  send_download_segment(now_ns);
}

void SdoClient::on_download_segment(const can_frame& frame, std::int64_t now_ns) noexcept {
  if (sdo_command_specifier(frame.data[0]) != kScsDownloadSegment) return fail(kAbortCommandSpecifier);
  if (detail::sdo_toggle(frame) != toggle_) return fail(kAbortToggleBit);
  transferred_ += in_flight_;
  in_flight_ = 0;
  if (last_segment_sent_) return finish();
  toggle_ = static_cast<std::uint8_t>(toggle_ ^ 1U);
  send_download_segment(now_ns);
}

void SdoClient::on_upload_initiate(const can_frame& frame, std::int64_t now_ns) noexcept {
  const std::uint8_t command = frame.data[0];
  if (sdo_command_specifier(command) != kScsInitiateUpload) return fail(kAbortCommandSpecifier);
  if (detail::sdo_index(frame) != index_ || detail::sdo_sub(frame) != sub_) return fail(kAbortGeneral);
  const bool size_indicated = (command & kBitSizeIndicated) != 0;
  if ((command & kBitExpedited) != 0) {
    std::size_t size = kExpeditedDataBytes;
    if (size_indicated) {
      size = kExpeditedDataBytes - ((command >> 2) & 3U);
      indicated_size_ = static_cast<std::uint32_t>(size);
    } else {
      // Size not indicated: the data is up to 4 bytes; take what the buffer holds.
      size = std::min(size, upload_buffer_.size());
    }
    if (size > upload_buffer_.size()) return fail(kAbortOutOfMemory);
    std::copy_n(frame.data + 4, size, upload_buffer_.begin());
    transferred_ = size;
    return finish();
  }
  if (size_indicated) {
    const std::uint32_t size = detail::get_u32(frame.data + 4);
    indicated_size_ = size;
    if (size > upload_buffer_.size()) return fail(kAbortOutOfMemory);
  }
  phase_ = Phase::upload_segment;
  toggle_ = 0;
  send_upload_segment_request(now_ns);
}

void SdoClient::on_upload_segment(const can_frame& frame, std::int64_t now_ns) noexcept {
  const std::uint8_t command = frame.data[0];
  if (sdo_command_specifier(command) != kScsUploadSegment) return fail(kAbortCommandSpecifier);
  if (detail::sdo_toggle(frame) != toggle_) return fail(kAbortToggleBit);
  const std::size_t count = kSegmentDataBytes - ((command >> 1) & 7U);
  if (transferred_ + count > upload_buffer_.size()) return fail(kAbortOutOfMemory);
  std::copy_n(frame.data + 1, count, upload_buffer_.begin() + static_cast<std::ptrdiff_t>(transferred_));
  transferred_ += count;
  if ((command & kBitLastSegment) != 0) {
    if (indicated_size_ && *indicated_size_ != transferred_) return fail(kAbortLengthMismatch);
    return finish();
  }
  if (indicated_size_ && transferred_ > *indicated_size_) return fail(kAbortLengthMismatch);
  toggle_ = static_cast<std::uint8_t>(toggle_ ^ 1U);
  send_upload_segment_request(now_ns);
}

}  // namespace trainer::hal::canopen
