// The trainer's messages to systemd as a datagram socket standing in for NOTIFY_SOCKET
// receives them, driven with the snapshots and times the supervisor would pass: READY only
// once armed, pings while the cycle counter advances, none while it is stalled or after an
// overrun fault (with the STATUS saying why), STOPPING at the end.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "trainer/app/service_supervision.hpp"
#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {
namespace {

constexpr std::int64_t kSecondNs = 1'000'000'000;

class ServiceSupervisionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = std::filesystem::temp_directory_path() /
            ("supervision_test_" + std::to_string(getpid()) + ".sock");
    std::filesystem::remove(path_);
    socket_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    ASSERT_GE(socket_, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path_.c_str(), sizeof address.sun_path - 1);
    ASSERT_EQ(bind(socket_, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
    timeval timeout{0, 100'000};
    setsockopt(socket_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
    setenv("NOTIFY_SOCKET", path_.c_str(), 1);
    setenv("WATCHDOG_USEC", "2000000", 1);  // pings due every second
    unsetenv("WATCHDOG_PID");
  }
  void TearDown() override {
    close(socket_);
    std::filesystem::remove(path_);
    unsetenv("NOTIFY_SOCKET");
    unsetenv("WATCHDOG_USEC");
  }
  // Every message received since the last call.
  std::vector<std::string> received() {
    std::vector<std::string> messages;
    char buffer[4096];
    for (;;) {
      const ssize_t got = recv(socket_, buffer, sizeof buffer, 0);
      if (got <= 0) return messages;
      messages.emplace_back(buffer, static_cast<std::size_t>(got));
    }
  }
  static TelemetrySnapshot snapshot(std::uint64_t cycle, std::uint32_t faults) {
    TelemetrySnapshot s;
    s.cycle = cycle;
    s.latched_faults = faults;
    return s;
  }

  std::filesystem::path path_;
  int socket_ = -1;
};

TEST_F(ServiceSupervisionTest, ReadyOnlyOnceArmedThenPingsWhileTheLoopAdvances) {
  ServiceSupervision service(true, "wall", 1'000'000);
  service.tick(false, 0);  // no cycle yet
  service.observe(snapshot(30, safety::bit(safety::Fault::not_armed)));
  service.tick(false, kSecondNs / 30);
  service.tick(false, 2 * kSecondNs / 30);  // same faults: said once
  EXPECT_EQ(received(), std::vector<std::string>{"STATUS=waiting to arm: latched faults 0x1"});
  EXPECT_FALSE(service.ready_sent());
  service.observe(snapshot(60, 0));
  service.tick(false, kSecondNs / 10);
  EXPECT_EQ(received(), (std::vector<std::string>{
                            "READY=1\nSTATUS=armed scene wall: loop at 1000 Hz", "WATCHDOG=1"}));
  // 33 ms ticks up to 1.2 s with the counter advancing: one more ping (due from 1.1 s).
  std::uint64_t cycle = 60;
  for (std::int64_t now = kSecondNs / 10; now <= kSecondNs * 12 / 10; now += kSecondNs / 30) {
    cycle += 33;
    service.observe(snapshot(cycle, 0));
    service.tick(false, now);
  }
  EXPECT_EQ(received(), std::vector<std::string>{"WATCHDOG=1"});
  service.stopping(true);
  EXPECT_EQ(received(), std::vector<std::string>{"STOPPING=1\nSTATUS=stopping: signal received"});
}

TEST_F(ServiceSupervisionTest, StalledLoopStopsThePingsAndSaysSo) {
  ServiceSupervision service(true, "wall", 1'000'000);
  service.observe(snapshot(10, 0));
  service.tick(false, 0);
  EXPECT_EQ(received().size(), 2U);  // READY, the first ping
  // The RT thread stops advancing at cycle 10: no ping for three seconds.
  for (std::int64_t now = 0; now < 3 * kSecondNs; now += kSecondNs / 30) service.tick(false, now);
  EXPECT_EQ(received(), std::vector<std::string>{
                            "STATUS=loop stalled (cycle counter did not advance): watchdog pings "
                            "stopped at cycle 10"});
  EXPECT_EQ(service.watchdog().pings(), 1U);
  service.observe(snapshot(11, 0));
  service.tick(false, 3 * kSecondNs);
  EXPECT_EQ(received(), (std::vector<std::string>{"WATCHDOG=1", "STATUS=loop healthy"}));
}

TEST_F(ServiceSupervisionTest, OverrunFaultStopsThePingsButAnEstopDoesNot) {
  ServiceSupervision service(true, "wall", 1'000'000);
  service.observe(snapshot(10, 0));
  service.tick(false, 0);
  (void)received();
  service.observe(snapshot(1010, safety::bit(safety::Fault::estop)));
  service.tick(false, kSecondNs);
  EXPECT_EQ(received(), std::vector<std::string>{"WATCHDOG=1"});
  service.observe(snapshot(
      2010, safety::bit(safety::Fault::estop) | safety::bit(safety::Fault::overrun_streak)));
  service.tick(false, 2 * kSecondNs);
  service.observe(snapshot(3010, safety::bit(safety::Fault::overrun_streak)));
  service.tick(false, 3 * kSecondNs);
  EXPECT_EQ(received(), std::vector<std::string>{
                            "STATUS=loop overrun fault latched: watchdog pings stopped at cycle "
                            "2010"});
}

TEST_F(ServiceSupervisionTest, NoArmIsReadyOnceTheLoopRunsAndNothingIsSentOutsideAUnit) {
  ServiceSupervision unarmed(false, "wall", 500'000);
  unarmed.observe(snapshot(1, safety::bit(safety::Fault::not_armed)));
  unarmed.tick(false, 0);
  const auto messages = received();
  ASSERT_FALSE(messages.empty());
  EXPECT_EQ(messages[0], "READY=1\nSTATUS=running unarmed scene wall: loop at 2000 Hz");
  unsetenv("NOTIFY_SOCKET");
  ServiceSupervision outside(true, "wall", 1'000'000);
  outside.observe(snapshot(10, 0));
  outside.tick(false, 0);
  outside.stopping(false);
  EXPECT_TRUE(received().empty());
  EXPECT_FALSE(outside.ready_sent());
}

}  // namespace
}  // namespace trainer::app
