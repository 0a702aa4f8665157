// The telemetry sender over a real loopback UDP socket: frames arrive decodable with rising
// sequence numbers at the configured schedule; a snapshot already sent is not sent again;
// nobody listening (ICMP port unreachable → ECONNREFUSED) is counted, never fatal; sending
// allocates nothing; bad destinations are refused at create().
#include "trainer/app/telemetry_sender.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <memory>
#include <vector>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace trainer::app {
namespace {

constexpr std::int64_t kPeriodNs = 1'000'000'000 / 60;

// A UDP socket bound to 127.0.0.1 on a port the kernel picks.
class LoopbackReceiver {
 public:
  LoopbackReceiver() {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    socklen_t length = sizeof address;
    EXPECT_EQ(getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &length), 0);
    port_ = ntohs(address.sin_port);
  }
  ~LoopbackReceiver() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  std::uint16_t port() const { return port_; }
  // Every datagram waiting now.
  std::vector<std::vector<std::byte>> drain() {
    std::vector<std::vector<std::byte>> out;
    std::vector<std::byte> buffer(70000);
    for (;;) {
      const ssize_t n = recv(fd_, buffer.data(), buffer.size(), 0);
      if (n < 0) break;
      out.emplace_back(buffer.begin(), buffer.begin() + n);
    }
    return out;
  }

 private:
  int fd_ = -1;
  std::uint16_t port_ = 0;
};

config::TelemetryConfig loopback(std::uint16_t port) {
  config::TelemetryConfig config;
  config.enabled = true;
  config.address = "127.0.0.1";
  config.port = port;
  config.rate_hz = 60;
  return config;
}

std::unique_ptr<TelemetrySnapshot> sample_snapshot() {
  auto snapshot = std::make_unique<TelemetrySnapshot>();
  snapshot->cycle = 100;
  snapshot->time_ns = 5'000'000;
  snapshot->latched_faults = 0x40;
  snapshot->instrument_count = 2;
  snapshot->instruments[0].joints = {0.1F, 0.2F, 0.05F, 0.3F, 0.4F};
  snapshot->instruments[0].tip_m = {0.01F, 0.02F, -0.1F};
  snapshot->instruments[0].hinge_m = {0.01F, 0.02F, -0.085F};
  snapshot->instruments[0].shaft_start_m = {0.0F, 0.0F, 0.27F};
  snapshot->instruments[0].opening_direction = {0.0F, 1.0F, 0.0F};
  snapshot->instruments[0].force_n = {1.0F, 0.0F, 0.0F};
  snapshot->instruments[0].stream_flags = telemetry::kInstrumentGrasping;
  snapshot->model_count = 2;
  telemetry::ModelState& duct = snapshot->models[0];
  duct.kind = telemetry::ModelKind::modal;
  duct.scene_index = 0;
  duct.image_checksum = 0xABCDEF;
  duct.flags = telemetry::kModalStaticCorrection;
  duct.mode_count = 40;
  duct.load_count = 2;
  duct.loads[1] = {300, {0.5F, 0.0F, -0.5F}};
  // Stale data beyond the counts (the triple buffer's slot from an earlier cycle) must not
  // travel.
  duct.contact_count = 7;
  duct.particle_count = 9;
  telemetry::ModelState& catheter = snapshot->models[1];
  catheter.kind = telemetry::ModelKind::catheter;
  catheter.scene_index = 1;
  catheter.particle_count = 11;
  catheter.particles_m[10] = {0.1F, 0.2F, 0.3F};
  snapshot->contact_count = 1;
  snapshot->contacts[0] = {0, telemetry::kNoModel, telemetry::ContactKind::jaw1,
                           {0.0F, 0.0F, -0.1F}, {0.0F, 0.0F, 0.2F}};
  return snapshot;
}

