// The CAN transport over socketpair(AF_UNIX, SOCK_SEQPACKET): frames cross intact and in
// order, nothing blocks, every frame that cannot move is counted, and the RT calls do not
// touch the heap. The raw SocketCAN path is exercised for its errors here (this kernel may
// have no CAN); over a real kernel bus it runs in the bench VM (tests/benchvm).
#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cstring>

#include <gtest/gtest.h>

#include "trainer/core/alloc_counter.hpp"
#include "trainer/hal_socketcan/can_transport.hpp"

namespace trainer::hal::socketcan {
namespace {

can_frame frame(canid_t id, std::initializer_list<std::uint8_t> bytes) {
  can_frame f{};
  f.can_id = id;
  f.len = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (std::uint8_t b : bytes) f.data[i++] = b;
  return f;
}

CanTransportPair make_pair() {
  auto pair = make_transport_pair("master", "drive");
  EXPECT_TRUE(pair) << (pair ? "" : pair.error().message);
  return std::move(*pair);
}

TEST(CanTransport, FramesCrossInOrderAndIntact) {
  CanTransportPair pair = make_pair();
  std::array<can_frame, 3> sent{frame(0x80, {}), frame(0x201, {0x0F, 0x00, 0xE8, 0x03}),
                                frame(0x601, {0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0})};
  EXPECT_EQ(pair.a.send(sent), 3U);
  std::array<can_frame, 8> received{};
  ASSERT_EQ(pair.b.receive(received), 3U);
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_EQ(received[i].can_id, sent[i].can_id);
    EXPECT_EQ(received[i].len, sent[i].len);
    EXPECT_EQ(0, std::memcmp(received[i].data, sent[i].data, 8));
  }
  EXPECT_EQ(pair.a.counters().tx_frames, 3U);
  EXPECT_EQ(pair.a.counters().tx_calls, 1U);  // one sendmmsg for the whole batch
  EXPECT_EQ(pair.b.counters().rx_frames, 3U);
}

TEST(CanTransport, ReceiveWithNothingWaitingReturnsAtOnce) {
  CanTransportPair pair = make_pair();
  std::array<can_frame, 4> out{};
  EXPECT_EQ(pair.b.receive(out), 0U);
  EXPECT_EQ(pair.b.counters().io_errors, 0U);
  EXPECT_FALSE(pair.b.wait_readable(1'000'000));  // 1 ms poll, nothing there
}

TEST(CanTransport, ReceiveTakesAtMostTheSpan) {
  CanTransportPair pair = make_pair();
  for (canid_t id = 1; id <= 5; ++id) ASSERT_TRUE(pair.a.send_one(frame(0x180 + id, {1})));
  std::array<can_frame, 2> out{};
  EXPECT_EQ(pair.b.receive(out), 2U);
  EXPECT_EQ(out[0].can_id, 0x181U);
  EXPECT_EQ(out[1].can_id, 0x182U);
  std::array<can_frame, 8> rest{};
  EXPECT_EQ(pair.b.receive(rest), 3U);
  EXPECT_EQ(rest[2].can_id, 0x185U);
}

TEST(CanTransport, ErrorFramesAreCountedApart) {
  CanTransportPair pair = make_pair();
  can_frame bus_off = frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(pair.a.send_one(bus_off));
  ASSERT_TRUE(pair.a.send_one(frame(0x701, {0x05})));
  std::array<can_frame, 4> out{};
  ASSERT_EQ(pair.b.receive(out), 2U);
  EXPECT_EQ(pair.b.counters().rx_error_frames, 1U);
  EXPECT_EQ(pair.b.counters().rx_frames, 1U);
  EXPECT_NE(out[0].can_id & CAN_ERR_FLAG, 0U);
}

TEST(CanTransport, AFullQueueDropsAndCountsInsteadOfBlocking) {
  CanTransportPair pair = make_pair();
  const int small = 4096;
  ASSERT_EQ(0, ::setsockopt(pair.a.fd(), SOL_SOCKET, SO_SNDBUF, &small, sizeof small));
  std::array<can_frame, kMaxFramesPerCall> burst{};
  for (auto& f : burst) f = frame(0x201, {1, 2, 3, 4});
  std::uint64_t accepted = 0;
  for (int round = 0; round < 200; ++round) accepted += pair.a.send(burst);
  const CanCounters& c = pair.a.counters();
  EXPECT_GT(c.tx_dropped, 0U) << "the peer never reads, so the queue must fill";
  EXPECT_EQ(c.tx_frames, accepted);
  EXPECT_EQ(c.tx_frames + c.tx_dropped, 200U * kMaxFramesPerCall);
  EXPECT_EQ(c.io_errors, 0U);
}

TEST(CanTransport, MessagesOfTheWrongSizeAreCountedNotDelivered) {
  CanTransportPair pair = make_pair();
  const std::array<std::uint8_t, 5> junk{1, 2, 3, 4, 5};
  ASSERT_EQ(::send(pair.a.fd(), junk.data(), junk.size(), 0), 5);
  ASSERT_TRUE(pair.a.send_one(frame(0x181, {7})));
  std::array<can_frame, 4> out{};
  ASSERT_EQ(pair.b.receive(out), 1U);
  EXPECT_EQ(out[0].can_id, 0x181U);
  EXPECT_EQ(pair.b.counters().rx_malformed, 1U);
}

TEST(CanTransport, APeerThatWentAwayIsAnIoErrorNotACrash) {
  CanTransportPair pair = make_pair();
  { CanTransport gone = std::move(pair.b); }
  EXPECT_EQ(pair.a.send_one(frame(0x80, {})), false);
  EXPECT_EQ(pair.a.counters().io_errors, 1U);
  EXPECT_EQ(pair.a.counters().last_errno, EPIPE);
  EXPECT_EQ(pair.a.counters().tx_dropped, 1U);
}

TEST(CanTransport, RtCallsDoNotTouchTheHeap) {
  CanTransportPair pair = make_pair();
  std::array<can_frame, 12> batch{};
  for (std::size_t i = 0; i < batch.size(); ++i)
    batch[i] = frame(static_cast<canid_t>(0x200 + i), {1, 2});
  std::array<can_frame, 16> out{};
  core::alloc::begin_counting_this_thread();
  const std::uint64_t before = core::alloc::counted_allocations();
  for (int cycle = 0; cycle < 2000; ++cycle) {
    (void)pair.a.send(batch);
    (void)pair.b.receive(out);
    (void)pair.b.receive(out);
  }
  const std::uint64_t allocations = core::alloc::counted_allocations() - before;
  core::alloc::end_counting_this_thread();
  EXPECT_EQ(allocations, 0U);
  EXPECT_EQ(pair.b.counters().rx_frames, 2000U * batch.size());
}

TEST(CanTransport, FromFdRefusesABadDescriptor) {
  auto transport = CanTransport::from_fd(-1, "nothing");
  ASSERT_FALSE(transport);
  EXPECT_NE(transport.error().message.find("nothing"), std::string::npos);
}

TEST(CanTransport, OpeningAMissingInterfaceNamesIt) {
  // Either this kernel has no SocketCAN (the message says how to load it) or it has, and
  // the interface does not exist (the message says how to create one): both name it.
  auto transport = CanTransport::open_socketcan("nocan7", {});
  ASSERT_FALSE(transport);
  const std::string& message = transport.error().message;
  EXPECT_NE(message.find("'nocan7'"), std::string::npos) << message;
  EXPECT_TRUE(message.find("modprobe can-raw") != std::string::npos ||
              message.find("does not exist") != std::string::npos)
      << message;
}

TEST(CanTransport, AnInterfaceNameTooLongIsRefused) {
  auto transport = CanTransport::open_socketcan("a_name_longer_than_ifnamsiz", {});
  ASSERT_FALSE(transport);
  EXPECT_NE(transport.error().message.find("expected 1..15 characters"), std::string::npos)
      << transport.error().message;
}

}  // namespace
}  // namespace trainer::hal::socketcan
