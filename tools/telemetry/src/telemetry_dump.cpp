// telemetry_dump: the receiving end of the telemetry stream for tests and operators. Binds a
// UDP port, decodes every datagram with rt/telemetry, runs the Sequencer (newest wins), checks
// each model's image checksum against the image files given (a graphics host refuses a stream
// whose models it does not have), and prints a JSON summary when the stream has been quiet for
// --idle-ms after its first datagram (or --seconds passed). --frames adds one JSON line per
// accepted frame. --port-file: bind port 0 and write the port the kernel chose (tests).
//
//   telemetry_dump --listen 127.0.0.1:47800 --image out/models/duct.img --image ...
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "trainer/model/image_format.hpp"
#include "trainer/telemetry/sequencer.hpp"
#include "trainer/telemetry/wire_format.hpp"

namespace {

using trainer::telemetry::Frame;
using trainer::telemetry::ModelKind;

const char* kind_name(ModelKind kind) {
  switch (kind) {
    case ModelKind::modal: return "modal";
    case ModelKind::tensor: return "tensor";
    case ModelKind::catheter: return "catheter";
  }
  return "?";
}

std::string hex64(std::uint64_t value) {
  char text[20];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

nlohmann::json frame_json(const Frame& f) {
  nlohmann::json models = nlohmann::json::array();
  for (std::size_t m = 0; m < f.model_count; ++m) {
    const auto& s = f.models[m];
    nlohmann::json model = {{"scene_index", s.scene_index}, {"kind", kind_name(s.kind)},
                            {"checksum", hex64(s.image_checksum)}};
    if (s.kind == ModelKind::modal) {
      model["modes"] = s.mode_count;
      model["loads"] = s.load_count;
      model["static_correction"] = (s.flags & trainer::telemetry::kModalStaticCorrection) != 0;
      if (s.mode_count > 0) model["q0"] = s.modal_coordinates[0];
    } else if (s.kind == ModelKind::tensor) {
      model["contacts"] = s.contact_count;
    } else {
      model["particles"] = s.particle_count;
      if (s.particle_count > 0) {
        const auto& last = s.particles_m[s.particle_count - 1];
        model["last_particle_m"] = {last[0], last[1], last[2]};
      }
    }
    models.push_back(model);
  }
  nlohmann::json instruments = nlohmann::json::array();
  for (std::size_t i = 0; i < f.instrument_count; ++i) {
    const auto& s = f.instruments[i];
    instruments.push_back({{"tip_m", {s.tip_m[0], s.tip_m[1], s.tip_m[2]}},
                           {"grip_rad", s.grip_rad},
                           {"flags", s.flags}});
  }
  return {{"sequence", f.sequence}, {"cycle", f.cycle},   {"cycle_time_ns", f.cycle_time_ns},
          {"send_time_ns", f.send_time_ns}, {"latched_faults", f.latched_faults},
          {"flags", f.flags}, {"models", models}, {"instruments", instruments},
          {"contacts", f.contact_count}};
}

bool parse_listen(const std::string& text, sockaddr_in& out) {
  const std::size_t colon = text.rfind(':');
  if (colon == std::string::npos) return false;
  out = sockaddr_in{};
  out.sin_family = AF_INET;
  if (inet_pton(AF_INET, text.substr(0, colon).c_str(), &out.sin_addr) != 1) return false;
  const int port = std::stoi(text.substr(colon + 1));
  if (port < 0 || port > 65535) return false;
  out.sin_port = htons(static_cast<std::uint16_t>(port));
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"Receive, decode and check the trainer's telemetry stream (docs/telemetry.md)"};
  std::string listen = "127.0.0.1:47800";
  std::vector<std::string> images;
  std::string port_file;
  double seconds = 60.0;
  int idle_ms = 2000;
  bool frames = false;
  cli.add_option("--listen", listen, "IPv4 ADDRESS:PORT to receive on (PORT 0 with --port-file)")
      ->capture_default_str();
  cli.add_option("--image", images, "A model image the host holds (repeat): checksums checked");
  cli.add_option("--port-file", port_file, "Write the bound port to this file once listening");
  cli.add_option("--seconds", seconds, "Stop after this long in any case")->capture_default_str();
  cli.add_option("--idle-ms", idle_ms, "Stop when quiet this long after the first datagram")
      ->capture_default_str();
  cli.add_flag("--frames", frames, "Print one JSON line per accepted frame");
  CLI11_PARSE(cli, argc, argv);

  std::set<std::uint64_t> known_checksums;
  for (const std::string& path : images) {
    std::ifstream in(path, std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.eof() && !in) {
      std::cerr << "telemetry_dump: cannot read image " << path << "\n";
      return 1;
    }
    const auto* data = reinterpret_cast<const std::byte*>(bytes.data());
    known_checksums.insert(trainer::model::compute_image_checksum({data, bytes.size()}));
  }

  sockaddr_in address{};
  if (!parse_listen(listen, address)) {
    std::cerr << "telemetry_dump: --listen " << listen << ": expected IPv4 ADDRESS:PORT\n";
    return 2;
  }
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  const int big = 4 << 20;
  (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
  if (fd < 0 || bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    std::perror("telemetry_dump: bind");
    return 1;
  }
  if (!port_file.empty()) {
    socklen_t length = sizeof address;
    getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
    std::ofstream(port_file + ".tmp") << ntohs(address.sin_port) << "\n";
    std::rename((port_file + ".tmp").c_str(), port_file.c_str());
  }

  auto frame = std::make_unique<Frame>();
  auto last = std::make_unique<Frame>();
  trainer::telemetry::Sequencer sequencer;
  std::map<std::string, std::uint64_t> refused;
  std::vector<std::uint32_t> sizes;
  std::uint64_t datagrams = 0;
  std::uint64_t model_mismatch = 0;
  std::set<std::string> unknown_checksums;
  bool increasing = true;
  bool have_last = false;
  bool run_ended = false;
  std::uint32_t max_loads = 0;
  std::uint32_t max_contacts = 0;
  std::vector<std::byte> buffer(70000);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto last_datagram = start;
  for (;;) {
    const auto now = Clock::now();
    if (std::chrono::duration<double>(now - start).count() > seconds) break;
    if (datagrams > 0 && now - last_datagram > std::chrono::milliseconds(idle_ms)) break;
    if (run_ended) break;
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 50) <= 0) continue;
    const ssize_t n = recv(fd, buffer.data(), buffer.size(), 0);
    if (n < 0) continue;
    ++datagrams;
    last_datagram = Clock::now();
    const auto result = trainer::telemetry::decode({buffer.data(), static_cast<std::size_t>(n)}, *frame);
    if (!result.ok()) {
      ++refused[trainer::telemetry::to_string(result.error)];
      continue;
    }
    bool images_known = true;
    for (std::size_t m = 0; m < frame->model_count && !known_checksums.empty(); ++m) {
      if (known_checksums.count(frame->models[m].image_checksum) == 0) {
        images_known = false;
        unknown_checksums.insert(hex64(frame->models[m].image_checksum));
      }
    }
    if (!images_known) {
      ++model_mismatch;  // a host without these images refuses the frame
      continue;
    }
    const auto verdict = sequencer.offer(frame->stream_id, frame->sequence);
    if (verdict != trainer::telemetry::Sequencer::Verdict::accept) continue;
    if (have_last && frame->sequence <= last->sequence && frame->stream_id == last->stream_id)
      increasing = false;
    sizes.push_back(static_cast<std::uint32_t>(n));
    for (std::size_t m = 0; m < frame->model_count; ++m)
      max_loads = std::max(max_loads, frame->models[m].load_count);
    max_contacts = std::max(max_contacts, frame->contact_count);
    if ((frame->flags & trainer::telemetry::kFlagRunEnded) != 0) run_ended = true;
    if (frames) std::cout << frame_json(*frame).dump() << "\n";
    std::swap(frame, last);
    have_last = true;
  }
  std::sort(sizes.begin(), sizes.end());
  const auto& c = sequencer.counters();
  nlohmann::json summary = {
      {"datagrams", datagrams},
      {"accepted", c.accepted},
      {"refused", refused},
      {"model_mismatch", model_mismatch},
      {"unknown_checksums", unknown_checksums},
      {"images_checked", known_checksums.size()},
      {"duplicates", c.duplicates},
      {"late", c.late},
      {"stale", c.stale},
      {"lost", sequencer.lost()},
      {"stream_restarts", c.stream_restarts},
      {"sequence_increasing", increasing},
      {"run_ended", run_ended},
      {"max_loads", max_loads},
      {"max_contacts", max_contacts},
      {"frame_bytes",
       {{"min", sizes.empty() ? 0 : sizes.front()},
        {"p50", sizes.empty() ? 0 : sizes[sizes.size() / 2]},
        {"max", sizes.empty() ? 0 : sizes.back()}}},
      {"last", have_last ? frame_json(*last) : nlohmann::json(nullptr)}};
  std::cout << summary.dump() << "\n";
  close(fd);
  return 0;
}