TEST(TelemetrySender, FramesArriveDecodableInOrderAtTheSchedule) {
  LoopbackReceiver receiver;
  auto sender = TelemetrySender::create(loopback(receiver.port()), "sim.toml");
  ASSERT_TRUE(sender) << sender.error().message;
  auto snapshot = sample_snapshot();
  std::int64_t now = 1'000'000'000;
  EXPECT_LE((*sender)->ns_until_due(now), 0);
  for (int k = 0; k < 10; ++k) {
    snapshot->cycle = 100 + static_cast<std::uint64_t>(k);
    (*sender)->send_if_due(*snapshot, now);
    EXPECT_EQ((*sender)->ns_until_due(now), kPeriodNs);
    (*sender)->send_if_due(*snapshot, now + kPeriodNs / 2);  // not due: nothing sent
    now += kPeriodNs;
  }
  const auto datagrams = receiver.drain();
  ASSERT_EQ(datagrams.size(), 10U);
  auto frame = std::make_unique<telemetry::Frame>();
  for (std::size_t k = 0; k < datagrams.size(); ++k) {
    const telemetry::DecodeResult r = telemetry::decode(datagrams[k], *frame);
    ASSERT_TRUE(r.ok()) << telemetry::to_string(r.error) << ": " << r.detail;
    EXPECT_EQ(frame->sequence, k);
    EXPECT_EQ(frame->cycle, 100 + k);
    EXPECT_EQ(frame->stream_id, (*sender)->stats().stream_id);
  }
  // The last frame's content is the snapshot's, used part only.
  EXPECT_EQ(frame->latched_faults, 0x40U);
  ASSERT_EQ(frame->model_count, 2U);
  EXPECT_EQ(frame->models[0].image_checksum, 0xABCDEFU);
  EXPECT_EQ(frame->models[0].mode_count, 40U);
  EXPECT_EQ(frame->models[0].load_count, 2U);
  EXPECT_EQ(frame->models[0].loads[1].node, 300U);
  EXPECT_EQ(frame->models[0].contact_count, 0U);
  EXPECT_EQ(frame->models[0].particle_count, 0U);
  EXPECT_EQ(frame->models[1].particle_count, 11U);
  EXPECT_EQ(frame->models[1].particles_m[10], (std::array<float, 3>{0.1F, 0.2F, 0.3F}));
  ASSERT_EQ(frame->instrument_count, 2U);
  EXPECT_EQ(frame->instruments[0].grip_rad, 0.4F);
  EXPECT_EQ(frame->instruments[0].hinge_m, (std::array<float, 3>{0.01F, 0.02F, -0.085F}));
  EXPECT_EQ(frame->instruments[0].flags, telemetry::kInstrumentGrasping);
  ASSERT_EQ(frame->contact_count, 1U);
  EXPECT_EQ(frame->contacts[0].kind, telemetry::ContactKind::jaw1);
  const TelemetrySenderStats stats = (*sender)->stats();
  EXPECT_EQ(stats.frames_sent, 10U);
  EXPECT_EQ(stats.send_errors, 0U);
  EXPECT_EQ(stats.bytes_max, datagrams.back().size());
  EXPECT_EQ(stats.bytes_p50, datagrams.front().size());
}

