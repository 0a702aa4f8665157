// The live source: the trainer's telemetry stream (rt/telemetry wire format, docs/telemetry.md)
// on a UDP socket. Each datagram is decoded (malformed ones refused with the decoder's reason
// and offset), ordered by the telemetry Sequencer (newest wins; duplicates, late and stale
// datagrams dropped and counted, gaps counted as lost), checked against the scene's images
// (every frame carries their checksums: another image is refused with both checksums named),
// and converted to the viewer's SceneFrame.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "frame_source.hpp"
#include "scene_assets.hpp"
#include "trainer/telemetry/sequencer.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::viewer {

// Converts a decoded telemetry frame (times already on CLOCK_REALTIME where the frame allows)
// to the viewer's frame; refuses a frame whose models, kinds or instruments are not the
// scene's, or whose image checksums differ.
core::Expected<void> scene_frame_from_telemetry(const SceneAssets& assets,
                                                const telemetry::Frame& in, SceneFrame& out);

class UdpSource final : public FrameSource {
 public:
  // `endpoint` is "address:port" (IPv4, e.g. 0.0.0.0:47800; port 0 picks a free one).
  static core::Expected<std::unique_ptr<UdpSource>> open(const SceneAssets& assets,
                                                         const std::string& endpoint);
  ~UdpSource() override;
  UdpSource(const UdpSource&) = delete;
  UdpSource& operator=(const UdpSource&) = delete;

  core::Expected<bool> next(SceneFrame& frame, std::chrono::milliseconds timeout) override;
  std::string describe() const override;
  std::string stats_json() const override;
  std::uint16_t port() const noexcept { return port_; }

 private:
  UdpSource(const SceneAssets& assets) : assets_(assets) {}
  const SceneAssets& assets_;
  int fd_ = -1;
  std::string address_;
  std::uint16_t port_ = 0;
  std::vector<std::byte> buffer_;
  std::unique_ptr<telemetry::Frame> decoded_;  // large: on the heap, reused
  telemetry::Sequencer sequencer_;
  std::uint64_t datagrams_ = 0;
  std::uint64_t malformed_ = 0;
  std::uint64_t refused_ = 0;
  double bytes_total_ = 0.0;
  std::size_t bytes_max_ = 0;
  std::size_t bytes_last_ = 0;
};

}  // namespace trainer::viewer
