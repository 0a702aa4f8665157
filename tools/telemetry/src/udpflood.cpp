// udpflood: malformed UDP traffic at a set rate, for the telemetry flood measurement
// (docs/telemetry.md): nothing sent toward the appliance may change its RT loop.
//
// Datagrams (mixed in turn): random bytes of random length; the telemetry magic and version
// followed by random bytes; a well-formed telemetry header with a wrong CRC; empty datagrams.
// They go to --target on every port of --ports (round robin). --bind fixes the source
// address:port: bound to the telemetry destination (the port the appliance sends to), the
// flood matches the appliance's connected socket and lands in its receive queue, the worst
// case for it; the frames the appliance sends meanwhile arrive here, are decoded and counted
// (so the run also shows the stream kept flowing). --cpu pins the flood to one CPU.
//
//   udpflood --target 127.0.0.1 --ports 47900,22,80,5353 --bind 127.0.0.1:47800
//            --rate 100000 --seconds 20 --cpu 0
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "trainer/telemetry/wire_format.hpp"

namespace {

constexpr std::size_t kBatch = 64;
constexpr std::size_t kMaxPayload = 1472;  // one Ethernet frame

std::vector<std::uint16_t> parse_ports(const std::string& text) {
  std::vector<std::uint16_t> ports;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    const std::size_t dash = item.find('-');
    const int low = std::stoi(item.substr(0, dash));
    const int high = dash == std::string::npos ? low : std::stoi(item.substr(dash + 1));
    if (low < 1 || high > 65535 || low > high) throw std::runtime_error("bad port item " + item);
    for (int p = low; p <= high; ++p) ports.push_back(static_cast<std::uint16_t>(p));
    begin = end + 1;
  }
  return ports;
}

void fill_payload(std::mt19937_64& random, std::uint64_t kind, std::vector<std::byte>& out) {
  const std::size_t size = kind == 3 ? 0 : 1 + random() % kMaxPayload;
  out.resize(std::max<std::size_t>(size, kind == 2 ? trainer::telemetry::kHeaderBytes : 0));
  for (std::byte& b : out) b = std::byte(static_cast<std::uint8_t>(random()));
  if ((kind == 1 || kind == 2) && out.size() >= 6) {
    for (std::size_t i = 0; i < 4; ++i) out[i] = std::byte{trainer::telemetry::kMagic[i]};
    out[4] = std::byte{trainer::telemetry::kVersionMajor};
    out[5] = std::byte{trainer::telemetry::kVersionMinor};
  }
  if (kind == 2) {  // consistent length, wrong CRC (random)
    out[6] = std::byte(static_cast<std::uint8_t>(out.size()));
    out[7] = std::byte(static_cast<std::uint8_t>(out.size() >> 8));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"Flood UDP ports with malformed datagrams (docs/telemetry.md, flood measurement)"};
  std::string target = "127.0.0.1";
  std::string ports_text;
  std::string bind_text;
  double rate = 100000.0;
  double seconds = 10.0;
  int cpu = -1;
  std::uint64_t seed = 18;
  cli.add_option("--target", target, "IPv4 address to flood")->capture_default_str();
  cli.add_option("--ports", ports_text, "Ports: 47900,22,1000-1010")->required();
  cli.add_option("--bind", bind_text, "Source IPv4 ADDRESS:PORT (e.g. the telemetry destination)");
  cli.add_option("--rate", rate, "Datagrams per second (0: as fast as possible)")->capture_default_str();
  cli.add_option("--seconds", seconds, "Duration")->capture_default_str();
  cli.add_option("--cpu", cpu, "Pin to this CPU");
  cli.add_option("--seed", seed, "Random seed")->capture_default_str();
  CLI11_PARSE(cli, argc, argv);

  std::vector<std::uint16_t> ports;
  try {
    ports = parse_ports(ports_text);
  } catch (const std::exception& error) {
    std::cerr << "udpflood: --ports " << ports_text << ": " << error.what() << "\n";
    return 2;
  }
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(cpu), &set);
    if (sched_setaffinity(0, sizeof set, &set) != 0) std::perror("udpflood: sched_setaffinity");
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    std::perror("udpflood: socket");
    return 1;
  }
  if (!bind_text.empty()) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    const std::size_t colon = bind_text.rfind(':');
    if (colon == std::string::npos ||
        inet_pton(AF_INET, bind_text.substr(0, colon).c_str(), &local.sin_addr) != 1) {
      std::cerr << "udpflood: --bind " << bind_text << ": expected IPv4 ADDRESS:PORT\n";
      return 2;
    }
    local.sin_port = htons(static_cast<std::uint16_t>(std::stoi(bind_text.substr(colon + 1))));
    const int one = 1;
    (void)setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
      std::perror("udpflood: bind");
      return 1;
    }
  }
  std::vector<sockaddr_in> destinations(ports.size());
  for (std::size_t i = 0; i < ports.size(); ++i) {
    destinations[i].sin_family = AF_INET;
    destinations[i].sin_port = htons(ports[i]);
    if (inet_pton(AF_INET, target.c_str(), &destinations[i].sin_addr) != 1) {
      std::cerr << "udpflood: --target " << target << ": expected an IPv4 address\n";
      return 2;
    }
  }

  std::mt19937_64 random(seed);
  std::vector<std::vector<std::byte>> payloads(kBatch);
  std::vector<mmsghdr> messages(kBatch);
  std::vector<iovec> vectors(kBatch);
  std::vector<std::byte> receive(70000);
  auto frame = std::make_unique<trainer::telemetry::Frame>();
  std::uint64_t sent = 0, send_errors = 0, refused = 0, kind = 0, next_port = 0;
  std::uint64_t received = 0, frames_decoded = 0;
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  for (;;) {
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    if (elapsed >= seconds) break;
    if (rate > 0.0 && static_cast<double>(sent + send_errors) > rate * elapsed) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    } else {
      for (std::size_t k = 0; k < kBatch; ++k) {
        fill_payload(random, kind++ % 4, payloads[k]);
        vectors[k] = {payloads[k].data(), payloads[k].size()};
        messages[k] = {};
        messages[k].msg_hdr.msg_name = &destinations[next_port++ % destinations.size()];
        messages[k].msg_hdr.msg_namelen = sizeof(sockaddr_in);
        messages[k].msg_hdr.msg_iov = &vectors[k];
        messages[k].msg_hdr.msg_iovlen = 1;
      }
      const int n = sendmmsg(fd, messages.data(), kBatch, MSG_DONTWAIT);
      if (n > 0) {
        sent += static_cast<std::uint64_t>(n);
      } else {
        ++send_errors;
        if (errno == ECONNREFUSED) ++refused;  // a flooded closed port's ICMP reply
      }
    }
    // Whatever arrives at the bound socket (the appliance's frames when bound to its
    // destination): counted and decoded.
    for (;;) {
      const ssize_t n = recv(fd, receive.data(), receive.size(), MSG_DONTWAIT);
      if (n < 0) break;
      ++received;
      if (trainer::telemetry::decode({receive.data(), static_cast<std::size_t>(n)}, *frame).ok())
        ++frames_decoded;
    }
  }
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  const nlohmann::json summary = {{"sent", sent},
                                  {"send_errors", send_errors},
                                  {"refused", refused},
                                  {"seconds", elapsed},
                                  {"datagrams_per_s", static_cast<double>(sent) / elapsed},
                                  {"ports", ports.size()},
                                  {"received", received},
                                  {"telemetry_frames_received", frames_decoded}};
  std::cout << summary.dump() << "\n";
  close(fd);
  return 0;
}