// The frames a recording keeps (channel 2): the sink gets every frame encoded, the same bytes
// the socket sends; an unsent encoder (no destination) hands them over at the same schedule.
TEST(TelemetrySender, TheFrameSinkGetsTheBytesSentAndAnUnsentEncoderSendsNothing) {
  LoopbackReceiver receiver;
  auto sender = TelemetrySender::create(loopback(receiver.port()), "sim.toml");
  ASSERT_TRUE(sender) << sender.error().message;
  std::vector<std::vector<std::byte>> sunk;
  std::vector<std::int64_t> cycle_times;
  (*sender)->set_frame_sink([&](std::span<const std::byte> bytes, const telemetry::Frame& f) {
    sunk.emplace_back(bytes.begin(), bytes.end());
    cycle_times.push_back(f.cycle_time_ns);
  });
  auto snapshot = sample_snapshot();
  std::int64_t now = 1'000'000'000;
  for (int k = 0; k < 5; ++k) {
    snapshot->cycle = 100 + static_cast<std::uint64_t>(k);
    snapshot->time_ns = 5'000'000 + k;
    (*sender)->send_if_due(*snapshot, now);
    now += kPeriodNs;
  }
  const auto datagrams = receiver.drain();
  ASSERT_EQ(datagrams.size(), 5U);
  ASSERT_EQ(sunk.size(), 5U);
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_TRUE(std::equal(sunk[k].begin(), sunk[k].end(), datagrams[k].begin(),
                           datagrams[k].end()));
    EXPECT_EQ(cycle_times[k], 5'000'000 + static_cast<std::int64_t>(k));
  }
  EXPECT_TRUE((*sender)->sends());

  auto unsent = TelemetrySender::create_unsent(loopback(receiver.port()), "sim.toml");
  ASSERT_TRUE(unsent) << unsent.error().message;
  EXPECT_FALSE((*unsent)->sends());
  std::uint64_t frames = 0;
  (*unsent)->set_frame_sink([&](std::span<const std::byte>, const telemetry::Frame&) { ++frames; });
  for (int k = 0; k < 5; ++k) {
    snapshot->cycle = 200 + static_cast<std::uint64_t>(k);
    (*unsent)->send_if_due(*snapshot, now);
    (*unsent)->send_if_due(*snapshot, now + kPeriodNs / 2);  // not due
    now += kPeriodNs;
  }
  (*unsent)->send_final(*snapshot, now);
  EXPECT_EQ(frames, 6U);
  EXPECT_EQ((*unsent)->stats().frames_sent, 0U);
  EXPECT_TRUE(receiver.drain().empty());
  config::TelemetryConfig too_fast = loopback(receiver.port());
  too_fast.rate_hz = 500;
  auto refused = TelemetrySender::create_unsent(too_fast, "sim.toml");
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().message, "sim.toml: telemetry.rate_hz = 500: expected 30 to 120");
}

TEST(TelemetrySender, ASnapshotAlreadySentIsNotSentAgain) {
  LoopbackReceiver receiver;
  auto sender = TelemetrySender::create(loopback(receiver.port()), "sim.toml");
  ASSERT_TRUE(sender) << sender.error().message;
  auto snapshot = sample_snapshot();
  (*sender)->send_if_due(*snapshot, 0);
  (*sender)->send_if_due(*snapshot, kPeriodNs);  // due, same cycle: skipped
  snapshot->cycle += 1;
  (*sender)->send_if_due(*snapshot, 2 * kPeriodNs);
  EXPECT_EQ(receiver.drain().size(), 2U);
  EXPECT_EQ((*sender)->stats().stale_skipped, 1U);
  // After a stall the schedule restarts from now: no burst.
  snapshot->cycle += 1;
  (*sender)->send_if_due(*snapshot, 100 * kPeriodNs);
  EXPECT_EQ((*sender)->ns_until_due(100 * kPeriodNs), kPeriodNs);
  // The final frame goes whatever the schedule, flagged.
  (*sender)->send_final(*snapshot, 100 * kPeriodNs + 1);
  const auto datagrams = receiver.drain();
  ASSERT_EQ(datagrams.size(), 2U);
  auto frame = std::make_unique<telemetry::Frame>();
  ASSERT_TRUE(telemetry::decode(datagrams[1], *frame).ok());
  EXPECT_NE(frame->flags & telemetry::kFlagRunEnded, 0U);
}

TEST(TelemetrySender, NobodyListeningIsCountedNeverFatal) {
  LoopbackReceiver receiver;
  const std::uint16_t port = receiver.port();
  receiver.close();  // the port is now closed: the kernel answers port unreachable
  auto sender = TelemetrySender::create(loopback(port), "sim.toml");
  ASSERT_TRUE(sender) << sender.error().message;
  auto snapshot = sample_snapshot();
  for (int k = 0; k < 20; ++k) {
    snapshot->cycle += 1;
    (*sender)->send_if_due(*snapshot, static_cast<std::int64_t>(k) * kPeriodNs);
  }
  const TelemetrySenderStats stats = (*sender)->stats();
  // Loopback delivers the ICMP error before the next send: every other send reports it.
  EXPECT_GT(stats.refused, 5U);
  EXPECT_EQ(stats.frames_sent + stats.send_errors, 20U);
  EXPECT_EQ(stats.refused, stats.send_errors);
}

