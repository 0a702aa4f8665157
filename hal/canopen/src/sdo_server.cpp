// SDO server over the object dictionary (CiA 301 v4.2, 7.2.4.3.3 - 7.2.4.3.8).
#include "trainer/hal_canopen/sdo_server.hpp"

#include <algorithm>

#include "sdo_frames.hpp"
#include "trainer/hal_canopen/frame.hpp"

namespace trainer::hal::canopen {

using detail::kBitExpedited;
using detail::kBitLastSegment;
using detail::kBitSizeIndicated;
using detail::kExpeditedDataBytes;
using detail::kSdoFrameLength;
using detail::kSegmentDataBytes;

void SdoServer::set_node_id(std::uint8_t node_id) noexcept {
  node_id_ = node_id;
  reset();
}

void SdoServer::set_timeout_ns(std::int64_t timeout_ns) noexcept {
  if (timeout_ns > 0) timeout_ns_ = timeout_ns;
}

void SdoServer::reset() noexcept {
  phase_ = Phase::idle;
  pending_tx_.reset();
}

std::uint16_t SdoServer::response_cob_id() const noexcept {
  return static_cast<std::uint16_t>(kCobSdoTxBase + node_id_);
}

std::optional<can_frame> SdoServer::next_tx() noexcept {
  std::optional<can_frame> frame = pending_tx_;
  pending_tx_.reset();
  return frame;
}

void SdoServer::respond(const can_frame& frame) noexcept {
  if (pending_tx_) ++overwritten_;
  pending_tx_ = frame;
}

void SdoServer::send_abort(std::uint16_t index, std::uint8_t sub, std::uint32_t code) noexcept {
  phase_ = Phase::idle;
  last_abort_code_ = code;
  ++aborts_sent_;
  respond(detail::sdo_abort_frame(response_cob_id(), index, sub, code));
}

bool SdoServer::on_frame(const can_frame& frame, std::int64_t now_ns) noexcept {
  if (!is_valid_node_id(node_id_)) return false;
  if (!is_data_frame_with_id(frame, static_cast<std::uint16_t>(kCobSdoRxBase + node_id_)) ||
      frame.len != kSdoFrameLength) {
    return false;
  }
  last_request_ns_ = now_ns;
  switch (sdo_command_specifier(frame.data[0])) {
    case kCsAbort: phase_ = Phase::idle; break;  // never answered
    case kCcsInitiateDownload: on_initiate_download(frame); break;
    case kCcsDownloadSegment: on_download_segment(frame); break;
    case kCcsInitiateUpload: on_initiate_upload(frame); break;
    case kCcsUploadSegment: on_upload_segment(frame); break;
    default:  // block download/upload (5, 6) and 7
      send_abort(detail::sdo_index(frame), detail::sdo_sub(frame), kAbortCommandSpecifier);
      break;
  }
  return true;
}

void SdoServer::on_time(std::int64_t now_ns) noexcept {
  if (phase_ != Phase::idle && now_ns - last_request_ns_ > timeout_ns_) {
    send_abort(index_, sub_, kAbortTimeout);
  }
}

void SdoServer::on_initiate_download(const can_frame& frame) noexcept {
  phase_ = Phase::idle;
  index_ = detail::sdo_index(frame);
  sub_ = detail::sdo_sub(frame);
  const std::uint8_t command = frame.data[0];
  const ObjectEntry* entry = nullptr;
  if (const std::uint32_t code = dictionary_.locate(index_, sub_, &entry); code != 0) {
    return send_abort(index_, sub_, code);
  }
  if (!entry->writable()) return send_abort(index_, sub_, kAbortWriteReadOnly);
  const bool size_indicated = (command & kBitSizeIndicated) != 0;
  if ((command & kBitExpedited) != 0) {
    std::size_t size = kExpeditedDataBytes;
    if (size_indicated) {
      size = kExpeditedDataBytes - ((command >> 2) & 3U);
    } else if (is_numeric(entry->type())) {
      size = data_type_size(entry->type());  // CiA 301 leaves it open; the entry knows
    }
    const std::uint32_t code = dictionary_.write(index_, sub_, {frame.data + 4, size});
    if (code != 0) return send_abort(index_, sub_, code);
    return respond(detail::sdo_initiate_frame(response_cob_id(),
                                              static_cast<std::uint8_t>(kScsInitiateDownload << 5), index_, sub_));
  }
  indicated_size_.reset();
  if (size_indicated) {
    const std::uint32_t size = detail::get_u32(frame.data + 4);
    if (const std::uint32_t code = ObjectDictionary::check_length(*entry, size); code != 0) {
      return send_abort(index_, sub_, code);
    }
    if (size > kMaxTransferBytes) return send_abort(index_, sub_, kAbortOutOfMemory);
    indicated_size_ = size;
  }
  capacity_ = entry->capacity();
  size_ = 0;
  toggle_ = 0;
  phase_ = Phase::download_segment;
  respond(detail::sdo_initiate_frame(response_cob_id(), static_cast<std::uint8_t>(kScsInitiateDownload << 5),
                                     index_, sub_));
}

void SdoServer::on_download_segment(const can_frame& frame) noexcept {
  if (phase_ != Phase::download_segment) return send_abort(index_, sub_, kAbortCommandSpecifier);
  const std::uint8_t command = frame.data[0];
  if (detail::sdo_toggle(frame) != toggle_) return send_abort(index_, sub_, kAbortToggleBit);
  const std::size_t count = kSegmentDataBytes - ((command >> 1) & 7U);
  if (size_ + count > capacity_) return send_abort(index_, sub_, kAbortLengthTooHigh);
  if (size_ + count > kMaxTransferBytes) return send_abort(index_, sub_, kAbortOutOfMemory);
  std::copy_n(frame.data + 1, count, buffer_.begin() + static_cast<std::ptrdiff_t>(size_));
  size_ += count;
  const std::uint8_t toggle = toggle_;
  if ((command & kBitLastSegment) != 0) {
    if (indicated_size_ && *indicated_size_ != size_) return send_abort(index_, sub_, kAbortLengthMismatch);
    const std::uint32_t code = dictionary_.write(index_, sub_, {buffer_.data(), size_});
    if (code != 0) return send_abort(index_, sub_, code);
    phase_ = Phase::idle;
  } else {
    toggle_ = static_cast<std::uint8_t>(toggle_ ^ 1U);
  }
  can_frame response = detail::sdo_frame(response_cob_id());
  response.data[0] = static_cast<std::uint8_t>((kScsDownloadSegment << 5) | (toggle << 4));
  respond(response);
}

void SdoServer::on_initiate_upload(const can_frame& frame) noexcept {
  phase_ = Phase::idle;
  index_ = detail::sdo_index(frame);
  sub_ = detail::sdo_sub(frame);
  std::size_t size = 0;
  if (const std::uint32_t code = dictionary_.read(index_, sub_, buffer_, size); code != 0) {
    return send_abort(index_, sub_, code);
  }
  if (size >= 1 && size <= kExpeditedDataBytes) {
    return respond(detail::sdo_expedited_frame(response_cob_id(), kScsInitiateUpload, index_, sub_,
                                               {buffer_.data(), size}));
  }
  // Segmented, also for an empty value (an expedited response cannot carry 0 bytes).
  size_ = size;
  offset_ = 0;
  toggle_ = 0;
  phase_ = Phase::upload_segment;
  respond(detail::sdo_segmented_initiate_frame(response_cob_id(), kScsInitiateUpload, index_, sub_,
                                               static_cast<std::uint32_t>(size)));
}

void SdoServer::on_upload_segment(const can_frame& frame) noexcept {
  if (phase_ != Phase::upload_segment) return send_abort(index_, sub_, kAbortCommandSpecifier);
  if (detail::sdo_toggle(frame) != toggle_) return send_abort(index_, sub_, kAbortToggleBit);
  const std::size_t count = std::min(kSegmentDataBytes, size_ - offset_);
  const bool last = offset_ + count == size_;
  respond(detail::sdo_segment_frame(response_cob_id(), kScsUploadSegment, toggle_, {buffer_.data() + offset_, count},
                                    last));
  offset_ += count;
  if (last) {
    phase_ = Phase::idle;
  } else {
    toggle_ = static_cast<std::uint8_t>(toggle_ ^ 1U);
  }
}

}  // namespace trainer::hal::canopen
