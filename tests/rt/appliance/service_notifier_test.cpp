// The sd_notify messages as systemd receives them: a datagram socket the test owns stands in
// for NOTIFY_SOCKET.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "trainer/appliance/service_notifier.hpp"

namespace trainer::appliance {
namespace {

class NotifySocket : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = std::filesystem::temp_directory_path() /
            ("notify_test_" + std::to_string(getpid()) + ".sock");
    std::filesystem::remove(path_);
    socket_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    ASSERT_GE(socket_, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path_.c_str(), sizeof address.sun_path - 1);
    ASSERT_EQ(bind(socket_, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
    timeval timeout{1, 0};
    setsockopt(socket_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  }
  void TearDown() override {
    close(socket_);
    std::filesystem::remove(path_);
    unsetenv("NOTIFY_SOCKET");
    unsetenv("WATCHDOG_USEC");
    unsetenv("WATCHDOG_PID");
  }
  std::string receive() {
    char buffer[4096];
    const ssize_t got = recv(socket_, buffer, sizeof buffer, 0);
    return got > 0 ? std::string(buffer, static_cast<std::size_t>(got)) : std::string{};
  }

  std::filesystem::path path_;
  int socket_ = -1;
};

TEST_F(NotifySocket, MessagesArriveInOrderWithTheWatchdogPeriod) {
  setenv("NOTIFY_SOCKET", path_.c_str(), 1);
  setenv("WATCHDOG_USEC", "3000000", 1);
  setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
  const ServiceNotifier notifier = ServiceNotifier::from_environment();
  EXPECT_TRUE(notifier.active());
  EXPECT_EQ(notifier.watchdog_usec(), 3'000'000U);
  notifier.ready("armed\nrunning");
  notifier.watchdog();
  notifier.stopping("done");
  EXPECT_EQ(receive(), "READY=1\nSTATUS=armed running");
  EXPECT_EQ(receive(), "WATCHDOG=1");
  EXPECT_EQ(receive(), "STOPPING=1\nSTATUS=done");
  EXPECT_EQ(notifier.messages_sent(), 3U);
}

TEST_F(NotifySocket, WatchdogOfAnotherProcessIsNotOurs) {
  setenv("NOTIFY_SOCKET", path_.c_str(), 1);
  setenv("WATCHDOG_USEC", "3000000", 1);
  setenv("WATCHDOG_PID", "1", 1);
  EXPECT_EQ(ServiceNotifier::from_environment().watchdog_usec(), 0U);
}

TEST_F(NotifySocket, InactiveWithoutNotifySocket) {
  unsetenv("NOTIFY_SOCKET");
  const ServiceNotifier notifier = ServiceNotifier::from_environment();
  EXPECT_FALSE(notifier.active());
  notifier.ready("x");
  EXPECT_EQ(notifier.messages_sent(), 0U);
}

}  // namespace
}  // namespace trainer::appliance