TEST(TelemetrySender, SendingAllocatesNothing) {
  LoopbackReceiver receiver;
  auto sender = TelemetrySender::create(loopback(receiver.port()), "sim.toml");
  ASSERT_TRUE(sender) << sender.error().message;
  auto snapshot = sample_snapshot();
  const std::uint64_t before = core::alloc::counted_allocations();
  core::alloc::begin_counting_this_thread();
  // 100 frames: what the receiving socket's default buffer holds without dropping.
  for (int k = 0; k < 100; ++k) {
    snapshot->cycle += 1;
    (*sender)->send_if_due(*snapshot, static_cast<std::int64_t>(k) * kPeriodNs);
  }
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(core::alloc::counted_allocations() - before, 0U);
  EXPECT_EQ(receiver.drain().size(), 100U);
}

TEST(TelemetrySender, BadDestinationsAreRefusedNamingTheFile) {
  config::TelemetryConfig config = loopback(47800);
  config.address = "viewer.local";
  auto named = TelemetrySender::create(config, "devices/sim.toml");
  ASSERT_FALSE(named);
  EXPECT_NE(named.error().message.find("devices/sim.toml: telemetry.address = \"viewer.local\""),
            std::string::npos)
      << named.error().message;
  config = loopback(47800);
  config.rate_hz = 500;
  EXPECT_FALSE(TelemetrySender::create(config, "sim.toml"));
  config = loopback(47800);
  config.address = "::1";
  auto v6 = TelemetrySender::create(config, "sim.toml");
  if (v6) {  // (without IPv6 on this machine connect fails)
    EXPECT_EQ((*v6)->stats().destination, "[::1]:47800");
  }
}

// The cbd scene's worst case the format allows (64 loads on the duct, 16 contact points)
// is 1,858 bytes: trimmed to 1 KiB, the largest loads and contact points kept.
TEST(TelemetrySender, AFrameAboveTheBudgetKeepsItsLargestLoadsAndContacts) {
  auto frame = std::make_unique<telemetry::Frame>();
  frame->model_count = 2;
  telemetry::ModelState& duct = frame->models[0];
  duct.kind = telemetry::ModelKind::modal;
  duct.flags = telemetry::kModalStaticCorrection;
  duct.mode_count = 40;
  duct.load_count = 64;
  for (std::uint32_t k = 0; k < 64; ++k)  // force k+1 N on node k, in scrambled order
    duct.loads[(k * 37) % 64] = {k, {0.0F, 0.0F, static_cast<float>(k + 1)}};
  telemetry::ModelState& catheter = frame->models[1];
  catheter.kind = telemetry::ModelKind::catheter;
  catheter.scene_index = 1;
  catheter.particle_count = 11;
  frame->instrument_count = 2;
  frame->contact_count = 16;
  for (std::uint32_t k = 0; k < 16; ++k)
    frame->contacts[(k * 5) % 16] = {0, telemetry::kNoModel, telemetry::ContactKind::shaft,
                                     {0.0F, 0.0F, 0.0F}, {static_cast<float>(k + 1), 0.0F, 0.0F}};
  ASSERT_EQ(telemetry::encoded_size(*frame), 1858U);
  ASSERT_TRUE(TelemetrySender::trim_to_budget(*frame, TelemetrySender::kFrameBudgetBytes));
  EXPECT_LE(telemetry::encoded_size(*frame), TelemetrySender::kFrameBudgetBytes);
  EXPECT_GT(telemetry::encoded_size(*frame), TelemetrySender::kFrameBudgetBytes - 14);
  ASSERT_EQ(frame->contact_count, 4U);  // the rest of the budget went to loads
  for (std::uint32_t k = 0; k < 4; ++k) EXPECT_EQ(frame->contacts[k].force_n[0], 16.0F - static_cast<float>(k));
  ASSERT_GT(duct.load_count, 0U);
  for (std::uint32_t k = 0; k < duct.load_count; ++k) EXPECT_EQ(duct.loads[k].node, 63 - k);
  EXPECT_NE(duct.flags & telemetry::kModalLoadsTruncated, 0);
  EXPECT_NE(frame->flags & telemetry::kFlagContactsTruncated, 0U);
  // A frame within the budget is left alone.
  EXPECT_FALSE(TelemetrySender::trim_to_budget(*frame, TelemetrySender::kFrameBudgetBytes));
}

}  // namespace
}  // namespace trainer::app
